"""Blender's world as the dome Tessera renders.

Blender's USD export (``convert_world_material``) writes the world as a ``DomeLight``. Measured
on bpy 5.0.1, three things in it differ from what Cycles shows:

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
  the Bake Size, its width, as ``bake.py`` caches bakes).
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil

import bpy

from . import bake

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
#: Rendered worlds by fingerprint -> the image file, kept for the session.
_CACHE: dict[str, str] = {}


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
    dropped: the rendering holds any Mapping the world applied)."""
    width = exported.bake_size
    path = os.path.join(os.path.dirname(exported.path), "baked", f"world_{bake._clean(world.name)}.exr")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    key = _fingerprint(world, width)
    cached = _CACHE.get(key)
    if cached and os.path.exists(cached):
        if os.path.abspath(cached) != os.path.abspath(path):
            shutil.copyfile(cached, path)
    else:
        try:
            _render_panorama(world, width, path)
        except RuntimeError as e:
            exported.warnings.append(f"{world.name}: the world could not be rendered for the dome ({str(e).strip()}): the export's constant is used")
            return
        _CACHE[key] = path
    prim.GetAttribute("inputs:texture:file").Set(Sdf.AssetPath(os.path.relpath(path, os.path.dirname(exported.path))))
    for name in ("inputs:intensity", "inputs:color"):
        if prim.HasAttribute(name):
            prim.RemoveProperty(name)
    ops = [op for op in (prim.GetAttribute("xformOpOrder").Get() or []) if op == POLE_OP]
    prim.GetAttribute("xformOpOrder").Set(ops)
    exported.corrections.append(f"{prim.GetPath()}: the world '{world.name}' rendered into a {width}×{width // 2} latitude-longitude image")


def _render_panorama(world, width, path) -> None:
    """Cycles' equirectangular rendering of `world` alone, saved to `path` as float OpenEXR."""
    scratch = bpy.data.scenes.new("tessera-world")
    camera = bpy.data.cameras.new("tessera-world")
    holder = bpy.data.objects.new("tessera-world", camera)
    try:
        camera.type, camera.panorama_type = "PANO", "EQUIRECTANGULAR"
        holder.rotation_euler = tuple(math.radians(a) for a in PANORAMA_TURN)
        scratch.collection.objects.link(holder)
        scratch.camera, scratch.world = holder, world
        scratch.render.engine = "CYCLES"
        scratch.cycles.samples, scratch.cycles.device, scratch.cycles.use_denoising = PANORAMA_SAMPLES, "CPU", False
        scratch.render.resolution_x, scratch.render.resolution_y, scratch.render.resolution_percentage = width, width // 2, 100
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


def _fingerprint(world, width) -> str:
    h = hashlib.sha256()
    bake._hash_tree(h, world.node_tree, set())
    h.update(repr((world.name, width, PANORAMA_SAMPLES)).encode())
    return h.hexdigest()
