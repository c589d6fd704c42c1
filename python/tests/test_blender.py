"""The Blender add-on, headless, against Cycles: PyPI's `bpy` in a virtual environment this
test creates (target/bpy-venv, with the tessera package this checkout installed linked into it),
the add-on enabled, the comparison scenes built in bpy and rendered by both engines (same resolution and
samples, denoising off, view transform Standard, linear EXR, Cycles' Filter Glossy off), compared
region by region. The ratios quoted below were measured with Filter Glossy off (since 2026-12-08)
where a comment says so or names that date; older ones moved by less than 0.5% with it."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

ROOT = Path(__file__).resolve().parents[2]
VENV = ROOT / "target" / "bpy-venv"
#: bpy on PyPI pairs with one Python: 5.0.1 with 3.11, 5.2.x with 3.13.
BPY = {(3, 11): "bpy==5.0.1", (3, 13): "bpy>=5.2,<5.3"}
SPP = 256

#: Regions where both renderers model the same thing: mean luminance within 3% of Cycles.
AGREE = [
    # A glass sphere on a floor under a sun. Measured at 256 spp (2026-12-08): 1.025 and 1.026;
    # at 2048, 1.006 and 1.027. The floor's caustic is a heavy tail that Cycles' 256-spp mean
    # falls short of (its floor 0.521 at 256 spp, 0.531 at 2048; Tessera's 0.534 at both).
    # The sphere's 2.7% is the floor's specular layer (IOR 1.5, as the box's walls), which the
    # sphere shows at grazing angles, where the two layerings part most: with the floor at
    # IOR 1 the sphere reads 1.000 (1024 spp). With Filter Glossy on: 1.019, 1.017.
    ("glass", "floor"),
    ("glass", "glass sphere"),
    # Walls under UsdPreviewSurface's dielectric specular layer (IOR 1.5), diffuse beneath it
    # by Kulla & Conty's energy coupling, against Cycles' Principled layering. Measured at 256
    # spp (2026-12-08): floor 1.018, red 1.013, green 1.013, back 1.008, sphere 0.999. With
    # Cycles' Filter Glossy on (as until then) 1.066, 1.040, 1.036, 1.031: most of what was
    # put down to the layering was the filter, which roughens the specular layer a path meets
    # after a diffuse bounce.
    ("box", "floor"),
    ("box", "red wall"),
    ("box", "green wall"),
    ("box", "back wall"),
    ("box", "rough metal sphere"),
    # The same box at IOR 1 (Lambertian walls): 0.998, 1.000, 1.001, 0.998, 0.993 (2026-12-08;
    # 1.011-1.019 with Filter Glossy on).
    ("box_matte", "floor"),
    ("box_matte", "red wall"),
    ("box_matte", "green wall"),
    ("box_matte", "back wall"),
    ("box_matte", "rough metal sphere"),
    # Light linking (Lambertian, as box_matte): the key lights the left sphere alone and the
    # right sphere casts none of the fill's shadows. Measured at 256 spp: 1.004, 1.002 and
    # 1.010; with the links dropped, Tessera's floor is 5.2x, the left sphere 1.3x and the
    # right 3.9x Cycles' linked render.
    ("linked", "floor"),
    ("linked", "key-lit sphere"),
    ("linked", "unlinked sphere"),
    # An emissive panel's own light linking, exported as a mesh light: the panel lights the
    # left sphere alone; a point light reaches all three regions. Measured at 256 spp: 1.004,
    # 1.003 and 1.011; with the panel exported without its links, 2.78, 1.18 and 1.66.
    ("emitter_linked", "floor"),
    ("emitter_linked", "panel-lit sphere"),
    ("emitter_linked", "unlinked sphere"),
    # A UDIM set (tiles.<UDIM>.png, as Blender's exporter writes a tiled image): each plane's
    # UVs lie in one tile, so each shows one solid colour under a sun (Lambertian, IOR 1).
    ("udim", "tile 1001 plane"),
    ("udim", "tile 1002 plane"),
    # Subsurface (docs/blender.md): the floor the spheres light agrees like any Lambertian floor.
    ("subsurface", "floor"),
    # True displacement (Displacement Only) raising a block out of a grid, Lambertian under a
    # sun. Measured at 128 spp: 1.000 and 0.994; with the displacement dropped, the grid reads
    # 0.837 (it lies flat, without the block's lit and shaded sides) and the floor 0.988.
    ("displaced", "floor"),
    ("displaced", "displaced grid"),
    # Lit only by a panel whose surface is an Emission shader (dropped by Blender's USD export;
    # the add-on writes it as an emissive UsdPreviewSurface), over a Diffuse BSDF floor (exported
    # with UsdPreviewSurface's specular layer; the add-on sets IOR 1). Measured at 64 spp: 1.002
    # and 1.003; without the emission correction both are black, without the diffuse one the
    # floor reads 0.912.
    ("emission_shader", "diffuse floor"),
    # The floor beside the two rough spheres (Lambertian): measured 1.004 at 256 spp.
    ("rough_diffuse", "floor"),
    # A Principled BSDF's sheen over dark bases in a white world, written as
    # tessera:SolidDielectric's fuzz (Zeltner et al.'s sheen in both): measured 0.987 and
    # 0.987 at 256 spp (the fits against Cycles' table, and the coat's layering; the floor
    # 1.006, 1.001 with Filter Glossy off); with the
    # sheen dropped, as before, 0.386 and 0.954; as the Charlie sheen it read 1.6-1.8.
    ("sheen", "floor"),
    ("sheen", "white sheen sphere"),
    ("sheen", "tinted sheen sphere"),
    # A near-black sphere whose specular has an orange Specular Tint, written as
    # tessera:SolidDielectric's specularColor: measured 0.980 at 256 spp; untinted, as the
    # export left it, 1.318.
    ("sheen", "specular tint sphere"),
    # A gold metal whose Specular Tint (1, 0.5, 0.2) is its F82 edge tint, written as
    # tessera:Metal with f82: measured 0.999 at 256 spp; untinted (Schlick, as exported) 1.063,
    # and read as Gulbrandsen's edge tint instead 1.028.
    ("sheen", "edge-tinted metal sphere"),
    # A dark sphere whose Sheen Weight is a Checker (0 and 1), baked into an image at 256²:
    # measured 0.994 at 256 spp; with the link dropped (no sheen, as before) 0.556.
    ("sheen", "checkered sheen sphere"),
    # Baked colours and a baked sheen roughness: a full sheen whose Sheen Tint is a Checker of
    # orange and blue and whose Sheen Roughness runs 0.2-0.4 across it (a Gradient), and a
    # near-black specular whose Specular Tint is a Checker of orange and white. Measured at
    # 256 spp: 0.995 and 0.996; with the roughness's link dropped (0.5) 1.506, with every link
    # dropped (as before: the sheen and the tint reported) 0.918 and 1.134.
    ("sheen", "checkered sheen tint sphere"),
    ("sheen", "checkered specular tint sphere"),
    # A Principled BSDF's Anisotropic 0.9 along Cycles' default tangent (radial around the
    # object's Z in Generated coordinates), which the add-on writes per vertex as the
    # `tangent` of tessera:Metal and tessera:SolidDielectric, with the Anisotropic Rotation as
    # `anisotropyRotation`; single scattering in both (Cycles' GGX, Tessera's energy
    # compensation off). Measured at 256 spp: floor 1.009 (1.019 with the checkered sphere
    # beside it), sphere 1.012, panel 0.999, turned specular 0.998; with Filter Glossy off
    # (2026-12-08) floor 0.998, sphere 1.006, panel 1.001, turned specular 0.986. Without the tangents (the lobes around the object's Y) the panel read
    # 3.58 and the turned specular 1.088, without the rotation 1.049. With both renderers
    # compensating, 1.09 and 1.20 on the metals: Tessera's Kulla-Conty lobe uses the
    # anisotropic lobe's own E (docs/materials.md), Cycles scales its lobe by E at
    # √(αx·αy), which loses less (docs/blender.md).
    ("anisotropic", "floor"),
    ("anisotropic", "brushed metal sphere"),
    # The panel is stretched (scale 1.4 by 0.7): Cycles places tangents as normals, Tessera as
    # directions, so the add-on writes (AᵀA)⁻¹·t. Measured 1.000; written as is, 2.406. And a
    # Displace modifier moves it along its X, where Cycles' Generated coordinates stay the
    # undeformed mesh's: measured 1.003; the tangent taken at the displaced points, 0.882.
    ("anisotropic", "brushed metal panel"),
    ("anisotropic", "turned specular sphere"),
    # A black dielectric whose Anisotropic is a Checker (0 and 1), baked into an image:
    # measured 0.984 at 256 spp (0.980 with Filter Glossy off); with the link dropped
    # (isotropic, as before) 0.931.
    ("anisotropic", "checkered specular sphere"),
    # Tangents from a Tangent node on black dielectrics: a panel along its UV map (turned a
    # quarter, written per face corner from Blender's MikkTSpace tangents) and a sphere radial
    # around X. Measured at 256 spp: 1.001 and 0.987 (the floor 1.019; with Filter Glossy
    # off, 2026-12-08, 1.001, 0.982 and 0.998); with the node's
    # tangent replaced by the default (radial around Z) the panel read 0.714, with the
    # anisotropy dropped for the link (as before) 1.250 and 1.060. The sphere's mean does not
    # tell X from Z (0.989 around Z).
    ("anisotropic", "uv-brushed panel"),
    ("anisotropic", "x-brushed sphere"),
    # A Principled BSDF's Thin Film over black dielectrics in a white world (500 nm of IOR
    # 1.33, 250 nm of IOR 1.45), written as tessera:SolidDielectric's surface film: both
    # renderers integrate the film's Airy reflectance over the spectrum (Belcour & Barla).
    # Measured at 256 spp: 1.007, 0.983 and 0.989 (with Filter Glossy off, 2026-12-08: 0.997,
    # 0.979 and 0.986); without the film 1.345 and 1.055 (the
    # colours: test_thin_film_colours_agree_channel_by_channel).
    ("thin_film", "floor"),
    # Films over metals (tessera:Metal's surface film over the complex index Cycles estimates
    # from the colour and the F82 tint): 300 nm of IOR 1.5 over silver-white, 200 nm of IOR 2
    # over gold with an orange tint. Measured at 256 spp: 1.005 and 0.988 (each channel within
    # 1.7%; with Filter Glossy off, 2026-12-08, 1.000 and 0.983); with the film dropped (as before: reported) 1.114 and 1.487 (gold's green 1.849).
    ("thin_film", "filmed metal sphere"),
    ("thin_film", "filmed gold sphere"),
    ("thin_film", "soap film sphere"),
    ("thin_film", "thin oil film sphere"),
    # A Principled BSDF's orange Coat Tint over grey, written as tessera:SolidDielectric's
    # absorbing clearcoat: measured 0.990 at 256 spp (2026-12-08), the Lambertian base
    # renormalised under the coat (docs/materials.md, Coats). By the slides' min rule it read
    # 0.958 (Filter Glossy on) and 0.947 (off), a difference bounded in [0.93, 0.99] until then;
    # as UsdPreviewSurface's untinted coat, 1.862.
    ("coats", "tinted coat sphere"),
    # An untinted coat of Coat IOR 1.8 over grey, carried as tessera:SolidDielectric's clear
    # coat with its IOR (2026-12-08): measured 1.012 at 256 spp; as UsdPreviewSurface's Disney
    # coat (its IOR reported), 1.028.
    ("coats", "untinted coat sphere"),
    # The `coats` scene's orange coat over a silver metal, written as tessera:Metal's absorbing
    # clearcoat: measured 0.996 at 256 spp (the coat over a metal takes from a specular lobe,
    # where over grey it takes from a diffuse one and reads 0.958); with Filter Glossy off
    # (2026-12-08) 0.985, the grey one 0.947, the floor beside them 0.999 (1.010 on); as exported (untinted
    # Disney coat) 1.834.
    ("coats", "tinted coat metal sphere"),
    # The same coat over silver with its Coat Tint a Checker of orange and white, baked:
    # measured 0.998 at 256 spp (0.978 with Filter Glossy off, 2026-12-08); with the link (as
    # before: the coat untinted, the tint reported) 1.165.
    ("coats", "checkered coat metal sphere"),
    ("emission_shader", "sphere"),
    # Bumps (tessera:Bump): a height ramp through a Bump node (Distance 0.5) and through Bump
    # Only displacement (Scale 0.5) tilts each plane 14° away from the sun; a flat plane between
    # them. Measured at 64 spp: 1.003, 1.002 and 1.001; without the bumps the two planes read
    # 1.207 (they shade as the flat one, which Cycles renders 17% brighter).
    ("bumped", "bump node plane"),
    ("bumped", "bump-only plane"),
    ("bumped", "flat plane"),
    # Mix Shaders as tessera:Layer: red Principled and blue Diffuse BSDF at Fac 0.3, and green
    # and white Principled BSDFs by a half-black, half-white image mask (Lambertian sides).
    # Measured at 64 spp: 1.001 and 1.001; with only the BSDF the export keeps, 1.136 and 0.797.
    ("mixed", "constant mix plane"),
    ("mixed", "masked mix plane"),
    # Inputs baked into images (tessera_blender/bake.py): a Noise through a Color Ramp, one
    # Object-coordinate Gradient material on a small and a large plane (each gets its own bake
    # and Material copy), an image's Emission Color at Strength 4, a saw Wave texture's bump
    # baked as a tangent-space normal map, and an Emission shader of a Checker texture. Measured
    # at 32 spp: 1.001, 1.015, 1.001, 1.001, 1.011 and 1.001; without the bakes and the
    # strength, 3.48, 6.96, 3.23, 0.250, 1.058 and 2.26.
    # Shaders the export drops (tessera_blender/nodes.py): a Glossy BSDF as a metal of its
    # Color, a Glass BSDF as tessera:Principled glass, and two Mix Shaders of a Transparent BSDF
    # and a red Principled BSDF as its opacity in UsdPreviewSurface's presence mode (Fac 0.6;
    # 1 − an image's alpha). Measured at 256 spp: 1.003, 0.993, 1.001, 1.004 and 1.002 (with
    # Filter Glossy off, 2026-12-08: 0.999, 1.001, 1.004, 1.001 and 1.002). At 128
    # spp, without the corrections: 0.982, 0.369 and 0.364 (the default surface), 0.744 and
    # 0.698 (opaque); with opacity in UsdPreviewSurface's default (clear glass) reading, the
    # cutouts 0.721 and 0.989 and the floor 0.986 (their shadows black).
    ("shaders", "floor"),
    ("shaders", "glossy sphere"),
    ("shaders", "glass sphere"),
    ("shaders", "cutout plane"),
    ("shaders", "image cutout plane"),
    # A Mix Shader of a blue Diffuse and a gold Glossy BSDF (Fac 0.4) as a tessera:Layer, the
    # Diffuse side the export kept made Lambertian: 1.006 at 256 spp; 0.772 with only the
    # Diffuse side (what the export keeps), and 1.059 at Fac 0 before the kept side of a mix
    # was corrected (its ior 1.5 laid a specular layer over it).
    ("shaders", "glossy mix sphere"),
    # A green Translucent BSDF plane between the camera and a point light of Blender 5's default
    # Radius 0: tessera:Principled's diffuse all transmitted, and the radius-0 sphere a point
    # light (render-core). Measured at 256 spp: 1.004; without the Translucent mapping 0.097
    # (the default surface); before the point light, 0.108 (and the glass sphere, which shows
    # the lit plane, 0.53).
    ("shaders", "translucent plane"),
    # The floor beside the coated sphere (its Lambertian base and the sun): 1.003.
    ("coats", "floor"),
    # The floor under the hair patches, their shadows on it: 0.991.
    ("hair", "floor"),
    # Hair curves (BasisCurves) whose Principled Hair BSDFs are written as tessera:Hair, both
    # Chiang et al.'s fibre: melanin 0.3 and a direct colour (0.6, 0.3, 0.1), 32 bounces in
    # both renderers. Measured at 256 spp (2026-12-08): 1.008 and 0.986. Until then they were
    # bounded as differences ([0.92, 1.0] and [0.78, 0.90]): with Filter Glossy on and 8
    # bounces they read 0.952 and 0.836; the filter off, 0.991 and 0.883. Light hair scatters
    # many times between fibres, and the budgets part at 8 (Tessera's counts every event,
    # Cycles' each kind apart). As the default grey tubes the export leaves, 0.825 and 0.270.
    ("hair", "melanin hair"),
    ("hair", "coloured hair"),
    ("procedural", "noise ramp plane"),
    ("procedural", "small gradient plane"),
    ("procedural", "large gradient plane"),
    ("procedural", "glowing plane"),
    ("procedural", "wave bump plane"),
    ("procedural", "checker emission plane"),
    # A Mix Shader by a Checker's Fac of a red Principled BSDF and a Diffuse BSDF coloured by a
    # Noise, the mask and the colour baked: 1.000 (0.955 with Fac's value, 0.5, as the mask and
    # the Diffuse BSDF's grey default; the pattern is checked below).
    ("procedural", "checker mix plane"),
    # An Add Shader of a grey Principled BSDF and an Emission of a Brick texture: 1.003 (0.690
    # with the BSDF alone, which is what the export keeps).
    ("procedural", "added glow plane"),
    # A Noise through a Color Ramp on a subdivided sphere without a UV map: baked over the
    # add-on's Smart UV Project of its cage (tessera_blender/unwrap.py). Measured at 32 spp:
    # 0.989; without the unwrap (nothing to bake over, the Base Color's grey), 1.590.
    ("procedural", "unwrapped noise sphere"),
    # Blender's world as the dome (tessera_blender/world.py, render-core's OpenEXR colour
    # interop): an HDRI (1024 × 512, a sky, a ground, a sun 10° across) at Strength 2, and a
    # procedural world coloured by direction. Measured: 0.999, 1.009 and 1.007 at 128 spp,
    # 1.000, 1.000 and 1.001 at 64; without the corrections 3.11, 0.365 and 0.212 (the map on
    # its side at strength 1) and 0.116, 0.070 and 0.077 (the export's dark grey constant). A
    # 256 × 128 HDRI read 1.036 on the floor: Cycles' linear interpolation rounds the sun's
    # few texels differently (with Closest, 1.000).
    ("world", "background"),
    ("world", "floor"),
    ("world", "sphere"),
    ("procedural_world", "background"),
    ("procedural_world", "floor"),
    ("procedural_world", "sphere"),
    # Blender's default Sky Texture, its sun 35° up: the sky rendered into the map without the
    # sun disc, the disc measured in Cycles' renderings and added as a distant light. Measured
    # at 64 spp: 0.997, 0.999 and 1.004; the map alone (its disc lost between four samples a
    # pixel), floor 0.245 and sphere 0.368; without the corrections, 0.130, 0.002 and 0.004.
    ("sky_world", "background"),
    ("sky_world", "floor"),
    ("sky_world", "sphere"),
    # A spot light straight down onto a Lambertian floor, Spot Blend 0.6, written as the cone
    # softness that gives Cycles' smoothstep (0.3733). Measured at 128 spp: 1.000; with the
    # blend written as the softness (the export's), 0.827. Its Radius is 0 (Blender 5's
    # default), a point light since 2026-12-07 (1.000; before, skipped as emitting nothing).
    ("spot", "floor"),
]

#: Regions that differ, the bound they stay in (Tessera / Cycles) and why (docs/blender.md).
DIFFER = {
    # Films on glass (tessera:Principled's film, on its glass: 400 nm of IOR 1.33 on a
    # Principled glass of IOR 1.5, 300 nm of IOR 1.45 on a Glass BSDF of roughness 0.1) against
    # black: measured 0.824 and 0.923 at 256 spp (R, G, B 0.488 / 0.880 / 1.287 and
    # 0.982 / 0.898 / 0.986). Leaving the glass, Tessera reads the film as the physical stack
    # (glass, film, air: the optical path 2·n·d·cos θ of the film's own index); Cycles reads it
    # through a film of index n / IOR, its path one IOR too short. With Cycles' reading
    # emulated, 1.021 / 1.000 / 1.011 and 1.006 / 1.023 / 1.019 (docs/blender.md).
    # Measured 0.824 and 0.906 with Filter Glossy off (2026-12-08; 0.923 on).
    ("glass_film", "filmed glass sphere"): (0.75, 0.9, "Cycles reads a film on glass from inside with its optical path one IOR too short (docs/blender.md)"),
    ("glass_film", "filmed Glass BSDF sphere"): (0.88, 0.97, "Cycles reads a film on glass from inside with its optical path one IOR too short (docs/blender.md)"),
    # A soap bubble (IOR 1 under 500 nm of IOR 1.33; both sides read alike in both renderers):
    # measured 1.037 (1.034 / 1.043 / 0.996). The film alone reflects a few percent, where the
    # two renderers' fits of the spectral integral part by a few thousandths: Tessera's misses
    # the wavelength-by-wavelength integral by up to 0.025 on this film. Without the film it
    # would not be there at all (index 1: left out of the scene).
    ("glass_film", "soap bubble"): (1.0, 1.06, "a soap film reflects a few percent, where the spectral fits part by a few thousandths"),
    # 1.041 while the spot's blend was read as Tessera's softness (the spot alone 0.975 then
    # offset part of the rest); 1.067 since it is converted (2026-12-07): the checker's
    # interpolation (1.060 at IOR 1) and the layering, as docs/blender.md explains.
    ("textured", "textured plane"): (1.0, 1.10, "layering, and texture interpolation across colour edges (docs/blender.md)"),
    # Random-walk subsurface in both, behind IOR 1.4: measured 0.968 (all of the base) and 0.970
    # (half) at 256 spp, where Tessera's region means move by up to 5% between seeds (light
    # leaves the medium through a rough boundary; Cycles' exit closure is smoother) and the
    # albedo inversions differ (Cycles' fit against van de Hulst's with Saunderson's boundary
    # term). Before the boundary term the full sphere read 0.60.
    ("subsurface", "subsurface sphere"): (0.9, 1.06, "random-walk noise and the two albedo inversions (docs/blender.md)"),
    ("subsurface", "half subsurface sphere"): (0.9, 1.06, "random-walk noise and the two albedo inversions (docs/blender.md)"),
    # Diffuse Roughness 1 (Principled) and Roughness 1 (Diffuse BSDF), grey 0.8 under a sun
    # from behind the camera, written as tessera:SolidDielectric's diffuseRoughness: both
    # energy-preserving Oren-Nayar, measured 1.029 and 1.028 at 256 spp. Cycles' multiple
    # scattering holds the base colour once more than EON's (ρ³ against ρ²): with ours made
    # ρ³ the spheres read 1.001 and 1.000. Left Lambertian (the correction dropped) they read
    # 0.850 and 0.847.
    ("rough_diffuse", "rough principled sphere"): (1.01, 1.05, "Cycles' Oren-Nayar multiple scattering goes as ρ³, EON's as ρ² (docs/materials.md)"),
    ("rough_diffuse", "rough diffuse sphere"): (1.01, 1.05, "Cycles' Oren-Nayar multiple scattering goes as ρ³, EON's as ρ² (docs/materials.md)"),
    # Diffuse Roughness from a Checker (0 and 1), baked: measured 1.023 at 256 spp, its rough
    # squares as the rough spheres; 0.940 with the link dropped (all Lambertian).
    ("rough_diffuse", "checkered rough sphere"): (1.0, 1.045, "its rough squares differ as the rough spheres do (ρ³ against ρ²)"),
}


def venv_python() -> Path:
    """The bpy environment, created on first use (bpy is a 300 MB wheel from PyPI)."""
    python = VENV / "bin" / "python"
    spec = BPY.get(sys.version_info[:2])
    assert spec, f"no bpy on PyPI for Python {sys.version_info[:2]}; use 3.11 (bpy 5.0.1) or 3.13 (bpy 5.2)"
    if not python.exists():
        subprocess.run([sys.executable, "-m", "venv", str(VENV)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "-q", spec], check=True)
    link_package(python)
    return python


def link_package(python: Path) -> None:
    """The add-on imports the package the README's command built from this checkout and
    installed for this interpreter: linked into the environment, not built a second time
    (the venv runs the same Python, so the same extension module loads)."""
    import tessera

    built = Path(tessera.__file__).parent
    assert any(built.glob("_native*")), f"{built} holds no built extension"
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], check=True, capture_output=True, text=True
    ).stdout.strip()
    link = Path(purelib) / "tessera"
    if link.is_symlink() or link.exists():
        if link.is_symlink() and link.resolve() == built.resolve():
            return
        subprocess.run([str(python), "-m", "pip", "uninstall", "-q", "-y", "tessera"], check=False)
        if link.is_symlink():
            link.unlink()
    link.symlink_to(built, target_is_directory=True)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    out = tmp_path_factory.mktemp("blender")
    script = ROOT / "dcc" / "blender" / "tests" / "run_in_blender.py"
    run = subprocess.run([str(venv_python()), str(script), str(out), str(SPP)], capture_output=True, text=True, timeout=1200)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-4000:]
    return out, json.loads((out / "results.json").read_text())


def rgb(path: Path) -> np.ndarray:
    """The Combined pass of an EXR Blender wrote, as an (h, w, 3) array."""
    f = OpenEXR.InputFile(str(path))
    dw = f.header()["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    return np.stack([np.frombuffer(f.channel(f"ViewLayer.Combined.{k}"), dtype=np.float32).reshape(h, w) for k in "RGB"], axis=-1)


def luminance(path: Path) -> np.ndarray:
    return rgb(path) @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def region_ratios(out: Path, kind: str, names: dict) -> dict:
    """Tessera / Cycles mean luminance per region, inner pixels only (a pixel and its four
    neighbours in the region: edges mix two surfaces and the renderers filter them differently)."""
    regions = np.load(out / f"{kind}_regions.npy")
    tessera, cycles = luminance(out / f"{kind}_tessera.exr"), luminance(out / f"{kind}_cycles.exr")
    ratios = {}
    for index, name in names.items():
        inner = inner_pixels(regions, int(index))
        assert inner.sum() > 100, f"{kind}/{name}: only {inner.sum()} pixels"
        ratios[name] = float(tessera[inner].mean() / cycles[inner].mean())
    return ratios


def channel_ratios(out: Path, kind: str, index: int) -> np.ndarray:
    """Tessera / Cycles mean of each of R, G and B over region `index`'s inner pixels."""
    inner = inner_pixels(np.load(out / f"{kind}_regions.npy"), index)
    return rgb(out / f"{kind}_tessera.exr")[inner].mean(axis=0) / rgb(out / f"{kind}_cycles.exr")[inner].mean(axis=0)


def inner_pixels(regions, index):
    """The pixels of region `index` whose four neighbours are in it too."""
    m = regions == index
    inner = m.copy()
    inner[1:] &= m[:-1]
    inner[:-1] &= m[1:]
    inner[:, 1:] &= m[:, :-1]
    inner[:, :-1] &= m[:, 1:]
    return inner


def test_regions_agree_with_cycles_where_both_model_the_same_thing(results):
    out, r = results
    kinds = ("box", "box_matte", "glass", "textured", "linked", "emitter_linked", "udim", "subsurface", "displaced", "emission_shader", "bumped", "mixed", "procedural", "world", "procedural_world", "sky_world", "spot", "shaders", "coats", "rough_diffuse", "sheen", "anisotropic", "thin_film", "glass_film", "hair")
    ratios = {(k, n): v for k in r if k in kinds for n, v in region_ratios(out, k, r[k]["regions"]).items()}
    for key in AGREE:
        # 3%: the issue's bound; at 256 spp both images' region means are within about 1% of
        # converged (the glass floor, lit by one sun, agrees to 2%).
        assert abs(ratios[key] - 1.0) <= 0.03, f"{key}: Tessera/Cycles {ratios[key]:.3f}"
    for key, (lo, hi, why) in DIFFER.items():
        assert lo <= ratios[key] <= hi, f"{key}: {ratios[key]:.3f} outside the documented [{lo}, {hi}] ({why})"
    assert set(AGREE) | set(DIFFER) == set(ratios), "every region is in one table"


def test_thin_film_colours_agree_channel_by_channel(results):
    """A film's colour is what it is for: each channel within 3% of Cycles'. Measured at 256
    spp: R, G, B 1.007 / 0.975 / 0.982 (soap), 1.010 / 0.983 / 0.985 (oil), 0.994 / 1.008 /
    1.004 (over silver-white metal) and 0.983 / 0.992 / 0.988 (over gold). With the film
    at three single wavelengths (Tessera's model until 2026-12-07) red read 0.87 on the soap
    film; without the film, 1.32 / 1.34 / 1.51."""
    out, r = results
    for index, name in r["thin_film"]["regions"].items():
        ratios = channel_ratios(out, "thin_film", int(index))
        assert np.all(np.abs(ratios - 1.0) <= 0.03), f"{name}: R, G, B {ratios.round(3)}"


def test_the_exporter_is_corrected(results):
    _, r = results
    assert any("sun strength x4" in c for c in r["glass"]["corrections"]), r["glass"]["corrections"]
    assert any("tessera:Principled specTrans" in c for c in r["glass"]["corrections"])
    subsurface = r["subsurface"]["corrections"]
    assert any("subsurface (weight 1, mean free path 0.05) as tessera:SolidDielectric" in c for c in subsurface), subsurface
    assert any("subsurface (weight 0.5, mean free path 0.05) as tessera:SolidDielectric" in c for c in subsurface), subsurface
    mixed = r["mixed"]["corrections"]
    assert any(c.endswith("constant_mix/TesseraMix: Mix Shader of 'Principled BSDF' and 'Diffuse BSDF' as tessera:Layer") for c in mixed), mixed
    assert any(c.endswith("masked_mix/TesseraMix: Mix Shader of 'Principled BSDF' and 'Principled BSDF.001' as tessera:Layer") for c in mixed), mixed
    emission = r["emission_shader"]["corrections"]
    assert any(c.endswith("glow: Emission shader as an emissive UsdPreviewSurface ((15, 13.5, 12))") for c in emission), emission
    assert any(c.endswith("diffuse_floor: Diffuse BSDF without a specular layer (ior 1)") for c in emission), emission
    rough = r["rough_diffuse"]["corrections"]
    for material, node, value in (("rough_principled", "Principled BSDF", "1"), ("rough_diffuse", "Diffuse BSDF", "1"), ("checkered_rough", "Principled BSDF", "baked")):
        wanted = f"{material}: {node}'s diffuse roughness {value} as tessera:SolidDielectric diffuseRoughness"
        assert any(c.endswith(wanted) for c in rough), rough
    assert not r["rough_diffuse"]["warnings"], r["rough_diffuse"]["warnings"]
    sheen = r["sheen"]["corrections"]
    assert any(c.endswith("sheen_2: sheen (weight 1, tint (1, 1, 1), roughness 0.5) as tessera:SolidDielectric fuzz") for c in sheen), sheen
    assert any(c.endswith("checkered_sheen: sheen (weight baked, tint (1, 1, 1), roughness 0.5) as tessera:SolidDielectric fuzz") for c in sheen), sheen
    assert any(c.endswith("sheen_3: sheen (weight 1, tint (1, 0.6, 0.2), roughness 0.2) as tessera:SolidDielectric fuzz") for c in sheen), sheen
    assert any(c.endswith("specular_tint: Specular Tint (1, 0.4, 0.1) as tessera:SolidDielectric specularColor") for c in sheen), sheen
    assert any(c.endswith("edge_tint: metal of edge tint (1, 0.5, 0.2) as tessera:Metal (F82)") for c in sheen), sheen
    assert any(c.endswith("checkered_sheen_tint: sheen (weight 1, tint baked, roughness baked) as tessera:SolidDielectric fuzz") for c in sheen), sheen
    assert any(c.endswith("checkered_specular_tint: Specular Tint baked as tessera:SolidDielectric specularColor") for c in sheen), sheen
    assert not r["sheen"]["warnings"], r["sheen"]["warnings"]
    brushed = r["anisotropic"]["corrections"]
    along = {"brushed_2": "RadialTangentZ", "brushed_3": "RadialTangentZ", "brushed_4": "RadialTangentZ", "checkered_brushed": "RadialTangentZ", "uv_brushed": "UVTangent_UVMap", "x_brushed": "RadialTangentX"}
    for material, amount, rotation in (("brushed_2", "0.9", 0), ("brushed_3", "0.9", 0), ("brushed_4", "0.9", 0.25), ("checkered_brushed", "baked", 0), ("uv_brushed", "0.9", 0), ("x_brushed", "0.9", 0)):
        assert any(c.endswith(f"{material}: anisotropy {amount}, rotation {rotation:g} along the tessera{along[material]} primvar") for c in brushed), brushed
    assert not r["anisotropic"]["warnings"], r["anisotropic"]["warnings"]
    film = r["thin_film"]["corrections"]
    for material, nm, ior in (("film_2", 500, 1.33), ("film_3", 250, 1.45)):
        assert any(c.endswith(f"{material}: thin film of {nm:g} nm, IOR {ior:g} as tessera:SolidDielectric's surface film") for c in film), film
    glass_film = r["glass_film"]["corrections"]
    for material, nm, ior in (("glass_film_2", 400, 1.33), ("glass_film_3", 500, 1.33)):
        assert any(c.endswith(f"{material}: thin film of {nm:g} nm, IOR {ior:g} as tessera:Principled's film") for c in glass_film), glass_film
    assert not r["glass_film"]["warnings"], r["glass_film"]["warnings"]
    coats = r["coats"]["corrections"]
    assert any(c.endswith("untinted_coat: coat of IOR 1.8, tint (1, 1, 1) as tessera:SolidDielectric's clearcoat") for c in coats), coats
    assert not r["coats"]["warnings"], r["coats"]["warnings"]
    linked = r["linked"]["corrections"]
    assert any("light linking from the receiver collection 'key receivers'" in c for c in linked), linked
    assert any("light linking from the blocker collection 'fill blockers'" in c for c in linked), linked


#: UsdPreviewSurface's inputs (its specification, version 2.6).
PREVIEW_SURFACE_INPUTS = {
    "diffuseColor", "emissiveColor", "useSpecularWorkflow", "specularColor", "metallic", "roughness", "clearcoat",
    "clearcoatRoughness", "opacity", "opacityMode", "opacityThreshold", "ior", "normal", "displacement", "occlusion",
}


def test_exported_preview_surfaces_hold_only_the_specifications_inputs(results):
    """Blender writes its Specular IOR Level as `specular`, which the reader would report as an
    unknown input on every material; the export correction drops it at the neutral 0.5."""
    _, r = results
    assert scenes_compared(r), "no comparison scene recorded its inputs"
    for kind in scenes_compared(r):
        extra = set(r[kind]["preview_inputs"]) - PREVIEW_SURFACE_INPUTS
        assert not extra, f"{kind}: {sorted(extra)}"


def scenes_compared(r) -> list:
    return [k for k in r if isinstance(r[k], dict) and "preview_inputs" in r[k]]


def test_bump_only_displacement_becomes_a_bump(results):
    """Cycles renders a Bump Only displacement as shading alone: the export writes it as a
    tessera:Bump over the same texture instead of moving the mesh (the `bumped` scene compares
    the result with Cycles)."""
    _, r = results
    corrections = r["displaced"]["corrections"]
    assert any(c.endswith("bumps/TesseraBump: Bump Only displacement as tessera:Bump") for c in corrections), corrections
    assert not any(w.startswith(("block:", "bumps:")) for w in r["displaced"]["warnings"]), r["displaced"]["warnings"]


def test_node_trees_the_export_cannot_carry_are_corrected_or_reported(results):
    """Blender's USD export keeps a Principled or Diffuse BSDF and the images behind its inputs,
    and drops or skips the rest without a word (tessera_blender/nodes.py). Each set-up of
    dcc/blender/tests/scenes.py's `node_trees` is a material named for it."""
    _, r = results
    n = r["node_reports"]
    said = {}
    for w in n["warnings"]:
        said.setdefault(w.split(":")[0], []).append(w)
    assert said.keys() == {"toon", "sheen", "render_levels", "beckmann_glass", "fresnel_mix", "ngon_tangent", "combined_tangent"}, n["warnings"]
    assert all(len(v) == 1 for v in said.values()), said
    # Baked (tessera_blender/bake.py), each to one value: a Color Ramp over the black image is
    # its first stop, black; the image's alpha (1) times Math's 0.5; the RGB node's green; a
    # Bump over a Color Ramp over that image, flat.
    corrections = n["corrections"]
    assert "ramp: Base Color baked: one value everywhere, (0, 0, 0)" in corrections, corrections
    assert "math: Roughness baked: one value everywhere, 0.5" in corrections, corrections
    assert "rgb: Base Color baked: one value everywhere, (0, 1, 0)" in corrections, corrections
    assert "ramp_bump: Normal baked: flat everywhere, so the mesh's own normals" in corrections, corrections
    # An Add Shader of a Principled BSDF (no emission) and an Emission of (1, 0.5, 0) at 2.
    assert "add_glow: Add Shader of 'Principled BSDF' and 'Emission': emission (2, 1, 0) added to the surface" in corrections, corrections
    # A plane without a UV map is baked over one the add-on makes (tessera_blender/unwrap.py),
    # written into the exported mesh; one whose exported mesh (subdivided at render time only)
    # is not the unwrapped one is said, with the value rendered instead.
    assert sum(c.endswith(": no UV map, so one by Smart UV Project to bake over (primvars:st)") for c in corrections) == 1, corrections
    assert "no_uvs: Base Color baked into an image of 1024²" in corrections, corrections
    unmatched = said["render_levels"][0]
    assert "is not Blender's corner for corner" in unmatched and "rendered with (0.8, 0.8, 0.8)" in unmatched, unmatched
    assert "'Toon BSDF'" in said["toon"][0] and "default surface" in said["toon"][0], said["toon"]
    # Mixes with a Glossy side are layers; a Fac through a Fresnel is baked as seen head-on
    # (F0 at the node's IOR 1.5: ((1.5 − 1)/(1.5 + 1))² = 0.04), and said.
    assert "/root/_materials/mix_shader/TesseraMix: Mix Shader of 'Principled BSDF' and 'Glossy BSDF' as tessera:Layer" in corrections, corrections
    assert "fresnel_mix: Fac baked: one value everywhere, 0.04" in corrections, corrections
    assert "depends on the view through 'Fresnel'" in said["fresnel_mix"][0], said["fresnel_mix"]
    # Glossy and Glass BSDFs, which the export drops, written as the surfaces they are (the
    # `shaders` comparison scene measures them); a Beckmann lobe is said to render as GGX.
    assert "/root/_materials/glossy: Glossy BSDF as UsdPreviewSurface (metallic 1)" in corrections, corrections
    assert "/root/_materials/beckmann_glass: Glass BSDF as tessera:Principled (specTrans 1)" in corrections, corrections
    assert said["beckmann_glass"] == ["beckmann_glass: the Beckmann distribution of 'Glass BSDF' is rendered as GGX"], said
    # On a half metal the sheen is not carried (the fuzz goes on opaque dielectrics and full
    # metals: the `sheen` scene).
    assert "Sheen Weight is not carried" in said["sheen"][0], "and not the tint of a coat that is not there"
    # Anisotropy along a UV map's tangents on a face of 32 corners (MikkTSpace takes tris and
    # quads), said with the mesh; along a Geometry node's Tangent, Cycles' default (radial
    # around Z), carried; along a Combine XYZ, not carried.
    assert "no tangents of UV map '(active render)' on /root/" in said["ngon_tangent"][0] and "tris/quads" in said["ngon_tangent"][0], said
    assert "/root/_materials/geometry_tangent: anisotropy 0.5, rotation 0 along the tesseraRadialTangentZ primvar" in corrections, corrections
    assert "Anisotropic is not carried (its Tangent comes from 'Combine XYZ'" in said["combined_tangent"][0], said
    # A Bump over an image becomes a tessera:Bump over it (scale: Blender's default Distance,
    # 0.001); over anything else the height image would arrive as a normal map, so the normal
    # is baked instead (flat here, so disconnected).
    assert any(c.endswith("bump/TesseraBump: Bump 'Bump' as tessera:Bump (scale 0.001, the image's a channel)") for c in n["corrections"]), n["corrections"]
    connected = n["connected"]
    assert connected["bump"] == ["normal"] and connected["ramp_bump"] == [] and connected["normal_map"] == ["normal"], connected
    # A Normal Map's Strength 0.5, dropped by the export, as the texture's scale and bias:
    # Cycles' N + s·(N_map − N) in tangent space.
    assert n["normal_map"] == {"scale": [1.0, 1.0, 1.0, 2.0], "bias": [-0.5, -0.5, 0.0, -1.0]}, n["normal_map"]
    # A Mapping, a UV, a Separate Color: carried, not reported.
    assert connected["mapped"] == ["roughness"], connected
    assert connected["ramp"] == connected["math"] == connected["rgb"] == [], "constants, not images"


def test_bakes_follow_the_bake_size_and_are_reused_until_their_tree_changes(results):
    """The `procedural` scene's nine bakes (noise, two gradients, the wave's normal, the
    checker emission, the mix's Fac and its Diffuse BSDF's colour, the added glow, the noise
    on the sphere without UVs) at Bake Size 64; a second export of the unchanged scene bakes
    nothing (a viewport re-export after an unrelated edit; the sphere's unwrap is made again
    and comes out the same); a changed Color Ramp stop, a node group put in, and a value
    changed inside that group each rebake their one material."""
    _, r = results
    reuse = r["bake_reuse"]
    assert (reuse["bakes"], reuse["sizes"]) == ([9, 0, 1, 1, 1], [[64, 64]]), reuse
    # The unwrap's copies are gone and the artist's sphere is as it was.
    assert (reuse["left"], reuse["sphere_uvs"]) == ([], 0), reuse


def test_the_world_becomes_a_dome_turned_and_scaled_as_blender_shows_it(results):
    """An HDRI world keeps its image at the Background Strength the export drops; a procedural
    one is rendered into a map, a Sky Texture's sun disc apart as a distant light (the
    comparisons above check what each lights)."""
    _, r = results
    assert "/root/env_light: the world's Strength 2 as the dome's intensity" in r["world"]["corrections"], r["world"]
    assert "/root/env_light: the world 'directions' rendered into a 1024×512 latitude-longitude image" in r["procedural_world"]["corrections"], r["procedural_world"]
    sun = [c for c in r["sky_world"]["corrections"] if c.startswith("/root/env_light_sun: the Sky Texture's sun disc as a distant light (0.545° across, ")]
    assert len(sun) == 1, r["sky_world"]["corrections"]
    assert r["world"]["warnings"] == r["procedural_world"]["warnings"] == r["sky_world"]["warnings"] == []


def test_a_baked_mix_mask_keeps_its_pattern(results):
    """A checker-masked Mix Shader keeps its checker: the region's spread of luminance matches
    Cycles' (measured 0.956 at 32 spp; with Fac's constant as the mask, 0.138)."""
    out, _ = results
    inner = inner_pixels(np.load(out / "procedural_regions.npy"), 7)
    tessera, cycles = luminance(out / "procedural_tessera.exr")[inner], luminance(out / "procedural_cycles.exr")[inner]
    assert 0.85 <= tessera.std() / cycles.std() <= 1.15, tessera.std() / cycles.std()


def test_baked_inputs_get_a_material_per_object_normals_and_their_strength(results):
    """One procedural material on two planes: each plane is baked and bound to its own copy
    (the comparison with Cycles above checks what each reads); a procedural bump is baked as a
    normal map; an image's Emission Strength, which the export drops, becomes the texture's
    scale."""
    _, r = results
    corrections = r["procedural"]["corrections"]
    assert "gradient: Base Color baked into an image of 1024² for each of its objects" in corrections, corrections
    assert "wave bump: Normal baked into a tangent-space normal map of 1024²" in corrections, corrections
    assert "checker emission: Emission baked into an image of 1024²" in corrections, corrections
    assert "added glow: Emission baked into an image of 1024²" in corrections, corrections
    assert "checker mix: Diffuse BSDF's Color baked into an image of 1024²" in corrections, corrections
    assert sum(c.startswith("gradient: a copy for ") for c in corrections) == 1, corrections
    assert "glowing: Emission Strength 4 as the emission texture's scale" in corrections, corrections
    assert r["procedural"]["warnings"] == [], r["procedural"]["warnings"]


def test_an_emissive_objects_light_linking_is_exported_as_a_mesh_light(results):
    _, r = results
    corrections = r["emitter_linked"]["corrections"]
    assert any("a mesh light (MeshLightAPI) for Panel's light linking" in c for c in corrections), corrections
    assert any("light linking from the receiver collection 'panel receivers'" in c for c in corrections), corrections


def test_moving_an_object_sends_one_transform_delta(results):
    _, r = results
    i = r["interactive"]
    assert i["sent"] == [{"path": "/root/Sphere/Sphere", "kind": "mesh", "dirty": ["transform"], "chunks": 0}], i
    assert not i["reexport"] and i["image_changed"], i
    assert i["first_tile_pixel_size"] == 8, "the first image after an edit is a coarse one"
    # Hair curves move the same way: the server holds them as a mesh under their prim's path.
    m = r["hair_move"]
    assert m["sent"] == [{"path": "/root/hair_2/hair_2", "kind": "mesh", "dirty": ["transform"], "chunks": 0}], m
    assert not m["reexport"], m


def test_errors_reach_the_artist(results):
    _, r = results
    e = r["error_reports"]
    assert e["operator"] and "missing.usdc" in e["operator"], e
    assert e["reported"] and "missing.usdc" in e["reported"][-1], e


def test_the_extension_zip_installs_and_registers_the_engine(tmp_path):
    """`dcc/blender/build_extension.py` packs the add-on with the tessera wheel; Blender
    installs the zip (in a scratch user directory) and the engine registers."""
    build = subprocess.run([sys.executable, str(ROOT / "dcc" / "blender" / "build_extension.py"), str(tmp_path)], capture_output=True, text=True, check=True)
    zip_path = build.stdout.strip().splitlines()[-1]
    env = {"HOME": str(tmp_path / "home"), "PATH": "/usr/bin:/bin"}
    script = ROOT / "dcc" / "blender" / "tests" / "install_zip.py"
    run = subprocess.run([str(venv_python()), str(script), zip_path], capture_output=True, text=True, env=env, timeout=600)
    assert "installed: ['FINISHED'] engine: True" in run.stdout, run.stdout[-2000:] + run.stderr[-2000:]


def test_the_denoise_option_brings_16_spp_closer_to_256(results):
    """With Denoise on, the saved Combined is the denoised beauty: nearer the 256-spp render
    than the raw 16-spp one (relMSE, Rousselle's ε = 0.01)."""
    out, _ = results
    reference = luminance(out / "box_tessera.exr")

    def rel_mse(name):
        img = luminance(out / name)
        return float(((img - reference) ** 2 / (reference**2 + 0.01)).mean())

    raw, denoised = rel_mse("box_raw16.exr"), rel_mse("box_denoised16.exr")
    assert denoised < 0.5 * raw, f"denoised {denoised} vs raw {raw}"
