"""The evaluated scene as USD, through Blender's own exporter, corrected where the export
does not say what the artist sees in Cycles (docs/blender.md has the table):

* Sun strength: the exporter divides it by 4 ("to match Karma"); Cycles' sun strength is
  irradiance in W/m², which is what UsdLux ``DistantLight`` intensity means with
  ``normalize``. We multiply it back.
* Colour temperature: the exporter writes ``enableColorTemperature = 1`` (6500 K) for every
  light; we write what the light does: off, or on at the light's temperature.
* Camera visibility: Blender's lights are not seen by camera rays unless the object's
  ray visibility says so (``visible_camera``, off by default); UsdLux lights are seen. We
  write ``tessera:visibleToCamera`` from it.
* Spot Blend: written as ``shaping:cone:softness``, whose falloff UsdLux leaves to the renderer;
  we write the softness that gives Cycles' falloff (``_correct_spot_blend``).
* Light linking: the exporter drops a light's receiver and blocker collections; we write
  them as the light's ``collection:lightLink`` and ``collection:shadowLink``, with Blender's
  rule: included objects only when any is included, all but the excluded ones otherwise.
* Glass: UsdPreviewSurface has no transmission, so the exporter drops the Principled BSDF's
  Transmission Weight. A material that has one becomes ``tessera:Principled`` with
  ``specTrans`` and the Principled inputs it shares (Disney's names).
* Specular IOR Level: written as ``inputs:specular``, which UsdPreviewSurface does not have
  (the reader would warn of an unknown input on every material). At Blender's neutral 0.5 it
  is dropped; any other level is dropped with a warning naming the material.
* Subsurface: dropped by the exporter too. A material with a Subsurface Weight becomes
  ``tessera:SolidDielectric`` with a scattering medium: Blender's radius × scale as the mean
  free path per channel, the weight, the anisotropy, and the base colour the medium shows.
* Coat Tint and Coat IOR: dropped too. An opaque dielectric's coat becomes
  ``tessera:SolidDielectric``'s clearcoat (absorbing when tinted), a full metal's tinted coat
  ``tessera:Metal``'s (``_correct_coats``).
* Diffuse roughness (a Principled BSDF's Diffuse Roughness, a Diffuse BSDF's Roughness), a
  Principled BSDF's Sheen and its Specular Tint: dropped too. On an opaque dielectric they
  become ``tessera:SolidDielectric``'s ``diffuseRoughness`` (the energy-preserving Oren-Nayar
  Cycles renders), fuzz coat (Zeltner et al.'s sheen, Cycles' too) and ``specularColor``; on a
  full metal, ``tessera:Metal`` with the tint as its F82 edge tint, and the fuzz
  (``_correct_native_surface``).
* Thin Film: dropped too. On an opaque dielectric it becomes tessera:SolidDielectric's surface
  film (``filmThickness``, ``filmRefractiveIndex``), whose interference replaces the specular's
  Fresnel as in Cycles.
* Anisotropic: dropped too. On an opaque dielectric or a full metal whose Tangent is unlinked
  (Cycles' default) or comes from a Tangent node it becomes the shader's ``anisotropy`` and
  ``anisotropyRotation``, along that tangent written on the meshes (``tangents.py``).
* Node trees: an Emission shader, a Glossy, Glass or Translucent BSDF, a Transparent BSDF
  mixed into a BSDF, a Diffuse BSDF, a Bump on the normal, a Normal Map's Strength, an
  Emission Strength on an image and a Mix Shader of two BSDFs are corrected; an input driven
  by nodes the export drops or skips (procedural textures, Color Ramps, Math) is baked into an
  image (``bake.py``); whatever else is reported (``nodes.py``).
"""

from __future__ import annotations

import math
import os
import tempfile
from dataclasses import dataclass, field

import bpy

from . import bake, nodes, tangents, unwrap, world

#: What the exporter's sun strength is divided by.
SUN_EXPORT_DIVISOR = 4.0


@dataclass
class Export:
    """A scene exported for Tessera: the file, and each object's prims in it."""

    path: str
    #: Blender object name -> paths of the Mesh, light or Camera prims it exported.
    prims: dict[str, list[str]] = field(default_factory=dict)
    #: What the corrections changed, for the log.
    corrections: list[str] = field(default_factory=list)
    #: Blender object name -> the path of the Xform prim that holds its prims.
    xforms: dict[str, str] = field(default_factory=dict)
    #: What the export cannot carry, for the artist.
    warnings: list[str] = field(default_factory=list)
    #: Material path -> (texture path, {object name: its baked file}) for each baked input.
    baked: dict[str, list] = field(default_factory=dict)
    #: Texels along each side of a baked image (the scene's Bake Size).
    bake_size: int = bake.BAKE_SIZE
    #: Blender object name -> (its unwrapped copy or None, why not), for objects without UVs
    #: whose inputs are baked (``unwrap.py``); emptied when the corrections are done.
    unwrapped: dict[str, tuple] = field(default_factory=dict)
    #: The evaluated scene the file was exported from (evaluated meshes' UV tangents), if known.
    depsgraph: object = None


def _pxr():
    bpy.utils.expose_bundled_modules()
    from pxr import Sdf, Usd, UsdLux, UsdShade  # noqa: F401

    return Sdf, Usd, UsdLux, UsdShade


def export_scene(depsgraph, directory: str | None = None) -> Export:
    """Exports the evaluated scene (render visibility) and corrects it."""
    directory = directory or tempfile.mkdtemp(prefix="tessera-")
    path = os.path.join(directory, "scene.usdc")
    with bpy.context.temp_override(scene=depsgraph.scene, view_layer=depsgraph.view_layer):
        bpy.ops.wm.usd_export(
            filepath=path,
            export_materials=True,
            generate_preview_surface=True,
            export_textures_mode="NEW",
            evaluation_mode="RENDER",
            export_custom_properties=True,
            author_blender_name=True,
            convert_world_material=True,
            export_animation=False,
        )
    exported = Export(path=path, bake_size=depsgraph.scene.tessera.bake_size, depsgraph=depsgraph)
    correct(exported, depsgraph.scene)
    return exported


def correct(exported: Export, scene) -> None:
    """Applies the corrections above to the exported file and maps objects to prims."""
    try:
        _correct_stage(exported, scene)
    finally:
        unwrap.clean_up(exported)


def _correct_stage(exported: Export, scene) -> None:
    Sdf, Usd, UsdLux, UsdShade = _pxr()
    stage = Usd.Stage.Open(exported.path)
    lights = []
    prims = list(stage.Traverse())
    # Materials first: an Emission shader made emissive here makes its objects emitters below.
    for prim in (p for p in prims if p.IsA(UsdShade.Material)):
        _correct_material(exported, prim, Sdf, UsdShade)
    for prim in prims:
        name_attr = prim.GetAttribute("userProperties:blender:object_name")
        if name_attr and name_attr.HasValue():
            obj = bpy.data.objects.get(name_attr.Get())
            exported.xforms[name_attr.Get()] = str(prim.GetPath())
            # Hair curves and points too: the server holds them as meshes under their prims'
            # paths, so a move is a transform delta.
            children = [c for c in prim.GetChildren() if c.GetTypeName() in ("Mesh", "BasisCurves", "Points", "Camera") or c.HasAPI(UsdLux.LightAPI)]
            exported.prims.setdefault(name_attr.Get(), []).extend(str(c.GetPath()) for c in children)
            for child in children:
                if obj is not None and obj.type == "LIGHT" and child.HasAPI(UsdLux.LightAPI):
                    _correct_light(exported, child, obj, UsdLux, Sdf)
                    lights.append((child, obj))
            links = getattr(obj, "light_linking", None)
            if obj is not None and obj.type != "LIGHT" and links and (links.receiver_collection or links.blocker_collection):
                # An emissive object's own linking: its meshes become mesh lights that carry
                # it (an object that emits nothing has nothing to link, in Blender too).
                for child in (c for c in children if c.GetTypeName() == "Mesh" and _emits(c, UsdShade)):
                    _make_mesh_light(exported, child, obj, UsdLux)
                    lights.append((child, obj))
    # After the traversal: a light may link objects exported after it.
    for prim, obj in lights:
        _link_light(exported, prim, obj, UsdLux)
    bake.split_per_object(exported, stage, Sdf, UsdShade)
    world.correct(exported, stage, scene, Sdf, UsdLux)
    stage.GetRootLayer().Save()


def _correct_material(exported: Export, prim, Sdf, UsdShade) -> None:
    material = bpy.data.materials.get(_material_name(prim))
    if material is not None:
        # Before the rest: they read the inputs it checks and rewrite the shader's names.
        nodes.check(exported, prim, material, Sdf, UsdShade)
    # Before glass and subsurface, which rewrite the shader without its displacement.
    _correct_displacement(exported, prim, Sdf, UsdShade)
    _correct_glass(exported, prim, Sdf, UsdShade)
    _correct_subsurface(exported, prim, Sdf, UsdShade)
    if material is not None:
        _correct_coats(exported, prim, material, Sdf, UsdShade)
        _correct_native_surface(exported, prim, material, Sdf, UsdShade)
    _drop_specular_level(exported, prim, UsdShade)
    if material is not None:
        # Last: the corrections above act on the BSDF the export kept, which the layer holds.
        nodes.mix_as_layer(exported, prim, material, Sdf, UsdShade)


def _emits(prim, UsdShade) -> bool:
    """True when the surface bound to `prim` has an emissive colour above black, or a
    connected one."""
    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    shader = material.ComputeSurfaceSource()[0] if material else None
    emissive = shader.GetInput("emissiveColor") if shader else None
    if not emissive:
        return False
    value = emissive.Get()
    return emissive.HasConnectedSource() or (value is not None and max(value) > 0.0)


def _make_mesh_light(exported: Export, prim, obj, UsdLux) -> None:
    """`prim` as a UsdLux mesh light whose glow is its material's emission at intensity 1, so
    it emits what it did, and can carry `obj`'s light linking."""
    UsdLux.MeshLightAPI.Apply(prim)
    UsdLux.LightAPI(prim).CreateMaterialSyncModeAttr().Set("materialGlowTintsLight")
    exported.corrections.append(f"{prim.GetPath()}: a mesh light (MeshLightAPI) for {obj.name}'s light linking")


def _collection_states(collection, state=None):
    """(object name, link state) for every object in a light-linking collection: an object
    listed directly has its own state; one inside a child collection takes the child's."""
    for obj, entry in zip(collection.objects, collection.collection_objects):
        yield obj.name, state or entry.light_linking.link_state
    for child, entry in zip(collection.children, collection.collection_children):
        yield from _collection_states(child, state or entry.light_linking.link_state)


def _link_light(exported: Export, prim, obj, UsdLux) -> None:
    """Blender's receiver and blocker collections as the light's link collections."""
    api = UsdLux.LightAPI(prim)
    links = obj.light_linking
    for collection, usd, what in (
        (links.receiver_collection, api.GetLightLinkCollectionAPI(), "receiver"),
        (links.blocker_collection, api.GetShadowLinkCollectionAPI(), "blocker"),
    ):
        if collection is None:
            continue
        states = list(_collection_states(collection))
        paths = {state: sorted({exported.xforms[n] for n, s in states if s == state and n in exported.xforms}) for state in ("INCLUDE", "EXCLUDE")}
        if any(s == "INCLUDE" for _, s in states):
            usd.CreateIncludeRootAttr(False)
            usd.GetIncludesRel().SetTargets(paths["INCLUDE"])
        if paths["EXCLUDE"]:
            usd.GetExcludesRel().SetTargets(paths["EXCLUDE"])
        exported.corrections.append(f"{prim.GetPath()}: light linking from the {what} collection '{collection.name}' (the exporter drops it)")


def _correct_light(exported: Export, prim, obj, UsdLux, Sdf) -> None:
    light = obj.data
    api = UsdLux.LightAPI(prim)
    prim.CreateAttribute("tessera:visibleToCamera", Sdf.ValueTypeNames.Bool).Set(bool(obj.visible_camera))
    if prim.IsA(UsdLux.DistantLight):
        intensity = api.GetIntensityAttr()
        intensity.Set(intensity.Get() * SUN_EXPORT_DIVISOR)
        exported.corrections.append(f"{prim.GetPath()}: sun strength x{SUN_EXPORT_DIVISOR:g} (the exporter divides it)")
    uses = bool(getattr(light, "use_temperature", False))
    api.CreateEnableColorTemperatureAttr().Set(uses)
    if uses:
        api.CreateColorTemperatureAttr().Set(float(light.temperature))
    if light.type == "SPOT":
        _correct_spot_blend(exported, prim, light)


def _correct_spot_blend(exported: Export, prim, light) -> None:
    """Spot Blend b, which the export writes as `shaping:cone:softness`. Cycles' falloff is a
    smoothstep in cos θ from the cone's edge, cos θo, to cos θo + (1 − cos θo)·b; Tessera's
    softness s puts the inner edge at the angle θo·(1 − s) (``render-core/src/light/mod.rs``).
    The softness whose inner edge is Cycles' makes the two the same smoothstep."""
    softness = prim.GetAttribute("inputs:shaping:cone:softness")
    if not softness or not softness.HasValue():
        return
    outer = 0.5 * float(light.spot_size)
    blend = min(max(float(light.spot_blend), 0.0), 1.0)
    cos_inner = math.cos(outer) + (1.0 - math.cos(outer)) * blend
    equivalent = 1.0 - math.acos(min(cos_inner, 1.0)) / outer if outer > 0.0 else 0.0
    softness.Set(equivalent)
    exported.corrections.append(f"{prim.GetPath()}: Spot Blend {blend:g} as cone softness {equivalent:.4g} (Cycles' smoothstep in cos θ)")


def _principled_of(prim, UsdShade):
    """The Principled BSDF the export wrote as the Material `prim`'s surface shader (the
    exporter names the shader after the node), or None: the glass, subsurface and coat
    corrections rewrite that shader, so they must read that node and no other one the tree
    holds (a Diffuse side of a mix beside an unused Principled, say)."""
    material = bpy.data.materials.get(_material_name(prim))
    tree = getattr(material, "node_tree", None)
    shader = _surface_shader(prim, UsdShade)
    if tree is None or not shader:
        return None
    return next((n for n in tree.nodes if n.type == "BSDF_PRINCIPLED" and nodes.clean(n.name) == shader.GetPrim().GetName()), None)


def _material_name(prim) -> str:
    """The Blender name of the material exported as `prim` (the prim's name is sanitised)."""
    name_attr = prim.GetAttribute("userProperties:blender:data_name")
    return name_attr.Get() if name_attr and name_attr.HasValue() else prim.GetName()


_surface_shader = nodes.surface_shader


def _correct_glass(exported: Export, prim, Sdf, UsdShade) -> None:
    node = _principled_of(prim, UsdShade)
    if node is None:
        return
    transmission = float(node.inputs["Transmission Weight"].default_value)
    if transmission <= 0.0:
        return
    shader = _surface_shader(prim, UsdShade)
    if not shader:
        return
    _warn_if_displaced(exported, prim.GetName(), shader)
    shader.SetShaderId("tessera:Principled")
    renames = {"diffuseColor": "baseColor"}
    for inp in list(shader.GetInputs()):
        name = inp.GetBaseName()
        if name in renames:
            new = shader.CreateInput(renames[name], Sdf.ValueTypeNames.Color3f)
            if inp.HasConnectedSource():
                new.ConnectToSource(inp.GetConnectedSources()[0][0])
            else:
                new.Set(inp.Get())
        if name not in ("baseColor", "metallic", "roughness", "ior", "clearcoat", "normal"):
            shader.GetPrim().RemoveProperty(inp.GetAttr().GetName())
    shader.CreateInput("specTrans", Sdf.ValueTypeNames.Float).Set(transmission)
    exported.corrections.append(f"{prim.GetPath()}: glass (Transmission Weight {transmission:g}) as tessera:Principled specTrans")
    film = nodes.carried_thin_film(node)
    if film:
        for name, value in film.items():
            shader.CreateInput(name, Sdf.ValueTypeNames.Float).Set(value)
        exported.corrections.append(f"{prim.GetPath()}: thin film of {film['filmThickness']:g} nm, IOR {film['filmRefractiveIndex']:g} as tessera:Principled's film")


#: UsdPreviewSurface inputs that keep their meaning on ``tessera:SolidDielectric``, by its names.
SOLID_DIELECTRIC_NAMES = {
    "diffuseColor": ("albedo", "Color3f"),
    "roughness": ("roughness", "Float"),
    "ior": ("refractiveIndex", "Float"),
    "clearcoat": ("clearcoat", "Float"),
    "clearcoatRoughness": ("clearcoatRoughness", "Float"),
    "emissiveColor": ("emission", "Color3f"),
    "normal": ("normal", "Normal3f"),
}


def _subsurface_of(prim, UsdShade):
    """The Principled BSDF of the Material `prim` when its surface scatters below (Subsurface
    Weight above 0), else None."""
    node = _principled_of(prim, UsdShade)
    weight = node.inputs["Subsurface Weight"] if node else None
    if weight is None or (not weight.is_linked and float(weight.default_value) <= 0.0):
        return None
    return node


def _correct_subsurface(exported: Export, prim, Sdf, UsdShade) -> None:
    name = _material_name(prim)
    node = _subsurface_of(prim, UsdShade)
    shader = _surface_shader(prim, UsdShade) if node else None
    if not shader:
        return
    weight = node.inputs["Subsurface Weight"]
    others = [n for n in ("Metallic", "Transmission Weight") if node.inputs[n].is_linked or node.inputs[n].default_value > 0.0]
    if weight.is_linked or others:
        why = "its weight is textured" if weight.is_linked else f"{' and '.join(others)} above 0"
        exported.warnings.append(f"{name}: subsurface is rendered as diffuse reflection ({why})")
        return
    _warn_if_displaced(exported, name, shader)
    _as_solid_dielectric(shader, Sdf)
    if node.subsurface_method == "RANDOM_WALK_SKIN":
        # Skin's own boundary index (Cycles' "Random Walk (Skin)" reads Subsurface IOR).
        shader.CreateInput("refractiveIndex", Sdf.ValueTypeNames.Float).Set(float(node.inputs["Subsurface IOR"].default_value))
    radius = [float(r) * float(node.inputs["Subsurface Scale"].default_value) for r in node.inputs["Subsurface Radius"].default_value]
    longest = max(radius)
    spread = [r / longest for r in radius] if longest > 0.0 else [1.0, 1.0, 1.0]
    shader.CreateInput("scatteringRadius", Sdf.ValueTypeNames.Float).Set(longest)
    shader.CreateInput("scatteringColor", Sdf.ValueTypeNames.Color3f).Set(tuple(spread))
    shader.CreateInput("scatteringWeight", Sdf.ValueTypeNames.Float).Set(float(weight.default_value))
    shader.CreateInput("scatteringAnisotropy", Sdf.ValueTypeNames.Float).Set(float(node.inputs["Subsurface Anisotropy"].default_value))
    exported.corrections.append(
        f"{prim.GetPath()}: subsurface (weight {weight.default_value:g}, mean free path {longest:g}) as tessera:SolidDielectric"
    )


def _as_solid_dielectric(shader, Sdf) -> None:
    """The UsdPreviewSurface `shader` rewritten as tessera:SolidDielectric, its inputs renamed
    (``SOLID_DIELECTRIC_NAMES``), connections kept, the rest dropped; one already rewritten
    is left as it is."""
    _renamed(shader, "tessera:SolidDielectric", SOLID_DIELECTRIC_NAMES, Sdf)


def _renamed(shader, shader_id, names, Sdf) -> None:
    """`shader` made `shader_id`, its inputs renamed by `names` (name -> (new name, type)),
    connections kept, the rest dropped; one already `shader_id` is left as it is."""
    if shader.GetIdAttr().Get() == shader_id:
        return
    shader.SetShaderId(shader_id)
    for inp in list(shader.GetInputs()):
        old = inp.GetBaseName()
        new, kind = names.get(old, (None, None))
        if new and new != old:
            moved = shader.CreateInput(new, getattr(Sdf.ValueTypeNames, kind))
            if inp.HasConnectedSource():
                moved.ConnectToSource(inp.GetConnectedSources()[0][0])
            else:
                moved.Set(inp.Get())
        if new != old:
            shader.GetPrim().RemoveProperty(inp.GetAttr().GetName())


def _correct_coats(exported: Export, prim, material, Sdf, UsdShade) -> None:
    """A Principled BSDF's coat, whose tint and IOR UsdPreviewSurface cannot hold, on
    tessera:SolidDielectric's or, tinted on a full metal, tessera:Metal's clearcoat
    (``nodes.coats_carried`` says when): Coat IOR as the coat's index, Coat Tint as the colour a
    head-on pass through a coat of thickness 1 absorbs towards (Cycles tints by Coat Tint to
    the power of the path length through the coat, 1 head-on)."""
    node = _principled_of(prim, UsdShade)
    shader = _surface_shader(prim, UsdShade) if node is not None else None
    kind = nodes.coats_carried(node) if shader else None
    if kind is None:
        return
    _warn_if_displaced(exported, material.name, shader)
    if kind == "metal":
        _as_metal(shader, Sdf)
        # Untinted; a carried Specular Tint replaces it (_correct_native_surface, which follows).
        shader.CreateInput("edgeTint", Sdf.ValueTypeNames.Color3f).Set((1.0, 1.0, 1.0))
    else:
        _as_solid_dielectric(shader, Sdf)
    ior = float(node.inputs["Coat IOR"].default_value)
    # A linked tint is baked; white absorbs nothing.
    tint = nodes._colour_or_linked(node.inputs["Coat Tint"])
    shader.CreateInput("clearcoatRefractiveIndex", Sdf.ValueTypeNames.Float).Set(ior)
    _set_or_bake(exported, material, shader, "clearcoatAttenuationColor", tint, Sdf, UsdShade)
    shader.CreateInput("clearcoatThickness", Sdf.ValueTypeNames.Float).Set(1.0)
    exported.corrections.append(f"{prim.GetPath()}: coat of IOR {ior:g}, tint {_said(tint)} as {shader.GetIdAttr().Get()}'s clearcoat")


def _correct_native_surface(exported: Export, prim, material, Sdf, UsdShade) -> None:
    """What UsdPreviewSurface cannot hold of an opaque dielectric or a full metal, on Tessera's
    own shader for it (``nodes.native_surface``): a Principled BSDF's Diffuse Roughness or a
    Diffuse BSDF's Roughness as tessera:SolidDielectric's `diffuseRoughness` (the
    energy-preserving Oren-Nayar Cycles renders), a Principled BSDF's Sheen as the fuzz coat
    (Zeltner et al.'s sheen, Cycles' too), its Specular Tint as a dielectric's `specularColor`
    or a metal's F82 `edgeTint` (tessera:Metal, reflectivity the base colour)."""
    node = nodes.surface_node(material)
    kind = nodes.native_surface(node) if node is not None else None
    if kind is None:
        return
    sigma, sheen, tint = nodes.carried_diffuse_roughness(node), nodes.carried_sheen(node), nodes.carried_specular_tint(node)
    anisotropy, film = nodes.carried_anisotropy(node), nodes.carried_thin_film(node)
    shader = _surface_shader(prim, UsdShade) if sigma is not None or sheen or tint or anisotropy or film else None
    if not shader:
        return
    _warn_if_displaced(exported, material.name, shader)
    if kind == "metal":
        _as_metal(shader, Sdf)
        _set_or_bake(exported, material, shader, "edgeTint", tint or (1.0, 1.0, 1.0), Sdf, UsdShade)
        exported.corrections.append(f"{prim.GetPath()}: metal of edge tint {_said(tint or (1.0, 1.0, 1.0))} as tessera:Metal (F82)")
    else:
        _as_solid_dielectric(shader, Sdf)
    if sigma is not None:
        _set_or_bake(exported, material, shader, "diffuseRoughness", sigma, Sdf, UsdShade)
        exported.corrections.append(f"{prim.GetPath()}: {node.bl_label}'s diffuse roughness {_said(sigma)} as tessera:SolidDielectric diffuseRoughness")
    if sheen:
        for name, value in sheen.items():
            _set_or_bake(exported, material, shader, name, value, Sdf, UsdShade)
        exported.corrections.append(
            f"{prim.GetPath()}: sheen (weight {_said(sheen['fuzz'])}, tint {_said(sheen['fuzzColor'])}, roughness {_said(sheen['fuzzRoughness'])}) as {shader.GetIdAttr().Get()} fuzz"
        )
    if tint and kind == "dielectric":
        _set_or_bake(exported, material, shader, "specularColor", tint, Sdf, UsdShade)
        exported.corrections.append(f"{prim.GetPath()}: Specular Tint {_said(tint)} as tessera:SolidDielectric specularColor")
    if film:
        for name, value in film.items():
            _set_or_bake(exported, material, shader, name, value, Sdf, UsdShade)
        exported.corrections.append(
            f"{prim.GetPath()}: thin film of {film['filmThickness']:g} nm, IOR {film['filmRefractiveIndex']:g} as {shader.GetIdAttr().Get()}'s surface film"
        )
    if anisotropy:
        for name, value in anisotropy.items():
            _set_or_bake(exported, material, shader, name, value, Sdf, UsdShade)
        source = nodes.tangent_source(node)
        tangents.use(exported, material, prim, shader, source, Sdf, UsdShade)
        exported.corrections.append(
            f"{prim.GetPath()}: anisotropy {_said(anisotropy['anisotropy'])}, rotation {_said(anisotropy['anisotropyRotation'])} along the {tangents.primvar_name(source)} primvar"
        )


def _set_or_bake(exported: Export, material, shader, name: str, value, Sdf, UsdShade) -> None:
    """Tessera's input `name` on `shader`: a constant (a float, or an (r, g, b) colour) set, or
    a linked Blender socket baked into an image over the objects' UVs (``bake.carry``); one that
    cannot be baked is reported and keeps the input's default."""
    colour = isinstance(value, tuple) or getattr(value, "type", None) == "RGBA"
    usd_input = shader.CreateInput(name, Sdf.ValueTypeNames.Color3f if colour else Sdf.ValueTypeNames.Float)
    if isinstance(value, (float, tuple)):
        usd_input.Set(value)
        return
    why = bake.carry(exported, material, value.name, value, usd_input, 1.0, Sdf, UsdShade)
    if why is not None:
        exported.warnings.append(f"{material.name}: {value.name} could not be baked ({why}); {name} keeps its default")


def _said(value) -> str:
    """A carried value for the log: the number or colour, or "baked" for a linked socket."""
    return nodes._shown(value) if isinstance(value, (float, tuple)) else "baked"


#: UsdPreviewSurface inputs that keep their meaning on ``tessera:Metal``, by its names.
METAL_NAMES = {
    "diffuseColor": ("reflectivity", "Color3f"),
    "roughness": ("roughness", "Float"),
    "clearcoat": ("clearcoat", "Float"),
    "clearcoatRoughness": ("clearcoatRoughness", "Float"),
    "emissiveColor": ("emission", "Color3f"),
    "normal": ("normal", "Normal3f"),
}


def _as_metal(shader, Sdf) -> None:
    """The UsdPreviewSurface `shader` of a full metal rewritten as tessera:Metal: its inputs
    renamed (``METAL_NAMES``), connections kept, the rest dropped, and its `edgeTint` (set by
    the caller) read as the F82 tint, Cycles' metal Fresnel (white is Schlick's,
    UsdPreviewSurface's)."""
    _renamed(shader, "tessera:Metal", METAL_NAMES, Sdf)
    shader.CreateInput("f82", Sdf.ValueTypeNames.Bool).Set(True)


def _correct_displacement(exported: Export, prim, Sdf, UsdShade) -> None:
    """Blender exports a material's Displacement output whatever its Displacement method, and
    UsdPreviewSurface's displacement moves the mesh (Cycles' *Displacement Only*). *Bump Only*,
    which Cycles renders as shading alone, becomes a tessera:Bump over the same texture (the
    exporter folded the Displacement node's Scale and Midlevel into its scale and bias, so the
    bump's own scale is 1) and the displacement is dropped; the bump part of *Displacement and
    Bump* is said to be lost."""
    shader = _surface_shader(prim, UsdShade)
    displacement = shader.GetInput("displacement") if shader else None
    if not displacement:
        return
    name = _material_name(prim)
    material = bpy.data.materials.get(name)
    method = getattr(material, "displacement_method", "BUMP")
    if method == "BUMP":
        sources = displacement.GetConnectedSources()[0] if displacement.HasConnectedSource() else []
        normal = shader.GetInput("normal")
        shader.GetPrim().RemoveProperty(displacement.GetAttr().GetName())
        if not sources:
            return  # a constant height has no slope: nothing to bump
        if normal and normal.HasConnectedSource():
            exported.warnings.append(f"{name}: Bump Only displacement is not rendered on a material whose normal is already mapped")
            return
        source = sources[0]
        texture = UsdShade.Shader(source.source.GetPrim())
        path = nodes.add_bump(shader, texture, source.sourceName, 1.0, Sdf, UsdShade)
        exported.corrections.append(f"{path}: Bump Only displacement as tessera:Bump")
    elif method == "BOTH":
        exported.warnings.append(f"{name}: the bump part of Displacement and Bump is not rendered; the surface moves at its vertices")


def _warn_if_displaced(exported: Export, name: str, shader) -> None:
    """Glass, subsurface, tinted coats, rough diffuse and sheen are rewritten onto Tessera's
    own shaders, which do not displace."""
    if shader.GetInput("displacement"):
        exported.warnings.append(f"{name}: displacement is not carried on glass, subsurface, tinted-coat, rough-diffuse or sheen materials")


#: Blender's Specular IOR Level that leaves the IOR's reflectance as it is.
NEUTRAL_SPECULAR_LEVEL = 0.5


def _drop_specular_level(exported: Export, prim, UsdShade) -> None:
    shader = _surface_shader(prim, UsdShade)
    level = shader.GetInput("specular") if shader and shader.GetIdAttr().Get() == "UsdPreviewSurface" else None
    if not level:
        return
    value = level.Get()
    if level.HasConnectedSource() or value is None or abs(float(value) - NEUTRAL_SPECULAR_LEVEL) > 1e-6:
        exported.warnings.append(f"{prim.GetName()}: Specular IOR Level {value} is not carried (the IOR sets the reflectance)")
    shader.GetPrim().RemoveProperty(level.GetAttr().GetName())
