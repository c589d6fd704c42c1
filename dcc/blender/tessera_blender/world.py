"""Blender's world as the dome Tessera renders.

Blender's USD export (``convert_world_material``) writes the world as a ``DomeLight``. Measured
on bpy 5.0.1, it differs from what Cycles shows in these ways:

* **Orientation.** The dome is written unturned in a Z-up stage. UsdLux's latitude-longitude
  map has its pole along the dome's +Y and longitude 0 along +Z; Blender's Environment Texture
  has its pole along +Z and u = 0.5 − atan2(y, x) / 2π. The map lands on its side. The same
  map reads as Blender reads it when dome +X is Blender's +Y, +Y is +Z and +Z is +X: a
  rotateXYZ of (90°, 0, 90°) applied to the dome first (``POLE``).
* **Strength.** An Environment Texture's Background Strength is dropped (the intensity stays
  1). A constant colour's strength is kept.
* **Float images** (an HDRI) are written as OpenEXR of sRGB-coded values marked
  ``colorInteropID = "srgb_rec709_display"`` (linear 0.06 as 0.2717, 40 as 4.65): Tessera's
  texture reader decodes files so marked (``render-core/src/texture.rs``), so nothing is done
  here.
* **Anything else** (a Sky Texture, a procedural, a Mapping, mixed backgrounds) becomes a
  constant dark grey. Here the world is rendered by Cycles into a latitude-longitude image,
  Blender's way round, through a panoramic camera in a scratch scene holding only the world,
  and the dome reads that image (``PANORAMA_SAMPLES`` a pixel, cached by the world's nodes and
  the Bake Size, its width, as ``bake.py`` caches bakes). A Sky Texture's sun disc, half a
  degree across and most of the light, would fall between a few samples of a pixel or two:
  it is rendered out of the map and becomes a ``DistantLight``, measured in Cycles' own
  renderings (``_measure_sun``).
"""

from __future__ import annotations

import hashlib
import math
import os

import bpy
import mathutils
import numpy as np

from . import bake, nodes

#: The turn from UsdLux's dome space to Blender's environment space, as rotateXYZ degrees.
POLE = (90.0, 0.0, 90.0)
#: The op that carries it, after the exporter's own ops (so it applies first).
POLE_OP = "xformOp:rotateXYZ:tesseraPole"
#: Samples a pixel of a rendered world: its antialiasing (a world has no other noise). The
#: first export of a procedural world at 1024 × 512 took 2.1 s on two cores, Cycles' start-up
#: included; at 16 samples and 2048 × 1024, 10 s.
PANORAMA_SAMPLES = 4
#: The panoramic camera's turn (degrees, XYZ) that puts Cycles' equirectangular image on
#: Blender's Environment Texture convention (found by rendering a world that shows its own
#: direction as colour and matching every pixel).
PANORAMA_TURN = (90.0, 0.0, 270.0)
#: Rendered worlds by fingerprint -> (the image file, the sun measured or None), kept for the
#: session.
_CACHE: dict[str, tuple] = {}


def correct(exported, stage, scene, Sdf, UsdLux) -> None:
    """Turns each exported dome to Blender's orientation, and gives it the world's strength or
    a rendering of the world where the export could not carry it."""
    domes = [p for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI) and p.GetTypeName().startswith("DomeLight")]
    world = scene.world
    how = _carried(world)
    for prim in domes:
        _turn(prim, Sdf)
        if how == "image":
            _set_strength(exported, prim, _surface(world), Sdf)
        elif how == "render":
            _render_into(exported, prim, world, Sdf)


def _set_strength(exported, prim, background, Sdf) -> None:
    """A plain Environment Texture's dome at the Background's Strength, which the export drops."""
    strength = float(background.inputs["Strength"].default_value)
    prim.CreateAttribute("inputs:intensity", Sdf.ValueTypeNames.Float).Set(strength)
    exported.corrections.append(f"{prim.GetPath()}: the world's Strength {strength:g} as the dome's intensity")


def _turn(prim, Sdf) -> None:
    """Appends the pole turn to the dome's transform ops."""
    order = prim.GetAttribute("xformOpOrder")
    ops = list(order.Get() or []) if order else []
    if POLE_OP in ops:
        return
    prim.CreateAttribute(POLE_OP, Sdf.ValueTypeNames.Float3).Set(POLE)
    prim.CreateAttribute("xformOpOrder", Sdf.ValueTypeNames.TokenArray, variability=Sdf.VariabilityUniform).Set(ops + [POLE_OP])


def _surface(world):
    """The node behind the world's active output's Surface, or None."""
    tree = getattr(world, "node_tree", None) if world is not None and world.use_nodes else None
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_WORLD"] if tree else []
    output = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    surface = output.inputs["Surface"] if output else None
    return surface.links[0].from_node if surface is not None and surface.is_linked else None


def _carried(world) -> str | None:
    """How the dome gets the world: None, as exported (a constant colour at its strength, or
    no node world); "image", a plain Environment Texture's image at the Background Strength;
    "render", rendered (anything else)."""
    node = _surface(world)
    if node is None:
        return None
    if node.type != "BACKGROUND" or node.inputs["Strength"].is_linked:
        return "render"
    color = node.inputs["Color"]
    if not color.is_linked:
        return None
    image = color.links[0].from_node
    plain = image.type == "TEX_ENVIRONMENT" and not image.inputs["Vector"].is_linked and image.image is not None
    return "image" if plain else "render"


def _render_into(exported, prim, world, Sdf) -> None:
    """The world rendered into a latitude-longitude image the dome reads (its own turns
    dropped: the rendering holds any Mapping the world applied), and a Sky Texture's sun disc
    as a distant light beside it."""
    width = exported.bake_size
    path = os.path.join(os.path.dirname(exported.path), "baked", f"world_{nodes.clean(world.name)}.exr")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    key = _fingerprint(world, width)
    cached = _CACHE.get(key)
    if not (cached and bake.reuse(cached[0], path)):
        try:
            cached = _CACHE[key] = (path, _render_world(world, width, path))
        except RuntimeError as e:
            exported.warnings.append(f"{world.name}: the world could not be rendered for the dome ({str(e).strip()}): the export's constant is used")
            return
    prim.GetAttribute("inputs:texture:file").Set(Sdf.AssetPath(os.path.relpath(path, os.path.dirname(exported.path))))
    for name in ("inputs:intensity", "inputs:color"):
        if prim.HasAttribute(name):
            prim.RemoveProperty(name)
    ops = [op for op in (prim.GetAttribute("xformOpOrder").Get() or []) if op == POLE_OP]
    prim.GetAttribute("xformOpOrder").Set(ops)
    exported.corrections.append(f"{prim.GetPath()}: the world '{world.name}' rendered into a {width}×{width // 2} latitude-longitude image")
    if cached[1] is not None:
        _add_sun(exported, prim, *cached[1], Sdf)


def _render_world(world, width, path):
    """Renders `world` into the map at `path`, with any Sky Texture's sun disc left out; returns
    that sun as (direction, irradiance RGB, angular diameter in degrees), or None."""
    skies = [n for n in world.node_tree.nodes if n.type == "TEX_SKY" and getattr(n, "sun_disc", False)]
    _with_discs(skies, False, lambda: _render(world, PANORAMA_TURN, None, (width, width // 2), PANORAMA_SAMPLES, path))
    return _measure_sun(world, skies, path) if skies else None


def _with_discs(skies, on, work):
    """`work()` with the Sky Textures' sun discs `on`, and the discs on again after."""
    for sky in skies:
        sky.sun_disc = on
    try:
        return work()
    finally:
        for sky in skies:
            sky.sun_disc = True


def _measure_sun(world, skies, without):
    """A sky's sun disc, measured from Cycles' own renderings of the world with the disc and
    without: found against the map rendered without it (`without`), then integrated through a
    narrow camera aimed at it (irradiance = Σ radiance × each pixel's solid angle)."""

    def rendered(turn, lens, size, samples, on):
        out = os.path.join(bpy.app.tempdir or "/tmp", f"tessera-sun-{on}.exr")
        _with_discs(skies, on, lambda: _render(world, turn, lens, size, samples, out))
        return _pixels(out)

    dark = _pixels(without)
    height, width = dark.shape[:2]
    found = (rendered(PANORAMA_TURN, None, (width, height), PANORAMA_SAMPLES, True) - dark).sum(-1)
    row, col = np.unravel_index(np.argmax(found), found.shape)
    phi, theta = (0.5 - (col + 0.5) / width) * 2 * math.pi, (1 - (row + 0.5) / height) * math.pi
    direction = mathutils.Vector((math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)))
    angle = math.degrees(max(sky.sun_size for sky in skies))
    fov = math.radians(max(4 * angle, 2.0))
    turn = direction.to_track_quat("-Z", "Y")
    n = 96
    disc = rendered(turn, fov, (n, n), 16, True) - rendered(turn, fov, (n, n), 16, False)
    # A pinhole pixel's solid angle: its area on the plane at distance 1, times cos³ off axis.
    x = (np.arange(n) + 0.5) / n * 2 - 1
    r2 = (x[None, :] ** 2 + x[:, None] ** 2) * math.tan(fov / 2) ** 2
    solid = (2 * math.tan(fov / 2) / n) ** 2 / (1 + r2) ** 1.5
    irradiance = (np.clip(disc, 0, None) * solid[..., None]).sum((0, 1))
    return tuple(direction), tuple(float(v) for v in irradiance), angle


def _add_sun(exported, dome, direction, irradiance, angle, Sdf) -> None:
    """The sun as a UsdLux DistantLight beside the dome: shining along −direction, `angle`
    across, its illuminance the measured irradiance (normalize on)."""
    from pxr import Gf, UsdGeom, UsdLux  # bundled with bpy, importable once export._pxr ran

    light = UsdLux.DistantLight.Define(dome.GetStage(), dome.GetPath().GetParentPath().AppendChild(dome.GetName() + "_sun"))
    strength = max(irradiance)
    light.CreateIntensityAttr(strength)
    light.CreateColorAttr(tuple(v / strength for v in irradiance) if strength > 0 else (1.0, 1.0, 1.0))
    light.CreateAngleAttr(angle)
    light.CreateNormalizeAttr(True)
    z = np.array(direction, np.float64)
    x = np.cross((0.0, 0.0, 1.0) if abs(z[2]) < 0.99 else (1.0, 0.0, 0.0), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    rows = [list(x) + [0.0], list(y) + [0.0], list(z) + [0.0], [0.0, 0.0, 0.0, 1.0]]
    UsdGeom.Xformable(light.GetPrim()).AddTransformOp().Set(Gf.Matrix4d(rows))
    exported.corrections.append(f"{light.GetPath()}: the Sky Texture's sun disc as a distant light ({angle:.3g}° across, {strength:.4g} W/m²)")


def _render(world, turn, lens, size, samples, path) -> None:
    """Cycles' rendering of `world` alone, saved to `path` as float OpenEXR: through an
    equirectangular camera turned by `turn` (XYZ degrees) when `lens` is None, else through a
    pinhole of field of view `lens` (radians) turned by the quaternion `turn`."""
    scratch = bpy.data.scenes.new("tessera-world")
    camera = bpy.data.cameras.new("tessera-world")
    holder = bpy.data.objects.new("tessera-world", camera)
    try:
        if lens is None:
            camera.type, camera.panorama_type = "PANO", "EQUIRECTANGULAR"
            holder.rotation_euler = tuple(math.radians(a) for a in turn)
        else:
            camera.sensor_fit, camera.angle = "HORIZONTAL", lens
            holder.rotation_mode, holder.rotation_quaternion = "QUATERNION", turn
        scratch.collection.objects.link(holder)
        scratch.camera, scratch.world = holder, world
        scratch.render.engine = "CYCLES"
        scratch.cycles.samples, scratch.cycles.device, scratch.cycles.use_denoising = samples, "CPU", False
        scratch.render.resolution_x, scratch.render.resolution_y, scratch.render.resolution_percentage = size[0], size[1], 100
        scratch.render.film_transparent = False
        scratch.render.use_compositing = scratch.render.use_sequencer = False
        scratch.view_settings.view_transform = "Standard"
        settings = scratch.render.image_settings
        settings.file_format, settings.color_depth, settings.color_mode = "OPEN_EXR", "32", "RGB"
        scratch.render.filepath = path
        bpy.ops.render.render(scene=scratch.name, write_still=True)
    finally:
        bpy.data.scenes.remove(scratch)
        bpy.data.objects.remove(holder)
        bpy.data.cameras.remove(camera)


def _pixels(path) -> np.ndarray:
    """An OpenEXR's RGB as rows from the bottom, as Blender holds images."""
    image = bpy.data.images.load(path, check_existing=False)
    try:
        width, height = image.size
        pixels = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(pixels)
        return pixels.reshape(height, width, 4)[..., :3]
    finally:
        bpy.data.images.remove(image)


def _fingerprint(world, width) -> str:
    h = hashlib.sha256()
    bake.hash_tree(h, world.node_tree, set())
    h.update(repr((world.name, width, PANORAMA_SAMPLES)).encode())
    return h.hexdigest()
