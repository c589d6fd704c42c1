"""Which way an anisotropic highlight runs on each exported mesh: a Principled BSDF's Tangent,
written as a primvar that the shader's `tangent` input reads.

Cycles takes the tangent from one of two places (its `svm_node_tangent`), and so does the export:

* **Radial** (the Principled BSDF's unlinked Tangent, around Z, or a Tangent node set to Radial
  around X, Y or Z): a circle around the axis through the middle of the object's texture space,
  in Generated coordinates g = (p − location)/(2·size) + ½. Around Z it is (−(g_y − ½), g_x − ½, 0);
  around X (0, −(g_z − ½), g_y − ½); around Y (−(g_z − ½), 0, g_x − ½). Written per vertex.
* **UV map** (a Tangent node set to UV Map): the map's MikkTSpace tangents, the direction in
  which its U grows, one per face corner as Blender computes them (``Mesh.calc_tangents``).

Cycles then places the tangent with the object as it places normals (by the inverse transpose
of the object's matrix A) and makes it perpendicular to the shading normal. Tessera places a
`tangent` as a direction (by A), so the primvar holds (AᵀA)⁻¹·t, which A takes where A⁻ᵀ takes
t: the same under rotations and uniform scale, and Cycles' highlight under any other.
"""

from __future__ import annotations

import re

import bpy
import numpy as np

from . import bake, unwrap

#: The Generated coordinates' components (x, y, z) that make up the radial tangent around each
#: axis, with their signs: around Z, (−c_y, c_x, 0) for c = g − ½.
RADIAL = {"X": ((None, 0.0), (2, -1.0), (1, 1.0)), "Y": ((2, -1.0), (None, 0.0), (0, 1.0)), "Z": ((1, -1.0), (0, 1.0), (None, 0.0))}


def primvar_name(source) -> str:
    """The primvar that holds the tangent from `source` (``nodes.tangent_source``)."""
    kind, which = source
    if kind == "radial":
        return f"tesseraRadialTangent{which}"
    return "tesseraUVTangent_" + (re.sub(r"[^A-Za-z0-9_]", "_", which) if which else "active")


def use(exported, material, material_prim, shader, source, Sdf, UsdShade) -> None:
    """Connects `shader`'s `tangent` to a primvar reader of the tangent from `source` and
    writes that primvar on every mesh the material (`material` in Blender) is bound to; a mesh
    it cannot be written on is reported (its highlight then runs around the object's up axis)."""
    stage = material_prim.GetStage()
    name = primvar_name(source)
    reader = UsdShade.Shader.Define(stage, material_prim.GetPath().AppendChild(name))
    reader.SetShaderId("UsdPrimvarReader_float3")
    reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set(name)
    result = reader.CreateOutput("result", Sdf.ValueTypeNames.Float3)
    shader.CreateInput("tangent", Sdf.ValueTypeNames.Vector3f).ConnectToSource(result)
    for object_name, prims in bake.users(stage, str(material_prim.GetPath()), UsdShade).items():
        obj = bpy.data.objects.get(object_name)
        for mesh in bake.meshes_of(prims):
            why = _write(exported, mesh, obj, source, name, Sdf) if obj is not None and obj.type == "MESH" else "it is not a mesh in Blender"
            if why is not None:
                exported.warnings.append(f"{material.name}: no {_described(source)} on {mesh.GetPath()} ({why}); its anisotropy runs around the object's up axis there")


def _described(source) -> str:
    kind, which = source
    return f"tangent radial around {which}" if kind == "radial" else f"tangents of UV map {which or '(active render)'!r}"


def _write(exported, mesh, obj, source, name, Sdf) -> str | None:
    """Writes the tangent from `source` on `mesh` (exported for `obj`); why not, or None."""
    from pxr import UsdGeom, Vt

    kind, which = source
    if kind == "radial":
        tangents, interpolation = _radial(mesh, obj.data, which, UsdGeom), UsdGeom.Tokens.vertex
    else:
        tangents, interpolation = _along_uv(exported, mesh, obj, which, UsdGeom), UsdGeom.Tokens.faceVarying
    if isinstance(tangents, str):
        return tangents
    tangents = _placed_as_normals(tangents, np.array(obj.matrix_world.to_3x3()))
    primvar = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(name, Sdf.ValueTypeNames.Vector3fArray, interpolation)
    primvar.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(tangents, dtype=np.float32)))
    return None


def _placed_as_normals(tangents, a):
    """`tangents` (rows) such that the object's linear part `a` takes each where Cycles' normal
    transform takes the original: (aᵀa)⁻¹·t, scaled to keep its largest entry 1; as they are
    when `a` is singular."""
    try:
        m = np.linalg.inv(a.T @ a)
    except np.linalg.LinAlgError:
        return tangents
    return tangents @ (m / np.abs(m).max()).T


def _radial(mesh, data, axis, UsdGeom):
    """The radial tangent around `axis` at each exported point of `mesh`, from the texture space
    of `data` (the object's mesh); or why not. Generated coordinates are the undeformed mesh's
    (Cycles' orco): where the exported mesh has the object's own points, one for one (modifiers
    and shape keys that only move them), the tangent is taken at the undeformed points."""
    points = UsdGeom.Mesh(mesh).GetPointsAttr().Get()
    if not points:
        return "the mesh has no points"
    p = np.array(points, dtype=np.float64)
    if len(data.vertices) == len(p):
        p = np.empty(len(p) * 3)
        data.vertices.foreach_get("co", p)
        p = p.reshape(-1, 3)
    location, size = np.array(data.texspace_location[:]), np.array(data.texspace_size[:])
    size = np.where(size != 0.0, size, 1.0)
    centred = (p - location) / (2.0 * size)  # g − ½
    zero = np.zeros(len(p))
    return np.stack([zero if i is None else sign * centred[:, i] for i, sign in RADIAL[axis]], axis=1)


def _along_uv(exported, mesh, obj, uv_map, UsdGeom):
    """The MikkTSpace tangents of `obj`'s UV map `uv_map` ("" for the active render map) at each
    face corner of the exported `mesh`, or why not. The exporter writes the faces in the loop
    order of the object's mesh (the cage, under an exported Subdivision Surface) or of its
    evaluated mesh: the tangents are taken from the one whose corners the exported mesh has, the
    cage first (the evaluated mesh is built only when the cage is not it)."""
    found = _corner_tangents(obj.data, uv_map)
    if isinstance(found, tuple) and unwrap.same_corners(mesh, found[0], UsdGeom):
        return found[1]
    why = found if isinstance(found, str) else "the exported mesh is not Blender's corner for corner"
    if exported.depsgraph is None:
        return why
    evaluated = obj.evaluated_get(exported.depsgraph)
    try:
        found = _corner_tangents(evaluated.to_mesh(), uv_map)
        if isinstance(found, tuple) and unwrap.same_corners(mesh, found[0], UsdGeom):
            return found[1]
        return why
    finally:
        evaluated.to_mesh_clear()


def _corner_tangents(data, uv_map):
    """(each corner's position, each corner's tangent) of the mesh `data` along its UV map
    `uv_map`, or why not."""
    layer = data.uv_layers.get(uv_map) if uv_map else next((layer for layer in data.uv_layers if layer.active_render), None)
    if layer is None:
        return f"the mesh has no UV map {uv_map!r}" if uv_map else "the mesh has no UV map"
    try:
        data.calc_tangents(uvmap=layer.name)
    except RuntimeError as e:  # faces of more than four corners
        return str(e).strip().removeprefix("Error: ")
    tangents = np.empty(len(data.loops) * 3, np.float32)
    data.loops.foreach_get("tangent", tangents)
    return unwrap.corner_positions(data), tangents.reshape(-1, 3)
