"""What Blender's USD exporter makes of a material's node tree, checked against the tree, so
nothing the artist built is dropped without a word (docs/blender.md has the table).

Measured on bpy 5.0.1 (``generate_preview_surface``):

* Only a Principled BSDF or a Diffuse BSDF becomes a UsdPreviewSurface. A material whose
  surface is any other shader (Emission, Glossy, Glass...) is exported without a surface; one
  whose surface is a Mix or Add Shader keeps one of the BSDFs inside it.
* From a BSDF input the exporter follows links through any node to the first Image Texture
  and connects that image: a Color Ramp, Math or Mix on the way is skipped. So a Bump node's
  height image arrives as a tangent-space normal map, which it is not.
* An input driven by nodes with no image behind them (Noise, RGB...) falls back to the
  input's own value.
* Principled inputs UsdPreviewSurface has no place for (sheen, anisotropy, tints, thin film)
  are not written, nor is a Normal Map's Strength.

The corrections here: an Emission shader becomes the emissive surface it is, a Glossy, Glass
or Translucent BSDF the metal, glass or translucent sheet it is, a Principled Hair BSDF
tessera:Hair, a Transparent BSDF mixed into a BSDF that BSDF's opacity
(present or absent, not clear glass), a Diffuse BSDF loses the specular layer
UsdPreviewSurface would add, a Bump over an image becomes a
tessera:Bump over it, a Normal Map's Strength goes into its texture's scale and bias, as does
an image's Emission Strength, a Mix Shader of two BSDFs becomes a tessera:Layer, any other
input driven by nodes the export drops or skips is baked into an image (``bake.py``), and any
other normal that went through a node the export cannot carry is disconnected. Everything
else is reported, once a material.
"""

from __future__ import annotations

import math
import re

import bpy

from . import bake

#: Principled BSDF inputs the exporter carries, by their UsdPreviewSurface names.
PRINCIPLED_CARRIED = {
    "Base Color": "diffuseColor",
    "Metallic": "metallic",
    "Roughness": "roughness",
    "IOR": "ior",
    "Alpha": "opacity",
    "Normal": "normal",
    "Coat Weight": "clearcoat",
    "Coat Roughness": "clearcoatRoughness",
    "Emission Color": "emissiveColor",
}

#: Diffuse BSDF inputs the exporter carries.
DIFFUSE_CARRIED = {"Color": "diffuseColor", "Normal": "normal"}

#: Surface inputs that are not floats, by their types' names in Sdf.ValueTypeNames.
INPUT_TYPES = {"diffuseColor": "Color3f", "emissiveColor": "Color3f", "baseColor": "Color3f", "normal": "Normal3f"}

#: Shaders the export drops that are written here as the surface they are: the shader id, its
#: fixed inputs, and its inputs by the Blender input they come from. Cycles' Glossy BSDF is
#: microfacet reflection tinted by Color with no Fresnel falloff (its OSL source: Color ×
#: microfacet), a metal whose reflectivity is Color; UsdPreviewSurface's metal rises from
#: diffuseColor to white at grazing angles (Schlick), which adds (1 − Color)/21 to its mean
#: reflectance. Its Glass BSDF is a rough dielectric tinted by Color; its Translucent BSDF
#: Lambertian transmission of Color with no reflection (Principled's diffuse all transmitted,
#: with no specular layer).
STANDALONE = {
    "BSDF_GLOSSY": ("UsdPreviewSurface", {"metallic": 1.0}, {"diffuseColor": "Color", "roughness": "Roughness"}),
    "BSDF_GLASS": ("tessera:Principled", {"specTrans": 1.0}, {"baseColor": "Color", "roughness": "Roughness", "ior": "IOR"}),
    "BSDF_TRANSLUCENT": ("tessera:Principled", {"diffTrans": 1.0, "specular": 0.0}, {"baseColor": "Color"}),
}

#: Microfacet distributions Tessera renders as they are (GGX, its energy compensated like
#: Cycles' multiscatter GGX); any other is reported.
GGX_DISTRIBUTIONS = {"GGX", "MULTI_GGX"}

#: Node types the exporter translates on the way from an input to its image: the image, its
#: UVs (a UV Map, a Texture Coordinate's UV, a 2D Mapping as UsdTransform2d), a channel of it
#: (Separate Color), a primvar (Attribute), a Normal Map into Normal, and reroutes.
CARRIED_NODES = {"TEX_IMAGE", "UVMAP", "TEX_COORD", "MAPPING", "SEPARATE_COLOR", "ATTRIBUTE", "NORMAL_MAP", "REROUTE"}


def principled_losses(node) -> list[str]:
    """Principled inputs with no UsdPreviewSurface counterpart that the artist set to something
    that shows: linked, or away from the value that does nothing. Transmission, subsurface and
    Specular IOR Level have corrections of their own in export.py."""
    value = {i.name: i.default_value for i in node.inputs if hasattr(i, "default_value")}
    linked = {i.name for i in node.inputs if i.is_linked}
    coat = "Coat Weight" in linked or float(value["Coat Weight"]) > 0.0
    # A dielectric's tinted coat goes onto tessera:SolidDielectric's, its IOR too (export.py).
    carried = coats_carried(node)
    white = (1.0, 1.0, 1.0)
    # (input, whether it matters at all, whether its value shows)
    rows = (
        ("Diffuse Roughness", carried_diffuse_roughness(node) is None, float(value["Diffuse Roughness"]) > 0.0),
        ("Specular Tint", carried_specular_tint(node) is None, tuple(value["Specular Tint"])[:3] != white),
        ("Anisotropic", carried_anisotropy(node) is None, float(value["Anisotropic"]) > 0.0),
        ("Coat IOR", coat and carried is None, float(value["Coat IOR"]) != 1.5),
        ("Coat Tint", coat and carried is None, tuple(value["Coat Tint"])[:3] != white),
        ("Coat Normal", coat, False),
        ("Sheen Weight", carried_sheen(node) is None, float(value["Sheen Weight"]) > 0.0),
        ("Thin Film Thickness", carried_thin_film(node) is None, float(value["Thin Film Thickness"]) > 0.0),
        ("Emission Strength", True, False),
    )
    return [name for name, matters, shows in rows if matters and (shows or name in linked)]


#: The input that holds a BSDF's Oren-Nayar roughness, by node type.
DIFFUSE_ROUGHNESS = {"BSDF_PRINCIPLED": "Diffuse Roughness", "BSDF_DIFFUSE": "Roughness"}


def carried_diffuse_roughness(node):
    """The Oren-Nayar roughness of a Principled or Diffuse BSDF that tessera:SolidDielectric's
    `diffuseRoughness` carries: a constant above 0, or the linked socket (export.py bakes it),
    on an opaque dielectric (``native_surface``); else None. Cycles' Oren-Nayar (since 4.3) is
    the energy-preserving one OpenPBR specifies, as ours is (docs/materials.md, "Rough
    diffuse")."""
    name = DIFFUSE_ROUGHNESS.get(node.type)
    if name is None or native_surface(node) != "dielectric":
        return None
    return _constant_or_linked(node.inputs[name], _shown_amount)


def _constant_or_linked(socket, constant):
    """A float socket as Tessera carries it: the socket itself when linked (to be baked), else
    `constant` of its value (None when that value does nothing)."""
    return socket if socket.is_linked else constant(float(socket.default_value))


def _colour_or_linked(socket):
    """A colour socket as Tessera carries it: the socket itself when linked (to be baked), else
    its value's (r, g, b)."""
    return socket if socket.is_linked else tuple(float(c) for c in tuple(socket.default_value)[:3])


def _shown_amount(value):
    """An amount in [0, 1] that shows (above 0), capped at 1; None when it is 0 or less."""
    return min(value, 1.0) if value > 0.0 else None


def carried_sheen(node):
    """A Principled BSDF's sheen as the fuzz inputs of Tessera's shaders (name -> value), or
    None. Cycles' sheen is Zeltner et al.'s, as the fuzz is (docs/materials.md, Coats). Carried
    when its weight is linked or above 0, on an opaque dielectric or a full metal
    (``native_surface``); a linked weight, tint or roughness is the socket, which export.py
    bakes."""
    if node.type != "BSDF_PRINCIPLED":
        return None
    weight = _constant_or_linked(node.inputs["Sheen Weight"], _shown_amount)
    if weight is None or native_surface(node) is None:
        return None
    return {
        "fuzz": weight,
        "fuzzColor": _colour_or_linked(node.inputs["Sheen Tint"]),
        "fuzzRoughness": _constant_or_linked(node.inputs["Sheen Roughness"], float),
    }


def carried_specular_tint(node):
    """A Principled BSDF's Specular Tint, or None. On a dielectric Cycles tints F0 and keeps
    grazing white (tessera:SolidDielectric's `specularColor`); on a metal it is the F82 tint
    (tessera:Metal's `edgeTint` with `f82`). Carried when it is linked (the socket, which
    export.py bakes) or a constant other than white, on an opaque dielectric or a full metal
    (``native_surface``)."""
    if node.type != "BSDF_PRINCIPLED":
        return None
    tint = _colour_or_linked(node.inputs["Specular Tint"])
    kind = native_surface(node)
    if tint == (1.0, 1.0, 1.0) or kind is None or (kind == "dielectric" and carried_thin_film(node)):
        # Under a dielectric's film the film's interference is the whole Fresnel: the tint is
        # reported. A metal's tint still shapes the index beneath its film.
        return None
    return tint


def carried_anisotropy(node):
    """A Principled BSDF's Anisotropic and Anisotropic Rotation as Tessera's `anisotropy` and
    `anisotropyRotation` (name -> constant, or the linked socket that export.py bakes), or None.
    Cycles stretches GGX as Tessera does (αx = r²/√(1 − 0.9a) along the tangent, αy =
    r²·√(1 − 0.9a)) and turns the tangent about the normal by the rotation's share of a turn.
    Carried when export.py can write the Tangent per mesh (``tangent_source``), the anisotropy
    linked or above 0, on an opaque dielectric or a full metal (``native_surface``)."""
    if node.type != "BSDF_PRINCIPLED" or tangent_source(node) is None or native_surface(node) is None:
        return None
    amount = _constant_or_linked(node.inputs["Anisotropic"], _shown_amount)
    if amount is None:
        return None
    return {"anisotropy": amount, "anisotropyRotation": _constant_or_linked(node.inputs["Anisotropic Rotation"], float)}


def tangent_source(node):
    """Where a Principled BSDF's Tangent runs, as export.py writes it on each mesh: ("radial",
    axis) around the object's X, Y or Z axis in Generated coordinates (unlinked or a Geometry
    node's Tangent: Cycles' default, around Z; or a radial Tangent node), ("uv", map) along a
    UV map's tangents (a Tangent node's UV Map; "" for the mesh's active render map); None when
    it comes from anything else."""
    socket = node.inputs["Tangent"]
    if not socket.is_linked:
        return ("radial", "Z")
    link = socket.links[0]
    while link.from_node.type == "REROUTE" and link.from_node.inputs[0].is_linked:
        link = link.from_node.inputs[0].links[0]
    source = link.from_node
    if source.type == "NEW_GEOMETRY" and link.from_socket.name == "Tangent":
        return ("radial", "Z")
    if source.type != "TANGENT":
        return None
    return ("radial", source.axis) if source.direction_type == "RADIAL" else ("uv", source.uv_map)


def carried_thin_film(node):
    """A Principled or Glass BSDF's Thin Film as Tessera's `filmThickness` and
    `filmRefractiveIndex` (name -> value), or None. Cycles' film replaces the specular's Fresnel
    by the film's interference, over a metal's complex index estimated from its colour and tint,
    and on glass transmits what it does not reflect, as `filmThickness` does. Carried when
    Thickness and IOR are constants and the thickness above 0: on an opaque dielectric or a full
    metal (``native_surface``: tessera:SolidDielectric's or tessera:Metal's surface film), and on
    glass without metalness (tessera:Principled's film, on its specular and its glass)."""
    if node.type not in ("BSDF_PRINCIPLED", "BSDF_GLASS") or any(node.inputs[n].is_linked for n in ("Thin Film Thickness", "Thin Film IOR")):
        return None
    thickness = float(node.inputs["Thin Film Thickness"].default_value)
    if thickness <= 0.0 or (native_surface(node) is None and not _filmed_glass(node)):
        return None
    return {"filmThickness": thickness, "filmRefractiveIndex": float(node.inputs["Thin Film IOR"].default_value)}


def _filmed_glass(node) -> bool:
    """True for glass whose film tessera:Principled carries: a Glass BSDF (written whole, in a
    mix too), or the material's own Principled BSDF (``export._correct_glass``) with a constant
    Transmission Weight above 0 and a constant Metallic of 0 (its metal takes no film)."""
    if node.type == "BSDF_GLASS":
        return True
    if not _is_material_surface(node):
        return False
    transmission, metallic = node.inputs["Transmission Weight"], node.inputs["Metallic"]
    return not transmission.is_linked and float(transmission.default_value) > 0.0 and not metallic.is_linked and float(metallic.default_value) == 0.0


def native_surface(node):
    """Which of Tessera's shaders a Principled or Diffuse BSDF can become: "dielectric"
    (tessera:SolidDielectric), "metal" (tessera:Metal) or None. Only the material's surface
    itself (not a side of a mix), without transmission and with Alpha 1 (neither shader has
    opacity), with a constant Metallic of 0 or 1."""
    if not _is_material_surface(node):
        return None
    if node.type == "BSDF_DIFFUSE":
        return "dielectric"
    return _opaque_kind(node) if node.type == "BSDF_PRINCIPLED" else None


def _is_material_surface(node) -> bool:
    """True when `node` feeds the Material Output itself, not a side of a mix."""
    return any(link.to_node.type == "OUTPUT_MATERIAL" for link in node.outputs[0].links)


def _opaque_kind(principled):
    """A Principled BSDF without transmission and with Alpha 1 (constants: neither of Tessera's
    shaders has opacity) as "dielectric" (Metallic 0) or "metal" (Metallic 1); None otherwise."""
    transmission, alpha, metallic = (principled.inputs[n] for n in ("Transmission Weight", "Alpha", "Metallic"))
    if transmission.is_linked or float(transmission.default_value) > 0.0:
        return None
    if alpha.is_linked or float(alpha.default_value) < 1.0 or metallic.is_linked:
        return None
    return {0.0: "dielectric", 1.0: "metal"}.get(float(metallic.default_value))


def coats_carried(node):
    """Which of Tessera's shaders carries a Principled BSDF's coat, whose tint and IOR
    UsdPreviewSurface cannot hold: "dielectric" (tessera:SolidDielectric's clearcoat), "metal"
    (tessera:Metal's, since 2026-12-07) or None. Constants, on an opaque dielectric or a full
    metal (no transmission, Alpha 1: the shaders have no opacity); the tint may be linked (it is
    baked). Measured on the `coats` comparison scene: a tinted coat over grey reads 0.990 of
    Cycles there (1.862 as UsdPreviewSurface's untinted coat). An untinted coat is carried on a
    dielectric only (since 2026-12-08, with its Coat IOR): the scene's untinted coat of IOR
    1.8 over grey reads 1.012 as SolidDielectric's coat, 1.028 as UsdPreviewSurface's Disney
    coat; over silver (tried the same day) the Disney coat read 0.995 and tessera:Metal's
    0.979, so a metal's untinted coat stays UsdPreviewSurface's, its Coat IOR reported. The
    sheen is not the Charlie sheen (1.63 of Cycles' microfibre sheen on a dark red sphere) but
    the fuzz, Cycles' own model (``carried_sheen``)."""
    value = {i.name: i.default_value for i in node.inputs if hasattr(i, "default_value")}
    if any(node.inputs[n].is_linked for n in ("Coat Weight", "Coat IOR")) or float(value["Coat Weight"]) <= 0.0:
        return None
    # A linked Coat Tint is baked (export.py).
    kind = _opaque_kind(node)
    if _colour_or_linked(node.inputs["Coat Tint"]) == (1.0, 1.0, 1.0) and kind == "metal":
        return None
    return kind


def active_output(tree):
    """The Material Output that renders (Blender's active one), or None."""
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    return next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)


def surface_node(material):
    """The node linked to `material`'s active output's Surface, or None."""
    tree = getattr(material, "node_tree", None)
    output = active_output(tree) if tree else None
    surface = output.inputs["Surface"] if output else None
    return surface.links[0].from_node if surface and surface.is_linked else None


def surface_shader(prim, UsdShade):
    """The shader behind the Material `prim`'s surface terminal, or None."""
    surface = UsdShade.Material(prim).ComputeSurfaceSource()[0]
    return UsdShade.Shader(surface.GetPrim()) if surface else None


def label(node) -> str:
    """A node as the artist sees it: its name, and its kind when the name does not say it."""
    return f"'{node.name}'" if node.name.startswith(node.bl_label) else f"'{node.name}' ({node.bl_label})"


def upstream(socket, seen=None) -> list:
    """Every node upstream of `socket`, nearest first, each once."""
    seen = [] if seen is None else seen
    for link in socket.links:
        node = link.from_node
        if node in seen:
            continue
        seen.append(node)
        for inp in node.inputs:
            upstream(inp, seen)
    return seen


def skipped(socket, into: str) -> list:
    """The nodes upstream of `socket` the exporter does not translate. A Texture Coordinate
    counts only through its UV output, a Normal Map only into Normal."""
    out = []
    for node in upstream(socket):
        if node.type not in CARRIED_NODES:
            out.append(node)
        elif node.type == "NORMAL_MAP" and into != "Normal":
            out.append(node)
        elif node.type == "TEX_COORD" and any(o.is_linked and o.name != "UV" for o in node.outputs):
            out.append(node)
    return out


def check(exported, prim, material, Sdf, UsdShade) -> None:
    """Holds the exported Material `prim` against Blender's `material`: corrects what can be
    corrected and adds a warning to `exported` for the rest."""
    node = surface_node(material)
    if node is None:
        return
    shader = surface_shader(prim, UsdShade)
    name = material.name
    if node.type == "BSDF_PRINCIPLED" or (node.type == "BSDF_DIFFUSE" and shader):
        _correct_bsdf(exported, material, node, shader, Sdf, UsdShade)
    elif node.type == "EMISSION":
        _correct_emission(exported, material, prim, node, shader, Sdf, UsdShade)
    elif node.type in STANDALONE:
        _write_standalone(exported, material, prim, node, shader, Sdf, UsdShade)
    elif node.type == "BSDF_HAIR_PRINCIPLED":
        _write_hair(exported, material, prim, node, shader, Sdf, UsdShade)
    elif node.type == "MIX_SHADER" and _cutout_sides(node) and shader:
        _correct_cutout(exported, material, node, shader, Sdf, UsdShade)
    elif node.type == "MIX_SHADER" and mixable(node):
        # The side the export kept is corrected here, as any BSDF; export.py rewrites the mix
        # as a tessera:Layer once the other corrections are made.
        kept = _kept_side(node, shader)
        if kept is not None:
            _correct_bsdf(exported, material, kept, shader, Sdf, UsdShade)
    elif node.type == "ADD_SHADER" and _glowing_bsdf(node) and shader:
        _correct_added_emission(exported, material, node, shader, Sdf, UsdShade)
    else:
        kept = f"only its {shader.GetPrim().GetName()} is rendered" if shader else "Tessera renders the default surface"
        exported.warnings.append(f"{name}: the surface is {label(node)}, which the USD export does not carry: {kept}")
    if active_output(material.node_tree).inputs["Volume"].is_linked:
        exported.warnings.append(f"{name}: the Volume output is not carried")


def _why_lost(bsdf, name: str) -> str:
    """Why a Principled BSDF's input `name` (``principled_losses``) is not carried."""
    if name == "Anisotropic" and tangent_source(bsdf) is None:
        return f"its Tangent comes from '{bsdf.inputs['Tangent'].links[0].from_node.name}', which the add-on does not write"
    return "UsdPreviewSurface has no such input"


def _correct_bsdf(exported, material, bsdf, shader, Sdf, UsdShade) -> None:
    """A Principled or Diffuse BSDF the export wrote as `shader`: its linked inputs checked (and
    baked where the export lost them), a Diffuse BSDF made Lambertian, and what a Principled
    BSDF has that UsdPreviewSurface cannot hold said."""
    if bsdf.type == "BSDF_PRINCIPLED":
        _check_inputs(exported, material, bsdf, PRINCIPLED_CARRIED, shader, Sdf, UsdShade)
        for lost in principled_losses(bsdf):
            exported.warnings.append(f"{material.name}: {lost} is not carried ({_why_lost(bsdf, lost)})")
    else:
        _check_inputs(exported, material, bsdf, DIFFUSE_CARRIED, shader, Sdf, UsdShade)
        _correct_diffuse(exported, material.name, shader.GetPrim().GetParent(), bsdf, shader, Sdf)


def _kept_side(node, shader):
    """The side of the Mix Shader `node` the export wrote as `shader` (by its name), or None."""
    if not shader:
        return None
    return next((side for side in _mix_sides(node) if side is not None and clean(side.name) == shader.GetPrim().GetName()), None)


def _write_standalone(exported, material, prim, node, shader, Sdf, UsdShade) -> None:
    """A Glossy, Glass or Translucent BSDF (``STANDALONE``), which the export drops, as the
    surface it is: its
    constant inputs written, its linked ones (a normal included) baked as any BSDF's are."""
    shader = _emptied(prim, shader, clean(node.name), UsdShade)
    _fill_standalone(exported, material, node, shader, Sdf, UsdShade)
    fixed = STANDALONE[node.type][1]
    exported.corrections.append(f"{prim.GetPath()}: {node.bl_label} as {shader.GetIdAttr().Get()} ({', '.join(f'{k} {v:g}' for k, v in fixed.items())})")


def _fill_standalone(exported, material, node, shader, Sdf, UsdShade, owner=None) -> None:
    """Writes the Glossy, Glass or Translucent BSDF `node` into the empty `shader`
    (``STANDALONE``); `owner` tells its baked inputs apart from another side's in a mix."""
    shader_id, fixed, inputs = STANDALONE[node.type]
    shader.SetShaderId(shader_id)
    for usd_name, value in fixed.items():
        shader.CreateInput(usd_name, Sdf.ValueTypeNames.Float).Set(value)
    for usd_name, blender_name in inputs.items():
        _write_constant(shader, usd_name, node.inputs[blender_name].default_value, Sdf)
    shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    carried = {blender_name: usd_name for usd_name, blender_name in inputs.items()} | {"Normal": "normal"}
    film = carried_thin_film(node)
    for usd_name, value in (film or {}).items():
        shader.CreateInput(usd_name, Sdf.ValueTypeNames.Float).Set(value)
    _check_inputs(exported, material, node, carried, shader, Sdf, UsdShade, owner)
    for lost in _standalone_losses(node):
        exported.warnings.append(f"{material.name}: {lost}")


def _write_constant(shader, usd_name, value, Sdf, scale=1.0) -> None:
    """A Blender socket's constant `value` (times `scale`) as the input `usd_name`: a colour's
    RGB as color3f, a number as a float."""
    if hasattr(value, "__len__"):
        shader.CreateInput(usd_name, Sdf.ValueTypeNames.Color3f).Set(tuple(float(c) * scale for c in tuple(value)[:3]))
    else:
        shader.CreateInput(usd_name, Sdf.ValueTypeNames.Float).Set(float(value) * scale)


def _emptied(prim, shader, name, UsdShade):
    """The Material `prim`'s surface shader with no inputs: the one exported, or a new one
    named `name` connected to the surface output."""
    if shader is None:
        shader = UsdShade.Shader.Define(prim.GetStage(), prim.GetPath().AppendChild(name))
        UsdShade.Material(prim).CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
        return shader
    for inp in list(shader.GetInputs()):
        shader.GetPrim().RemoveProperty(inp.GetAttr().GetName())
    return shader


def _standalone_losses(node) -> list[str]:
    """What a Glossy, Glass or Translucent BSDF has that its surface does not carry."""
    lost = []
    if getattr(node, "distribution", "GGX") not in GGX_DISTRIBUTIONS:
        lost.append(f"the {node.distribution.replace('_', ' ').title()} distribution of {label(node)} is rendered as GGX")
    for name in ("Anisotropy", "Thin Film Thickness"):
        socket = node.inputs.get(name)
        if name == "Thin Film Thickness" and carried_thin_film(node):
            continue
        if socket is not None and (socket.is_linked or float(socket.default_value) != 0.0):
            lost.append(f"the {name} of {label(node)} is not carried")
    return lost


#: tessera:Hair's inputs from a Principled Hair BSDF's, for each colour parametrization (both
#: are Chiang et al. 2016's fibre with Cycles' inputs, docs/materials.md): melanin, its
#: redness and a tint; an absorption coefficient; or a colour, which tessera:Hair's `tint`
#: turns into absorption by Chiang's fit as Cycles' direct colouring does.
HAIR_COLOUR = {
    "MELANIN": {"melanin": "Melanin", "melaninRedness": "Melanin Redness", "tint": "Tint"},
    "ABSORPTION": {"absorptionCoefficient": "Absorption Coefficient"},
    "COLOR": {"tint": "Color"},
}
#: Inputs every parametrization shares; the Huang model's lobe weights as tessera:Hair's tints
#: (Chiang's model shows none).
HAIR_SHARED = {"roughness": "Roughness", "radialRoughness": "Radial Roughness", "ior": "IOR"}
HAIR_LOBES = {"tintR": "Reflection", "tintTT": "Transmission", "tintTRT": "Secondary Reflection"}


def _write_hair(exported, material, prim, node, shader, Sdf, UsdShade) -> None:
    """A Principled Hair BSDF, which the export drops, as tessera:Hair: its colour by its
    parametrization (no melanin unless it is Melanin's), roughnesses, IOR, the Offset in
    degrees, the lobes' weights as their tints. Linked inputs, a Coat, random colour and
    roughness and the Huang model are reported."""
    shader = _emptied(prim, shader, clean(node.name), UsdShade)
    shader.SetShaderId("tessera:Hair")
    inputs = HAIR_COLOUR[node.parametrization] | HAIR_SHARED
    if node.parametrization != "MELANIN":
        shader.CreateInput("melanin", Sdf.ValueTypeNames.Float).Set(0.0)
    for usd_name, blender_name in inputs.items():
        _write_constant(shader, usd_name, node.inputs[blender_name].default_value, Sdf)
    # Blender finds only the inputs its model shows by name (Chiang's has no lobe weights,
    # Huang's no Coat).
    lobes = {usd_name: node.inputs.get(blender_name) for usd_name, blender_name in HAIR_LOBES.items()}
    for usd_name, socket in lobes.items():
        if socket is not None:
            shader.CreateInput(usd_name, Sdf.ValueTypeNames.Color3f).Set((float(socket.default_value),) * 3)
    offset = math.degrees(float(node.inputs["Offset"].default_value))
    shader.CreateInput("offset", Sdf.ValueTypeNames.Float).Set(offset)
    shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    exported.corrections.append(f"{prim.GetPath()}: Principled Hair BSDF ({node.parametrization.title()}) as tessera:Hair")
    used = [node.inputs[name] for name in list(inputs.values()) + ["Offset"]] + [s for s in lobes.values() if s is not None]
    lost = [f"{s.name} is linked" for s in used if s.is_linked]
    extras = [node.inputs.get(name) for name in ("Coat", "Random Color", "Random Roughness")]
    lost += [f"{s.name} {float(s.default_value):g}" for s in extras if s is not None and (s.is_linked or float(s.default_value) > 0.0)]
    if node.model != "CHIANG":
        lost.append(f"the {node.model.title()} model (rendered as Chiang's)")
    if lost:
        exported.warnings.append(f"{material.name}: the Principled Hair BSDF's {', '.join(lost)}: not carried")


def _cutout_sides(node):
    """A Mix Shader's (Transparent BSDF's side, 1 or 2; the other side) when it mixes a
    Transparent BSDF with a Principled or Diffuse BSDF (a cut-out, such as a leaf's alpha),
    else None."""
    sides = _mix_sides(node)
    for k, (this, other) in enumerate((sides, sides[::-1]), start=1):
        if this is not None and other is not None and this.type == "BSDF_TRANSPARENT" and other.type in MIXED_BSDFS:
            return k, other
    return None


def _correct_cutout(exported, material, node, shader, Sdf, UsdShade) -> None:
    """A Mix Shader of a Transparent BSDF and a BSDF: the export keeps the BSDF (checked as any
    BSDF is); how much of the surface is there becomes its opacity. Cycles' mix is (1 − Fac)·first
    + Fac·second, so the opacity is Fac when the Transparent BSDF is first, 1 − Fac when second.
    Shadows pass through the same share, in both renderers."""
    side, bsdf = _cutout_sides(node)
    _correct_bsdf(exported, material, bsdf, shader, Sdf, UsdShade)
    opacity = shader.GetInput("opacity") or shader.CreateInput("opacity", Sdf.ValueTypeNames.Float)
    alpha = opacity.Get() if not opacity.HasConnectedSource() else None
    if alpha is None or float(alpha) != 1.0:
        exported.warnings.append(f"{material.name}: {label(bsdf)}'s own Alpha is replaced by the Transparent BSDF's mix")
    opacity.GetAttr().ClearConnections()
    # Present or absent, as a Transparent BSDF is: UsdPreviewSurface's own reading of opacity
    # is clear glass, which bends and reflects (docs/materials.md).
    shader.CreateInput("opacityMode", Sdf.ValueTypeNames.Token).Set("presence")
    _mask(exported, material, node.inputs["Fac"], opacity, Sdf, UsdShade)
    if side == 2:
        _complement(opacity, Sdf, UsdShade)
    share = "Fac" if side == 1 else "1 − Fac"
    exported.corrections.append(f"{material.name}: Mix Shader of {label(_mix_sides(node)[side - 1])} and {label(bsdf)} as {bsdf.name}'s opacity ({share})")


def _complement(usd_input, Sdf, UsdShade) -> None:
    """`usd_input` as 1 minus what it held: its value, or its texture by scale −1 and bias 1."""
    if not usd_input.HasConnectedSource():
        usd_input.Set(1.0 - float(usd_input.Get()))
        return
    texture = UsdShade.Shader(usd_input.GetConnectedSources()[0][0].source.GetPrim())
    texture.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((-1.0, -1.0, -1.0, -1.0))
    texture.CreateInput("bias", Sdf.ValueTypeNames.Float4).Set((1.0, 1.0, 1.0, 1.0))


def _glowing_bsdf(node):
    """An Add Shader's (BSDF, Emission) when it adds an Emission shader to a Principled or
    Diffuse BSDF (a glowing surface), else None."""
    sides = [link.from_node for socket in list(node.inputs)[:2] for link in socket.links]
    bsdfs = [n for n in sides if n.type in MIXED_BSDFS]
    glows = [n for n in sides if n.type == "EMISSION"]
    return (bsdfs[0], glows[0]) if len(sides) == 2 and len(bsdfs) == 1 and len(glows) == 1 else None


def _correct_added_emission(exported, material, node, shader, Sdf, UsdShade) -> None:
    """An Add Shader of a BSDF and an Emission shader: the export keeps the BSDF, which is
    checked as any BSDF is; the Emission is added to its emissive colour (the surface's whole
    emission baked when any part of it is textured)."""
    bsdf, glow = _glowing_bsdf(node)
    principled = bsdf.type == "BSDF_PRINCIPLED"
    _correct_bsdf(exported, material, bsdf, shader, Sdf, UsdShade)
    parts = [glow.inputs["Color"], glow.inputs["Strength"]] + ([bsdf.inputs["Emission Color"], bsdf.inputs["Emission Strength"]] if principled else [])
    emissive = shader.GetInput("emissiveColor") or shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f)
    if any(p.is_linked for p in parts):
        why = bake.carry(exported, material, "Emission", None, emissive, 1.0, Sdf, UsdShade)
        if why is not None:
            exported.warnings.append(f"{material.name}: the emission added by {label(glow)} is textured and Tessera cannot bake it ({why}): the BSDF's own is used")
        return
    own = [float(c) * float(parts[3].default_value) for c in tuple(parts[2].default_value)[:3]] if principled else [0.0] * 3
    added = [o + float(c) * float(parts[1].default_value) for o, c in zip(own, tuple(parts[0].default_value)[:3])]
    emissive.GetAttr().ClearConnections()
    emissive.Set(tuple(added))
    exported.corrections.append(f"{material.name}: Add Shader of {label(bsdf)} and {label(glow)}: emission {_shown(added)} added to the surface")


def _check_inputs(exported, material, node, carried, shader, Sdf, UsdShade, owner=None) -> None:
    """Each linked BSDF input against what the export connected for it: a normal corrected or
    disconnected, any other input the export could not carry baked (``bake.py``; `owner`
    names the node when the material has several BSDFs)."""
    name = material.name
    for blender_name, usd_name in carried.items():
        socket = node.inputs[blender_name]
        if not socket.is_linked:
            continue
        lost = skipped(socket, blender_name)
        usd_input = shader.GetInput(usd_name) if shader else None
        connected = bool(usd_input) and usd_input.HasConnectedSource()
        nodes = ", ".join(label(n) for n in lost or upstream(socket))
        strength = _emission_strength(node) if usd_name == "emissiveColor" else 1.0
        if (lost or not connected) and shader:
            # The image found behind a Bump is a height map, not a tangent-space normal map.
            if blender_name == "Normal" and lost and connected and _carry_bump(exported, name, lost, usd_input, shader, Sdf, UsdShade):
                continue
            usd_input = usd_input or shader.CreateInput(usd_name, getattr(Sdf.ValueTypeNames, INPUT_TYPES.get(usd_name, "Float")))
            why = bake.carry(exported, material, blender_name, socket, usd_input, strength, Sdf, UsdShade, owner=owner)
            if why is not None:
                _report_unbaked(exported, name, blender_name, nodes, usd_input, connected, why)
        elif blender_name == "Normal":
            _correct_normal_map(exported, name, socket, usd_input, UsdShade)
        elif strength != 1.0:
            _scale_emission(exported, name, usd_input, strength, Sdf, UsdShade)


def _report_unbaked(exported, name, blender_name, nodes, usd_input, connected, why) -> None:
    """An input that could not be baked: what is rendered instead (a normal's image, which is
    not a normal map, is disconnected)."""
    if blender_name == "Normal":
        usd_input.GetPrim().RemoveProperty(usd_input.GetAttr().GetName())
        kept = "the mesh's own normals are used"
    elif connected:
        kept = "the image behind them is used unchanged"
    else:
        kept = f"rendered with {_shown(usd_input.Get())}"
    exported.warnings.append(f"{name}: {blender_name} goes through {nodes}, which the USD export does not carry and Tessera cannot bake ({why}): {kept}")


#: The scale and bias Blender's exporter puts on a texture it connects to a normal.
NORMAL_MAP_SCALE, NORMAL_MAP_BIAS = (2.0,) * 4, (-1.0,) * 4


def _emission_strength(node) -> float:
    """A Principled BSDF's Emission Strength (1 when linked: that is reported instead)."""
    socket = node.inputs["Emission Strength"]
    return 1.0 if socket.is_linked else float(socket.default_value)


def _scale_emission(exported, name, usd_input, strength, Sdf, UsdShade) -> None:
    """The export connects an Emission Color's image without its Strength: the strength goes
    into the texture's scale (a texture feeding other inputs too is copied first)."""
    source = usd_input.GetConnectedSources()[0][0]
    texture = UsdShade.Shader(source.source.GetPrim())
    stage = texture.GetPrim().GetStage()
    feeds = [i for p in stage.Traverse() if p.IsA(UsdShade.Shader) for i in UsdShade.Shader(p).GetInputs() if any(s.source.GetPrim() == texture.GetPrim() for s in i.GetConnectedSources()[0])]
    if len(feeds) > 1:
        own = texture.GetPath().GetParentPath().AppendChild(texture.GetPath().name + "_emission")
        Sdf.CopySpec(stage.GetRootLayer(), texture.GetPath(), stage.GetRootLayer(), own)
        texture = UsdShade.Shader(stage.GetPrimAtPath(own))
        usd_input.ConnectToSource(texture.GetOutput(source.sourceName))
    scale = tuple(texture.GetInput("scale").Get() or (1.0, 1.0, 1.0, 1.0)) if texture.GetInput("scale") else (1.0, 1.0, 1.0, 1.0)
    texture.CreateInput("scale", Sdf.ValueTypeNames.Float4).Set((scale[0] * strength, scale[1] * strength, scale[2] * strength, scale[3]))
    exported.corrections.append(f"{name}: Emission Strength {strength:g} as the emission texture's scale")


def _carry_bump(exported, name, lost, usd_input, shader, Sdf, UsdShade) -> bool:
    """A Bump node whose Height is an Image Texture (its Normal unlinked) as a tessera:Bump
    over the texture the export connected to the normal: scale Distance × Strength, negated
    when inverted. Strength blends the bumped normal with the plain one in Cycles; a scaled
    height is the same to first order in the slope. False when the chain is anything else."""
    bump = lost[0] if len(lost) == 1 and lost[0].type == "BUMP" else None
    height = bump.inputs["Height"] if bump else None
    if height is None or not height.is_linked or bump.inputs["Normal"].is_linked or height.links[0].from_node.type != "TEX_IMAGE":
        return False
    source = usd_input.GetConnectedSources()[0][0].source
    texture = UsdShade.Shader(source.GetPrim())
    for attr, normal_map in (("scale", NORMAL_MAP_SCALE), ("bias", NORMAL_MAP_BIAS)):
        authored = texture.GetInput(attr)
        if authored and tuple(authored.Get()) == normal_map:
            texture.GetPrim().RemoveProperty(authored.GetAttr().GetName())
    for linked in (n for n in ("Strength", "Distance") if bump.inputs[n].is_linked):
        exported.warnings.append(f"{name}: the Bump's {linked} is linked, which is not carried: its value is used")
    channel = "a" if height.links[0].from_socket.name == "Alpha" else "r"
    scale = float(bump.inputs["Distance"].default_value) * float(bump.inputs["Strength"].default_value) * (-1.0 if bump.invert else 1.0)
    path = add_bump(shader, texture, channel, scale, Sdf, UsdShade)
    exported.corrections.append(f"{path}: Bump '{bump.name}' as tessera:Bump (scale {scale:g}, the image's {channel} channel)")
    return True


def _correct_normal_map(exported, name, socket, usd_input, UsdShade) -> None:
    """A Normal Map node's Strength, which the export drops. Cycles bends the normal by
    N + s·(N_map − N) in tangent space, which is linear in the texel: scale (2s, 2s, 2s) and
    bias (−s, −s, 1 − 2s) on the texture give it exactly. Spaces other than tangent are
    reported."""
    node = next((n for n in upstream(socket) if n.type == "NORMAL_MAP"), None)
    if node is None:
        return
    if node.space != "TANGENT":
        exported.warnings.append(f"{name}: the Normal Map's {node.space.lower()} space is not carried; it is read as a tangent-space map")
    strength = node.inputs["Strength"]
    s = float(strength.default_value)
    if strength.is_linked:
        exported.warnings.append(f"{name}: the Normal Map's Strength is linked, which is not carried: strength {s:g} is used")
    if s == 1.0:
        return
    texture = UsdShade.Shader(usd_input.GetConnectedSources()[0][0].source.GetPrim())
    scale, bias = texture.GetInput("scale"), texture.GetInput("bias")
    if not (scale and bias and tuple(scale.Get()) == NORMAL_MAP_SCALE and tuple(bias.Get()) == NORMAL_MAP_BIAS):
        exported.warnings.append(f"{name}: the Normal Map's Strength {s:g} is not carried (its image is not read as the export reads a normal map)")
        return
    scale.Set((2 * s, 2 * s, 2 * s, 2.0))
    bias.Set((-s, -s, 1 - 2 * s, -1.0))
    exported.corrections.append(f"{texture.GetPath()}: Normal Map Strength {s:g} in the texture's scale and bias")


def add_bump(shader, texture, channel, scale, Sdf, UsdShade):
    """A tessera:Bump beside `shader` reading `texture`'s `channel`, connected to the shader's
    normal; its path."""
    material = shader.GetPrim().GetParent()
    bump = UsdShade.Shader.Define(material.GetStage(), material.GetPath().AppendChild("TesseraBump"))
    bump.SetShaderId("tessera:Bump")
    bump.CreateInput("height", Sdf.ValueTypeNames.Float).ConnectToSource(texture.ConnectableAPI(), channel)
    bump.CreateInput("scale", Sdf.ValueTypeNames.Float).Set(scale)
    shader.CreateInput("normal", Sdf.ValueTypeNames.Normal3f).ConnectToSource(bump.ConnectableAPI(), "out")
    return bump.GetPath()


#: BSDFs the export writes (one of them, when a Mix Shader mixes two).
MIXED_BSDFS = ("BSDF_PRINCIPLED", "BSDF_DIFFUSE")
#: BSDFs a tessera:Layer's side can be: the exported ones, and those written as ``STANDALONE``.
LAYERED_BSDFS = MIXED_BSDFS + tuple(STANDALONE)
#: Nodes whose output depends on the direction the surface is seen from, which a bake (seen
#: head-on) cannot hold.
VIEW_DEPENDENT = {"FRESNEL", "LAYER_WEIGHT", "LIGHT_PATH", "CAMERA"}


def _mix_sides(node):
    """The two shaders a Mix Shader mixes, None where a side is not linked."""
    return tuple(node.inputs[k].links[0].from_node if node.inputs[k].is_linked else None for k in (1, 2))


def mixable(node) -> bool:
    """A Mix Shader of two Principled, Diffuse, Glossy, Glass or Translucent BSDFs, which a
    tessera:Layer can carry (its Fac a constant, an Image Texture, or anything ``bake.py`` bakes)."""
    return all(side is not None and side.type in LAYERED_BSDFS for side in _mix_sides(node))


def clean(name: str) -> str:
    """A Blender node name as the USD exporter names its prim."""
    return re.sub(r"[^A-Za-z0-9_]", "_", name)


def mix_as_layer(exported, prim, material, Sdf, UsdShade) -> None:
    """A Mix Shader of two BSDFs as a tessera:Layer: Blender's export keeps one of them when it
    is a Principled or Diffuse BSDF (with its textures and the corrections above); the other
    is written here (a UsdPreviewSurface of its inputs, or a Glossy, Glass or Translucent BSDF as
    its ``STANDALONE`` surface), and the layer blends them by Fac (Cycles' mix is (1 − Fac)·first +
    Fac·second; the layer's `a` is the second, `mask` Fac). tessera:Layer blends parameters,
    which is Cycles' mix for the colours of Lambertian sides and an approximation for differing
    roughness (docs/blender.md)."""
    node = surface_node(material)
    if node is None or node.type != "MIX_SHADER" or not mixable(node):
        return
    kept = surface_shader(prim, UsdShade)
    first, second = _mix_sides(node)
    exported_side = _kept_side(node, kept)
    if kept and (exported_side is None or first == second):
        exported.warnings.append(f"{material.name}: the Mix Shader's BSDFs could not be told apart in the export; only {kept.GetPrim().GetName()} is rendered")
        return
    a, b = (kept if side is exported_side else _mixed_side(exported, material, prim, side, Sdf, UsdShade) for side in (second, first))
    layer = UsdShade.Shader.Define(prim.GetStage(), prim.GetPath().AppendChild("TesseraMix"))
    layer.SetShaderId("tessera:Layer")
    layer.CreateInput("a", Sdf.ValueTypeNames.Token).ConnectToSource(a.ConnectableAPI(), "surface")
    layer.CreateInput("b", Sdf.ValueTypeNames.Token).ConnectToSource(b.ConnectableAPI(), "surface")
    _mask(exported, material, node.inputs["Fac"], layer.CreateInput("mask", Sdf.ValueTypeNames.Float), Sdf, UsdShade)
    UsdShade.Material(prim).CreateSurfaceOutput().ConnectToSource(layer.ConnectableAPI(), "surface")
    exported.corrections.append(f"{layer.GetPath()}: Mix Shader of '{first.name}' and '{second.name}' as tessera:Layer")


#: Principled inputs written for the side of a mix the export did not keep, by
#: UsdPreviewSurface name (Emission Color is multiplied by Emission Strength).
SIDE_PRINCIPLED = {
    "diffuseColor": "Base Color",
    "metallic": "Metallic",
    "roughness": "Roughness",
    "ior": "IOR",
    "opacity": "Alpha",
    "clearcoat": "Coat Weight",
    "clearcoatRoughness": "Coat Roughness",
    "emissiveColor": "Emission Color",
}


def _mixed_side(exported, material, prim, node, Sdf, UsdShade):
    """`node` (a Principled or Diffuse BSDF) as a UsdPreviewSurface of its inputs: constants as
    they are, linked inputs baked (``bake.py``; one that cannot be is reported and its value
    used); a Glossy, Glass or Translucent BSDF as its ``STANDALONE`` surface."""
    shader = UsdShade.Shader.Define(prim.GetStage(), prim.GetPath().AppendChild(clean(node.name) + "_Mixed"))
    if node.type in STANDALONE:
        _fill_standalone(exported, material, node, shader, Sdf, UsdShade, owner=node.name)
        return shader
    shader.SetShaderId("UsdPreviewSurface")
    inputs = SIDE_PRINCIPLED if node.type == "BSDF_PRINCIPLED" else {"diffuseColor": "Color"}
    name = material.name
    linked = []
    for usd_name, blender_name in inputs.items():
        socket = node.inputs[blender_name]
        if socket.is_linked:
            linked.append((usd_name, socket))
        strength = float(node.inputs["Emission Strength"].default_value) if usd_name == "emissiveColor" else 1.0
        _write_constant(shader, usd_name, socket.default_value, Sdf, strength)
    if node.type == "BSDF_DIFFUSE":
        shader.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(1.0)  # Lambertian, as _correct_diffuse
    for usd_name, socket in linked:
        strength = _emission_strength(node) if usd_name == "emissiveColor" else 1.0
        why = bake.carry(exported, material, socket.name, socket, shader.GetInput(usd_name), strength, Sdf, UsdShade, owner=node.name)
        if why is not None:
            exported.warnings.append(f"{name}: the Mix Shader's '{node.name}' has {socket.name} linked, which Tessera cannot bake ({why}): its value is used")
    shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    return shader


def _mask(exported, material, fac, mask, Sdf, UsdShade) -> None:
    """The layer's `mask` from the Mix Shader's Fac: its value, its Image Texture read from the
    image's file, or else (other nodes, or a packed image) baked."""
    if not fac.is_linked:
        mask.Set(float(fac.default_value))
        return
    seen = [n for n in upstream(fac) if n.type in VIEW_DEPENDENT]
    if seen:
        exported.warnings.append(
            f"{material.name}: the Mix Shader's Fac depends on the view through {', '.join(label(n) for n in seen)}, which an image cannot hold: it is baked as seen head-on"
        )
    image = fac.links[0].from_node.image if fac.links[0].from_node.type == "TEX_IMAGE" else None
    if image is not None and not image.packed_file and image.source == "FILE":
        texture, channel = _image_texture(mask.GetPrim().GetParent(), fac.links[0], Sdf, UsdShade)
        mask.ConnectToSource(texture.ConnectableAPI(), channel)
        return
    why = bake.carry(exported, material, "Fac", fac, mask, 1.0, Sdf, UsdShade)
    if why is not None:
        mask.Set(float(fac.default_value))
        nodes = ", ".join(label(n) for n in upstream(fac))
        exported.warnings.append(f"{material.name}: the Mix Shader's Fac is driven by {nodes}, which Tessera cannot bake ({why}): Fac {float(fac.default_value):g} is used")


def _image_texture(prim, link, Sdf, UsdShade):
    """A UsdUVTexture of the Image Texture `link` comes from, read through the mesh's `st`,
    and the output its socket names (Alpha, else red)."""
    image = link.from_node.image
    texture = UsdShade.Shader.Define(prim.GetStage(), prim.GetPath().AppendChild(clean(link.from_node.name) + "_Mask"))
    texture.SetShaderId("UsdUVTexture")
    texture.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(bpy.path.abspath(image.filepath_from_user()) if image else "")
    space = "raw" if image is not None and image.colorspace_settings.name == "Non-Color" else "sRGB"
    texture.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(space)
    reader = UsdShade.Shader.Define(prim.GetStage(), prim.GetPath().AppendChild(clean(link.from_node.name) + "_MaskSt"))
    reader.SetShaderId("UsdPrimvarReader_float2")
    reader.CreateInput("varname", Sdf.ValueTypeNames.Token).Set("st")
    texture.CreateInput("st", Sdf.ValueTypeNames.Float2).ConnectToSource(reader.ConnectableAPI(), "result")
    channel = "a" if link.from_socket.name == "Alpha" else "r"
    texture.CreateOutput(channel, Sdf.ValueTypeNames.Float)
    return texture, channel


def _correct_diffuse(exported, name, prim, node, shader, Sdf) -> None:
    """A Diffuse BSDF is Lambertian; UsdPreviewSurface's default IOR 1.5 would lay a specular
    layer over it. IOR 1 has no Fresnel reflection."""
    shader.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(1.0)
    exported.corrections.append(f"{prim.GetPath()}: Diffuse BSDF without a specular layer (ior 1)")
    roughness = node.inputs["Roughness"]
    lost = roughness.is_linked or float(roughness.default_value) > 0.0
    if lost and carried_diffuse_roughness(node) is None:
        exported.warnings.append(f"{name}: the Diffuse BSDF's Roughness (Oren-Nayar) is not carried in a mix; the surface is Lambertian")


def _correct_emission(exported, material, prim, node, shader, Sdf, UsdShade) -> None:
    """An Emission shader, which the export drops, as a UsdPreviewSurface that only emits:
    black diffuse, no specular layer (IOR 1), emissive colour Color × Strength (the export's
    own product for a Principled BSDF's emission)."""
    color, strength = node.inputs["Color"], node.inputs["Strength"]
    shader = _emptied(prim, shader, "Emission", UsdShade)
    radiance = tuple(float(c) * float(strength.default_value) for c in tuple(color.default_value)[:3])
    shader.SetShaderId("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set((0.0, 0.0, 0.0))
    shader.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(radiance)
    shader.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(1.0)
    shader.CreateOutput("surface", Sdf.ValueTypeNames.Token)
    exported.corrections.append(f"{prim.GetPath()}: Emission shader as an emissive UsdPreviewSurface ({_shown(radiance)})")
    linked = [s for s in (color, strength) if s.is_linked]
    if linked:
        # What the shader emits, baked whole: Color × Strength wherever either is textured.
        why = bake.carry(exported, material, "Emission", None, shader.GetInput("emissiveColor"), 1.0, Sdf, UsdShade)
        if why is not None:
            nodes = ", ".join(label(n) for s in linked for n in upstream(s))
            exported.warnings.append(f"{material.name}: the Emission is driven by {nodes}, which is not carried and Tessera cannot bake ({why}): {_shown(radiance)} is used")


def _shown(value) -> str:
    if value is None:
        return "the default"
    if hasattr(value, "__len__"):
        return "(" + ", ".join(f"{float(v):g}" for v in value) + ")"
    return f"{float(value):g}"
