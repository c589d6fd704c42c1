"""Inputs Blender's USD export cannot carry, baked into images with Cycles.

The export follows an input's links to the first Image Texture and drops everything else
(``nodes.py``): a Noise or Voronoi texture, a Color Ramp, a Math or Mix node, an RGB node.
Here such an input's own subgraph is rendered into an image over each object's UVs (Cycles'
Emit bake, one sample: an emission shader returns the subgraph's value at the texel's centre,
so nothing is noisy) and the input reads that image, linear and unclamped (OpenEXR, ``raw``).
An image that comes out one value everywhere becomes that value instead. A normal is baked as
Cycles shades it (its Normal bake, tangent space), an Emission shader's surface as it emits,
a Mix Shader's Fac as the tessera:Layer's mask.

A procedural texture depends on the object (Generated and Object coordinates, an object's
own UVs), so each object using the material gets its own bake: the first keeps the exported
Material, each other one a copy of it bound in its place (``split_per_object``).

Baking runs in a scratch scene holding only the object: inside Blender's render pipeline
(where a final render exports) a bake in the rendering scene writes black, measured on bpy
5.0.1. Bakes are cached by what they depend on (the node tree, the object's mesh and
placement, the size), so a viewport re-export after an unrelated edit bakes nothing.
"""

from __future__ import annotations

import hashlib
import os
import shutil

import bpy
import numpy as np

from . import nodes, unwrap

#: Texels along each side of a baked image by default (the scene's Bake Size setting).
BAKE_SIZE = 1024
#: Texels a bake bleeds past its UV islands, so filtering at a seam reads the island's value.
BAKE_MARGIN = 8
#: Node settings of the editor's layout, which no bake depends on.
LAYOUT = {"select", "location", "location_absolute", "width", "height", "hide", "label", "color", "use_custom_color", "parent"}
#: A flat tangent-space normal as Cycles' Normal bake writes it.
FLAT = (0.5, 0.5, 1.0)
#: Bakes by fingerprint -> (the image file, its one value or None), kept for the session.
_CACHE: dict[str, tuple] = {}


def users(stage, material_path: str, UsdShade) -> dict[str, list]:
    """Blender object name -> the prims (Mesh or GeomSubset) bound directly to the Material at
    `material_path`, in the exported stage."""
    out = {}
    for prim in stage.Traverse():
        if prim.GetTypeName() not in ("Mesh", "GeomSubset"):
            continue
        rel = UsdShade.MaterialBindingAPI(prim).GetDirectBindingRel()
        if rel and [str(t) for t in rel.GetTargets()] == [material_path]:
            owner = _object_name(prim)
            if owner:
                out.setdefault(owner, []).append(prim)
    return out


def meshes_of(prims) -> list:
    """The distinct Mesh prims of `prims` (Meshes, or GeomSubsets of them), in order."""
    meshes = (p if p.GetTypeName() == "Mesh" else p.GetParent() for p in prims)
    return list({str(m.GetPath()): m for m in meshes}.values())


def _object_name(prim) -> str | None:
    while prim and not prim.IsPseudoRoot():
        attr = prim.GetAttribute("userProperties:blender:object_name")
        if attr and attr.HasValue():
            return attr.Get()
        prim = prim.GetParent()
    return None


def carry(exported, material, blender_name, socket, usd_input, scale, Sdf, UsdShade, owner=None) -> str | None:
    """Bakes the subgraph linked into `socket` for every object using `material` and connects
    `usd_input` to the result times `scale`; with no socket, what the surface emits. `owner`
    names the node the input belongs to when the material has several of it (a Mix Shader's
    sides). Returns None when carried, else why not (for the warning)."""
    prim = usd_input.GetPrim().GetParent()
    objects, why = _bakeable(exported, users(prim.GetStage(), str(prim.GetPath()), UsdShade), Sdf)
    if why:
        return why
    # A normal is baked as Cycles shades it (Bake type Normal, tangent space); any other input
    # through an emission shader reading its subgraph.
    normal = blender_name == "Normal"
    blender_name = f"{owner}'s {blender_name}" if owner else blender_name
    source = None if normal or socket is None else socket.links[0].from_socket
    directory = os.path.join(os.path.dirname(exported.path), "baked")
    os.makedirs(directory, exist_ok=True)
    files, values = {}, []
    for obj, over in objects:
        try:
            files[obj.name], value = _baked(material, source, "NORMAL" if normal else "EMIT", (obj, over), directory, blender_name, exported.bake_size)
        except RuntimeError as e:  # bpy.ops reports a failed bake this way
            return f"baking it over {obj.name} failed: {str(e).strip()}"
        values.append(value)
    one = values[0] if all(v is not None and np.allclose(v, values[0], rtol=0, atol=1e-6) for v in values) else None
    if one is not None and (not normal or np.allclose(one, FLAT, rtol=0, atol=1e-3)):
        _set_one_value(exported, material, blender_name, usd_input, one * scale, normal)
        return None
    texture = _connect(prim, usd_input, blender_name, files[objects[0][0].name], Sdf, UsdShade)
    if normal:
        # Cycles writes (n + 1) / 2 in the tangent frame (MikkTSpace, as Tessera's).
        texture.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((2.0, 2.0, 2.0, 1.0))
        texture.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set((-1.0, -1.0, -1.0, 0.0))
    elif scale != 1.0:
        texture.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((scale, scale, scale, 1.0))
    exported.baked.setdefault(str(prim.GetPath()), []).append((str(texture.GetPath()), files))
    each = " for each of its objects" if len(objects) > 1 else ""
    what = "a tangent-space normal map" if normal else "an image"
    exported.corrections.append(f"{material.name}: {blender_name} baked into {what} of {exported.bake_size}²{each}")
    return None


def _bakeable(exported, by_object, Sdf):
    """The Blender objects to bake for, by name, each with the object to bake over (itself, or
    an unwrapped copy when it has no UV map: ``unwrap.py``), or why they cannot be (an object
    the export names that Blender does not have, or one that has UVs the export did not write
    as ``st``)."""
    from pxr import UsdGeom

    objects = [bpy.data.objects.get(n) for n in sorted(by_object)]
    if not objects or None in objects:
        return [], "no mesh in the export uses the material"
    pairs = []
    for obj in objects:
        meshes = meshes_of(by_object[obj.name])
        over, why = unwrap.stand_in(exported, obj, meshes, BAKE_MARGIN, Sdf, UsdGeom)
        if why:
            return [], why
        if not all(m.GetAttribute("primvars:st") for m in meshes):
            return [], f"{obj.name} has UV maps, but none exported as st to bake over"
        pairs.append((obj, over))
    return pairs, None


def _set_one_value(exported, material, blender_name, usd_input, value, normal) -> None:
    """A bake of one value everywhere: that value on the input, or for a flat normal no normal."""
    if normal:
        usd_input.GetPrim().RemoveProperty(usd_input.GetAttr().GetName())
        exported.corrections.append(f"{material.name}: Normal baked: flat everywhere, so the mesh's own normals")
        return
    _set_constant(usd_input, value)
    exported.corrections.append(f"{material.name}: {blender_name} baked: one value everywhere, {_shown(value, usd_input)}")


def _baked(material, source, kind, objects, directory, blender_name, size):
    """The image file of `source` baked for `obj` over the UVs of `over` (`objects`; ``obj`` or
    its unwrapped copy), from the cache when nothing it depends on changed, and its value when
    it is one value everywhere."""
    obj, over = objects
    key = _fingerprint(material, source, kind, obj, over, size)
    path = os.path.join(directory, f"{nodes.clean(material.name)}_{nodes.clean(blender_name)}_{nodes.clean(obj.name)}.exr")
    cached = _CACHE.get(key)
    if cached and reuse(cached[0], path):
        return path, cached[1]
    pixels = _bake(material, source, kind, over, path, size)
    rgb = pixels.reshape(-1, 4)[:, :3]
    constant = rgb[0] if np.ptp(rgb, axis=0).max() <= 1e-6 else None
    _CACHE[key] = (path, constant)
    return path, constant


def reuse(cached: str, path: str) -> bool:
    """True when the file `cached` still exists, copied to `path` (this export's directory)
    when it lies elsewhere."""
    if not os.path.exists(cached):
        return False
    if os.path.abspath(cached) != os.path.abspath(path):
        shutil.copyfile(cached, path)
    return True


def _bake(material, source, kind, obj, path, size) -> np.ndarray:
    """Renders `source` into a float image over `obj`'s UVs (with no source, Cycles' `kind` bake
    of the surface as it is: its shading normal or what it emits), saves it to `path` as
    OpenEXR and returns its RGBA pixels. The material is restored whatever happens."""
    tree = material.node_tree
    output = nodes.active_output(tree)
    surface = output.inputs["Surface"]
    was = surface.links[0].from_socket if surface.is_linked else None
    active = tree.nodes.active
    emission = tree.nodes.new("ShaderNodeEmission") if source is not None else None
    target = tree.nodes.new("ShaderNodeTexImage")
    image = bpy.data.images.new("tessera-bake", size, size, alpha=True, float_buffer=True, is_data=True)
    scratch = bpy.data.scenes.new("tessera-bake")
    others = _park_other_slots(obj, material)
    try:
        target.image = image
        if emission is not None:
            tree.links.new(source, emission.inputs["Color"])
            tree.links.new(emission.outputs["Emission"], surface)
        tree.nodes.active = target
        _bake_in(scratch, obj, kind)
        image.filepath_raw = path
        image.file_format = "OPEN_EXR"
        image.save()
        pixels = np.empty(size * size * 4, np.float32)
        image.pixels.foreach_get(pixels)
        return pixels
    finally:
        if emission is not None:
            if was is not None:
                tree.links.new(was, surface)
            tree.nodes.remove(emission)
        tree.nodes.remove(target)
        tree.nodes.active = active
        _unpark(others)
        bpy.data.images.remove(image)
        bpy.data.scenes.remove(scratch)


def _bake_in(scratch, obj, kind) -> None:
    """Cycles' bake of `kind` (Emit or Normal) of `obj` alone, in the scratch scene (see the
    module comment)."""
    scratch.render.engine = "CYCLES"
    scratch.cycles.samples = 1
    scratch.cycles.device = "CPU"
    scratch.collection.objects.link(obj)
    layer = scratch.view_layers[0]
    # An object disabled in viewports still renders, but the bake operator refuses it.
    disabled, obj.hide_viewport = obj.hide_viewport, False
    try:
        with bpy.context.temp_override(scene=scratch, view_layer=layer, active_object=obj, object=obj, selected_objects=[obj]):
            obj.select_set(True, view_layer=layer)
            layer.objects.active = obj
            bpy.ops.object.bake(type=kind, normal_space="TANGENT", margin=BAKE_MARGIN, use_clear=True, target="IMAGE_TEXTURES")
    finally:
        obj.hide_viewport = disabled


def _park_other_slots(obj, material) -> list:
    """Cycles bakes every material of the object into its active image node: the object's
    other materials get a scratch image, so their faces do not write into this bake."""
    parked = []
    others = {s.material for s in obj.material_slots if s.material and s.material != material and s.material.node_tree}
    if not others:
        return parked
    image = bpy.data.images.new("tessera-bake-scratch", 8, 8, float_buffer=True, is_data=True)
    for m in others:
        node = m.node_tree.nodes.new("ShaderNodeTexImage")
        node.image = image
        parked.append((m.node_tree, node, m.node_tree.nodes.active))
        m.node_tree.nodes.active = node
    parked.append(image)
    return parked


def _unpark(parked) -> None:
    for entry in parked:
        if isinstance(entry, tuple):
            tree, node, active = entry
            tree.nodes.remove(node)
            tree.nodes.active = active
        else:
            bpy.data.images.remove(entry)


def _connect(material_prim, usd_input, blender_name, file, Sdf, UsdShade):
    """A UsdUVTexture reading `file` over the mesh's `st`, connected to `usd_input`: its r to
    a float (a float socket bakes as grey), its rgb to a colour or a normal."""
    base = f"Baked_{nodes.clean(blender_name)}"
    texture = UsdShade.Shader.Define(material_prim.GetStage(), material_prim.GetPath().AppendChild(base))
    texture.CreateIdAttr("UsdUVTexture")
    texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(os.path.relpath(file, os.path.dirname(material_prim.GetStage().GetRootLayer().realPath)))
    texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set("raw")
    for wrap in ("wrapS", "wrapT"):
        texture.CreateInput(wrap, Sdf.ValueTypeNames.Token).Set("clamp")
    reader = UsdShade.Shader.Define(material_prim.GetStage(), material_prim.GetPath().AppendChild("Baked_st"))
    reader.CreateIdAttr("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("st")
    st = reader.CreateOutput("result", Sdf.ValueTypeNames.Float2)
    texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(st)
    single = usd_input.GetTypeName() == Sdf.ValueTypeNames.Float
    out = texture.CreateOutput("r" if single else "rgb", Sdf.ValueTypeNames.Float if single else Sdf.ValueTypeNames.Float3)
    usd_input.ConnectToSource(out)
    return texture


def _set_constant(usd_input, value) -> None:
    """`usd_input` unconnected, at the bake's one value (grey for a float input)."""
    usd_input.GetAttr().ClearConnections()
    color = str(usd_input.GetTypeName()) == "color3f"
    usd_input.Set(tuple(float(v) for v in value) if color else float(value[0]))


def split_per_object(exported, stage, Sdf, UsdShade) -> None:
    """Each object after the first of a Material with per-object bakes gets a copy of the
    Material reading its own bakes, bound in place of the original."""
    layer = stage.GetRootLayer()
    for material_path, textures in exported.baked.items():
        objects = sorted(textures[0][1])
        for obj_name in objects[1:]:
            copy = Sdf.Path(material_path).GetParentPath().AppendChild(f"{Sdf.Path(material_path).name}_{nodes.clean(obj_name)}")
            Sdf.CopySpec(layer, material_path, layer, copy)
            for texture_path, files in textures:
                own = Sdf.Path(texture_path).ReplacePrefix(material_path, copy)
                rel = os.path.relpath(files[obj_name], os.path.dirname(layer.realPath))
                UsdShade.Shader(stage.GetPrimAtPath(own)).GetInput("file").Set(rel)
            for prim in users(stage, material_path, UsdShade).get(obj_name, []):
                UsdShade.MaterialBindingAPI(prim).GetDirectBindingRel().SetTargets([copy])
            exported.corrections.append(f"{Sdf.Path(material_path).name}: a copy for {obj_name}, with its own bakes")


def _fingerprint(material, source, kind, obj, over, size) -> str:
    """What a bake depends on: the node tree's nodes, values and links, which socket, the
    object's placement, the mesh and UVs it is baked over (`over`'s), and the bake's size."""
    h = hashlib.sha256()
    hash_tree(h, material.node_tree, set())
    what = (source.node.name, source.identifier) if source is not None else kind
    h.update(repr((what, obj.name, size, BAKE_MARGIN)).encode())
    h.update(np.array(obj.matrix_world, np.float32).tobytes())
    mesh = over.data
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    h.update(co.tobytes())
    layer = mesh.uv_layers.active
    if layer is not None:
        uv = np.empty(len(layer.uv) * 2, np.float32)
        layer.uv.foreach_get("vector", uv)
        h.update(uv.tobytes())
    return h.hexdigest()


def hash_tree(h, tree, seen) -> None:
    """A node tree's nodes, settings and links into `h`, and those of the node groups it uses
    (each group once)."""
    for node in sorted(tree.nodes, key=lambda n: n.name):
        h.update(repr((node.bl_idname, node.name, _node_state(node))).encode())
        group = getattr(node, "node_tree", None)
        if group is not None and group.name not in seen:
            seen.add(group.name)
            h.update(repr(("group", group.name)).encode())
            hash_tree(h, group, seen)
    # Sorted: a bake relinks the output, which moves that link to the end of the list.
    links = sorted((link.from_node.name, link.from_socket.identifier, link.to_node.name, link.to_socket.identifier, link.is_muted) for link in tree.links)
    h.update(repr(links).encode())


def _node_state(node) -> list:
    """A node's settings and unlinked input values, as plain values."""
    state = []
    for p in node.bl_rna.properties:
        if p.type in ("ENUM", "BOOLEAN", "INT", "FLOAT", "STRING") and not p.is_readonly and not _layout(p.identifier):
            state.append((p.identifier, _plain(getattr(node, p.identifier))))
    for socket in node.inputs:
        if hasattr(socket, "default_value"):
            state.append((socket.identifier, _plain(socket.default_value)))
    ramp = getattr(node, "color_ramp", None)
    if ramp is not None:
        state.append(("ramp", ramp.interpolation, [(e.position, tuple(e.color)) for e in ramp.elements]))
    image = getattr(node, "image", None)
    if image is not None:
        state.append(("image", image.name, image.filepath, _image_version(image)))
    return state


def _image_version(image):
    """What tells an image's content apart without reading it: its file's modification time,
    or, for an image held in memory (painted, packed or generated), its pixels' hash."""
    if image.source == "FILE" and not image.packed_file and not image.is_dirty:
        path = bpy.path.abspath(image.filepath)
        return os.path.getmtime(path) if os.path.exists(path) else None
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    return hashlib.sha256(pixels.tobytes()).hexdigest()


def _layout(identifier: str) -> bool:
    """Node settings that only place or show it in the editor (selecting a node changes them)."""
    return identifier in LAYOUT or identifier.startswith("show_")


def _plain(value):
    try:
        return tuple(value)
    except TypeError:
        return value


def _shown(value, usd_input) -> str:
    """A baked value as the input holds it: a colour, or one number."""
    if str(usd_input.GetTypeName()) == "color3f":
        return "(" + ", ".join(f"{float(v):.3g}" for v in value) + ")"
    return f"{float(value[0]):.3g}"
