"""The "Tessera" render engine: final renders (F12, ``bpy.ops.render.render``) and the
viewport, through a Tessera session."""

from __future__ import annotations

import bpy
import numpy as np

from . import export, passes

_clients: dict = {}

#: The last errors reported to the artist (newest last), for scripts and tests: Blender keeps
#: reports in the window manager, which a background session does not have.
REPORTED: list[str] = []


def client_for(context_prefs):
    """One client per (server URL, token) for the whole Blender session; no URL starts an
    embedded server in this process, once."""
    import tessera

    url = token = None
    if context_prefs is not None:
        url = context_prefs.server_url.strip() or None
        token = context_prefs.token.strip() or None
    key = (url, token)
    if key not in _clients:
        _clients[key] = tessera.Client(url, token)
    return _clients[key]


def preferences():
    addon = bpy.context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


def render_settings(scene) -> dict:
    """The scene's Tessera settings as ``Session.render`` keywords."""
    s = scene.tessera
    settings = {
        "max_depth": s.max_depth,
        "caustics": s.caustics.lower(),
        "energy_compensation": s.energy_compensation,
        "seed": scene.frame_current if s.animate_seed else 0,
    }
    if s.noise_threshold > 0.0:
        settings["noise_threshold"] = s.noise_threshold
    if s.clamp > 0.0:
        settings["clamp"] = s.clamp
    return settings


def resolution(scene) -> tuple[int, int]:
    r = scene.render
    scale = r.resolution_percentage / 100.0
    return max(1, int(r.resolution_x * scale)), max(1, int(r.resolution_y * scale))


def transform_rows(obj) -> list[list[float]]:
    """An object's world matrix, rows first, translation in the last column."""
    return [list(row) for row in obj.matrix_world]


def object_edits(session, exported: export.Export, depsgraph) -> tuple[list[dict], bool]:
    """Sends what a depsgraph update changed: moved objects as transform deltas (no
    re-export). Returns what was sent, and whether something needs a re-export (geometry,
    materials, lights' or cameras' data, objects added or removed)."""
    sent, reexport = [], False
    for update in depsgraph.updates:
        target = update.id
        if isinstance(target, bpy.types.Object):
            prims = exported.prims.get(target.name)
            if prims is None:
                reexport = True
                continue
            if update.is_updated_geometry or update.is_updated_shading:
                reexport = True
            elif update.is_updated_transform:
                for prim in prims:
                    sent += session.set_transform(prim, transform_rows(target.evaluated_get(depsgraph)))
        elif isinstance(target, (bpy.types.Material, bpy.types.Light, bpy.types.Camera, bpy.types.Mesh, bpy.types.World)):
            reexport = True
    return sent, reexport


class TesseraRenderEngine(bpy.types.RenderEngine):
    bl_idname = "TESSERA"
    bl_label = "Tessera"
    bl_use_preview = False
    bl_use_postprocess = True
    bl_use_eevee_viewport = True

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.exported = None
        self.viewport = None

    # --- final renders -------------------------------------------------------------------

    def update(self, data, depsgraph):
        """Exports the evaluated scene (called on the main thread before ``render``)."""
        if self.is_preview:
            return
        try:
            self.exported = export.export_scene(depsgraph)
        except Exception as e:  # reported from render(), where Blender shows it
            self.exported = e

    def render(self, depsgraph):
        try:
            self._render(depsgraph)
        except Exception as e:
            # A render() that raises still saves a black image: say why, where the artist looks.
            message = f"Tessera: {e}"
            self.report({"ERROR"}, message)
            REPORTED[:] = (REPORTED + [message])[-16:]

    def _render(self, depsgraph):
        if isinstance(self.exported, Exception) or self.exported is None:
            raise RuntimeError(f"exporting the scene failed: {self.exported}")
        # One session a render, closed when it ends: the server holds at most 64 sessions,
        # and an unclosed one lingers there until its idle timeout (ten minutes).
        with client_for(preferences()).session("blender") as session:
            self._render_in(session, depsgraph)

    def _render_in(self, session, depsgraph):
        scene = depsgraph.scene
        width, height = resolution(scene)
        session.sync_usd(self.exported.path)
        for w in self.exported.warnings:
            self.report({"WARNING"}, f"Tessera: {w}")
        denoise = scene.tessera.denoise
        aovs = passes.aovs_for(depsgraph.view_layer, denoise)
        self.update_stats("Tessera", "rendering")
        events = session.render(width, height, spp=scene.tessera.samples, aovs=aovs, **render_settings(scene))
        import tessera

        image = tessera.Framebuffer(width, height)
        cancelled = False
        for event in events:
            kind = type(event).__name__
            if kind == "Tile":
                self._write_tile(event, height, depsgraph.view_layer)
                image.add(event)
            elif kind == "Progress":
                self.update_progress(min(event.percent / 100.0, 1.0))
                self.update_stats("Tessera", f"{event.spp}/{scene.tessera.samples} spp, noise {100 * event.estimated_noise:.2f}%")
            elif kind == "Started":
                for w in event.warnings:
                    self.report({"WARNING"}, f"Tessera: {w}")
            if self.test_break():
                session.cancel()
                cancelled = True
                break
        if denoise and not cancelled:
            self._write_denoised(image, depsgraph.view_layer)

    def _write_denoised(self, image, view_layer) -> None:
        """The denoised beauty as Combined, the raw one as Noisy Image (Cycles' convention)."""
        import tessera

        self.update_stats("Tessera", "denoising")
        raw = image.layers["beauty"]
        rgb = tessera.denoise(raw, image.layers["albedo"], image.layers["normal"])
        denoised = np.concatenate([rgb, raw[..., 3:]], axis=2)
        result = self.begin_result(0, 0, image.width, image.height, layer=view_layer.name)
        for name, pixels in (("Combined", denoised), ("Noisy Image", raw)):
            rp = next((p for p in result.layers[0].passes if p.name == name), None)
            if rp is not None:
                rp.rect.foreach_set(np.ascontiguousarray(pixels[::-1]).reshape(-1).astype(np.float32))
        self.end_result(result)

    def _write_tile(self, tile, height: int, view_layer) -> None:
        # Blender's rows run bottom-up.
        y = height - (tile.y + tile.height)
        result = self.begin_result(tile.x, y, tile.width, tile.height, layer=view_layer.name)
        layer = result.layers[0]
        for aov, pixels in tile.layers.items():
            flipped = np.ascontiguousarray(pixels[::-1]).reshape(-1, pixels.shape[2])
            for name in passes.PASSES_OF_AOV.get(aov, []):
                rp = next((p for p in layer.passes if p.name == name), None)
                if rp is not None:
                    rp.rect.foreach_set(passes.to_pass(aov, flipped).ravel())
        self.end_result(result)

    def update_render_passes(self, scene=None, renderlayer=None):
        for name, channels, chanid, kind in passes.enabled(renderlayer, scene.tessera.denoise):
            self.register_pass(scene, renderlayer, name, channels, chanid, kind)

    # --- viewport ------------------------------------------------------------------------

    def view_update(self, context, depsgraph):
        from .viewport import Viewport

        if self.viewport is None:
            self.viewport = Viewport(self, client_for(preferences()))
        self.viewport.update(context, depsgraph)

    def view_draw(self, context, depsgraph):
        if self.viewport is not None:
            self.viewport.draw(context)

    def __del__(self):
        viewport = getattr(self, "viewport", None)
        if viewport is not None:
            viewport.stop()

