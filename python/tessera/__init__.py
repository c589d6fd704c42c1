"""Tessera for DCCs and pipeline scripts.

The Rust client itself (the USD translation, sync and tile decoding the ``tessera`` CLI
uses) behind a small Python API::

    import tessera

    client = tessera.Client()                 # an embedded server; or Client("http://host:50051")
    session = client.session()
    session.sync_usd("shot.usda")             # everything the first time
    for event in session.render(640, 360, spp=64, aovs=["albedo"]):
        if isinstance(event, tessera.Tile):
            event.layers["beauty"]            # (height, width, 4) float32, linear
    session.set_transform("/World/Cube", matrix)   # one delta; the next render shows it
    session.sync_usd("shot.usda")             # after re-export: only the prims that changed

Waiting for events releases the GIL. Errors are :class:`TesseraError` carrying the server's
message, which names the prim and field at fault.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterator, Sequence

import numpy as np

from ._native import TesseraError, _Client
from ._native import denoise as _denoise

__all__ = [
    "Client",
    "Session",
    "TesseraError",
    "Started",
    "Tile",
    "Progress",
    "Restarted",
    "Finished",
    "Framebuffer",
    "denoise",
]


@dataclass
class Started:
    """The render began: its size, AOVs, the render plan and warnings."""

    width: int
    height: int
    aovs: list[str]
    plan: list[dict]
    warnings: list[str]
    scene_version: int
    pass_spp: list[int]
    prim_paths: list[str] = field(default_factory=list)


@dataclass
class Tile:
    """One rect after one pass: every AOV as a (height, width, channels) float32 array.

    ``pixel_size > 1`` marks a coarse first-look tile, already scaled up to the rect.
    """

    x: int
    y: int
    width: int
    height: int
    pass_index: int
    samples: int
    pixel_size: int
    layers: dict[str, np.ndarray]


@dataclass
class Progress:
    """A pass finished."""

    pass_index: int
    spp: int
    percent: float
    estimated_noise: float
    elapsed_seconds: float
    rays_per_second: float
    active_pixels: int


@dataclass
class Restarted:
    """The scene changed during the render; the image starts over from this version."""

    scene_version: int


@dataclass
class Finished:
    """The render ended (``cancelled`` when it was stopped)."""

    seconds: float
    spp: int
    rays: int
    paths: int
    estimated_noise: float
    cancelled: bool
    mean_spp: float


def _event(d: dict):
    kind = d.pop("type")
    if kind == "tile":
        w, h = d["width"], d["height"]
        layers = {
            aov: np.frombuffer(data, dtype="<f4").reshape(h, w, channels)
            for aov, (channels, data) in d.pop("layers").items()
        }
        return Tile(layers=layers, **d)
    return {"started": Started, "progress": Progress, "restarted": Restarted, "finished": Finished}[kind](**d)


class Framebuffer:
    """Assembles tiles into whole-image arrays, one per AOV (the latest pass of each rect)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = width, height
        self.layers: dict[str, np.ndarray] = {}

    def add(self, tile: Tile) -> None:
        for aov, pixels in tile.layers.items():
            layer = self.layers.get(aov)
            if layer is None:
                layer = self.layers[aov] = np.zeros((self.height, self.width, pixels.shape[2]), np.float32)
            layer[tile.y : tile.y + tile.height, tile.x : tile.x + tile.width] = pixels


def denoise(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Open Image Denoise's RT filter (HDR) on ``color`` (height, width, 3 or 4), guided by
    ``albedo`` and ``normal`` (height, width, 3), which are prefiltered first. Returns the
    denoised RGB (height, width, 3) float32; alpha, if any, is the caller's to keep.
    Needs ``pip install pyoidn==2.5.1.0``; the device is created once per process."""
    h, w, c = color.shape
    as_bytes = lambda a: np.ascontiguousarray(a, dtype="<f4").tobytes()  # noqa: E731
    out = _denoise(w, h, as_bytes(color), c, as_bytes(albedo), as_bytes(normal))
    return np.frombuffer(out, dtype="<f4").reshape(h, w, 3)


class Session:
    """A server session: the scene it holds, edits sent as deltas, progressive renders."""

    def __init__(self, native):
        self._native = native

    @property
    def id(self) -> str:
        return self._native.id

    def sync_usd(self, path, frame: float | None = None) -> list[dict]:
        """Translate and sync a USD file; re-syncing sends only the prims that changed.

        Returns what was sent: one dict per prim with ``path``, ``kind``, ``dirty`` (Hydra's
        dirty bits by name) and ``chunks`` (array chunks sent with it). Warnings about the
        file are in :attr:`warnings` afterwards.
        """
        sent, self.warnings = self._native.sync_usd(str(path), frame)
        return sent

    def set_transform(self, prim_path: str, matrix) -> list[dict]:
        """Move a mesh, light or camera: ``matrix`` is 4x4, rows first, translation in the last column."""
        m = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
        return self._native.set_transform(prim_path, m.tolist())

    def set_camera(self, path: str, **params) -> list[dict]:
        """Change a camera's focal_length, f_stop, focus_distance, horizontal_aperture, vertical_aperture or exposure (stops)."""
        return self._native.set_camera(path, **params)

    def set_light_params(self, path: str, **params) -> list[dict]:
        """Change a light's (a UsdLux light's or a mesh light's) intensity, exposure, diffuse,
        specular or color."""
        return self._native.set_light_params(path, **params)

    def set_light_links(self, path: str, illuminates: list[str] | None = None, shadowed_by: list[str] | None = None) -> list[dict]:
        """Link a light (a UsdLux light or a mesh light): it illuminates only the prims at or under `illuminates`, and only those at
        or under `shadowed_by` cast its shadows (None: every prim), as UsdLux's
        collection:lightLink and collection:shadowLink do."""
        return self._native.set_light_links(path, illuminates, shadowed_by)

    def set_material_input(self, material_path: str, shader: str, input: str, value) -> list[dict]:
        """Set one input of one shader node (its path, or its name under the material)."""
        if isinstance(value, (list, tuple, np.ndarray)):
            value = [float(v) for v in value]
        return self._native.set_material_input(material_path, shader, input, value)

    def render(self, width: int, height: int, spp: int = 64, aovs: Sequence[str] = (), **settings) -> Iterator:
        """Render progressively: yields Started, Tile, Progress, Restarted and Finished events.

        ``settings`` are the CLI's knobs by name: max_depth, seed, camera, threads,
        tile_size, coarse_start, clamp, noise_threshold, caustics ("full"/"avoid"),
        sampler ("sobol"/"independent"), energy_compensation, texture_filtering,
        light_splitting, light_split_budget, pixel_aspect, progressive_f16.
        Leaving the loop early stops the render.
        """
        stream = self._native.render(width, height, spp, list(aovs), **settings)
        for d in stream:
            yield _event(d)

    def cancel(self) -> bool:
        """Stop this session's render; True when one was running."""
        return self._native.cancel()

    def close(self) -> None:
        """Close the session on the server, freeing its scene and its place among the server's
        sessions (one left open lingers until the server's idle timeout). Closing twice does
        nothing. ``with client.session() as s:`` closes it on leaving the block."""
        self._native.close()

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, exc_type, *_) -> None:
        try:
            self.close()
        except TesseraError:
            # The block's own error says more than a failed close (a server gone, say).
            if exc_type is None:
                raise


class Client:
    """A connection to a render server; without a URL, an embedded server in this process."""

    def __init__(self, url: str | None = None, token: str | None = None):
        self._native = _Client(url, token)

    @property
    def url(self) -> str:
        return self._native.url

    def session(self, name: str = "tessera-python") -> Session:
        return Session(self._native.session(name))

    def close(self) -> None:
        """Stop the embedded server, if this client started one."""
        self._native.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
