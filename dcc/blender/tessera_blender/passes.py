"""Blender's render passes and the Tessera AOVs that fill them."""

from __future__ import annotations

import numpy as np

#: (view-layer flag, Blender pass, channels, channel ids, kind, Tessera AOV)
PASSES = [
    ("use_pass_z", "Depth", 1, "Z", "VALUE", "depth"),
    ("use_pass_normal", "Normal", 3, "XYZ", "VECTOR", "normal"),
    ("use_pass_position", "Position", 3, "XYZ", "VECTOR", "position"),
    ("use_pass_diffuse_direct", "DiffDir", 3, "RGB", "COLOR", "diffuse_direct"),
    ("use_pass_diffuse_indirect", "DiffInd", 3, "RGB", "COLOR", "diffuse_indirect"),
    ("use_pass_glossy_direct", "GlossDir", 3, "RGB", "COLOR", "specular_direct"),
    ("use_pass_glossy_indirect", "GlossInd", 3, "RGB", "COLOR", "specular_indirect"),
    ("use_pass_transmission_direct", "TransDir", 3, "RGB", "COLOR", "transmission_direct"),
    ("use_pass_transmission_indirect", "TransInd", 3, "RGB", "COLOR", "transmission_indirect"),
    ("use_pass_emit", "Emit", 3, "RGB", "COLOR", "emission"),
]

#: Tessera AOV -> the Blender passes it fills (Cycles' Denoising Data: albedo and normal).
PASSES_OF_AOV = {aov: [name] for _, name, _, _, _, aov in PASSES} | {"beauty": ["Combined"], "albedo": ["Denoising Albedo"]}
PASSES_OF_AOV["normal"] = PASSES_OF_AOV["normal"] + ["Denoising Normal"]


def _albedo_enabled(view_layer) -> bool:
    cycles = getattr(view_layer, "cycles", None)
    return bool(getattr(cycles, "denoising_store_passes", False))


def enabled(view_layer, denoise=False):
    """The passes to register: Combined, then those the view layer enables that map (and
    Noisy Image, the raw beauty, when the render is denoised: Cycles' convention)."""
    yield ("Combined", 4, "RGBA", "COLOR")
    if denoise:
        yield ("Noisy Image", 4, "RGBA", "COLOR")
    for flag, name, channels, chanid, kind, _ in PASSES:
        if getattr(view_layer, flag, False):
            yield (name, channels, chanid, kind)
    if _albedo_enabled(view_layer):
        yield ("Denoising Normal", 3, "XYZ", "VECTOR")
        yield ("Denoising Albedo", 3, "RGB", "COLOR")


def aovs_for(view_layer, denoise=False) -> list[str]:
    """The Tessera AOVs a view layer's enabled passes need (beauty is always rendered), and
    the albedo and normal the denoiser is guided by."""
    aovs = [aov for flag, _, _, _, _, aov in PASSES if getattr(view_layer, flag, False)]
    if _albedo_enabled(view_layer) or denoise:
        aovs.append("albedo")
    if (_albedo_enabled(view_layer) or denoise) and "normal" not in aovs:
        aovs.append("normal")
    return aovs


def to_pass(aov: str, pixels: np.ndarray) -> np.ndarray:
    """Tessera's pixels (rows of channels) as Blender stores the pass. Depth of a pixel
    that saw nothing is Tessera's far value; Blender's is 1e10, also "far"."""
    if aov == "depth":
        return np.where(np.isfinite(pixels), pixels, 1e10).astype(np.float32)
    return pixels.astype(np.float32, copy=False)
