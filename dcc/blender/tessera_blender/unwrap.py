"""A UV map for objects that have none, so that what ``bake.py`` bakes has UVs to lie on.

Cycles bakes over an object's UVs, and the exported mesh must read the bake through the same
UVs. An object without a UV map gets a stand-in for the export's bakes: a copy of the object
and of its mesh (modifiers kept, so it renders as the original does), unwrapped by Blender's
own Smart UV Project. The bakes render over the copy, and the copy's UVs are written into the
exported mesh as ``primvars:st``. The artist's object and mesh are left as they were, and the
copies are removed once the export's corrections are done (``clean_up``).

The exporter writes a mesh's faces in Blender's loop order: the cage's when it exports the last
Subdivision Surface modifier as a subdivision scheme, the evaluated mesh's otherwise. The UVs
are written only where the exported points, read corner by corner, are the copy's (cage or
evaluated); anything else is reported and left unbaked.
"""

from __future__ import annotations

import math

import bpy
import numpy as np

#: Smart UV Project's own default: faces bent further apart than this start a new island.
ANGLE_LIMIT = math.radians(66.0)
#: The most UV space the gap between islands may take (a small Bake Size would ask for more).
MAX_ISLAND_MARGIN = 0.05
#: How far an exported corner may lie from the copy's (object space, relative to the mesh's
#: size) and still be the same corner: the exporter copies positions as they are.
SAME_CORNER = 1e-6


def stand_in(exported, obj, meshes, bake_margin: int, Sdf, UsdGeom):
    """The object to bake `obj`'s inputs over, and why not when there is none: `obj` itself
    when it has a UV map, else its unwrapped copy (made once an export), whose UVs are then
    written on each of `meshes` (the Mesh prims exported for it)."""
    if obj.type == "MESH" and obj.data.uv_layers:
        return obj, None
    if obj.type != "MESH":
        return None, f"{obj.name} is not a mesh in Blender, so it has no UV map to bake over"
    if obj.name not in exported.unwrapped:
        exported.unwrapped[obj.name] = _unwrapped(exported, obj, meshes, bake_margin, Sdf, UsdGeom)
    return exported.unwrapped[obj.name]


def clean_up(exported) -> None:
    """Removes the copies made for the export's bakes."""
    for copy, _ in exported.unwrapped.values():
        if copy is not None:
            _remove(copy)
    exported.unwrapped.clear()


def _unwrapped(exported, obj, meshes, bake_margin, Sdf, UsdGeom):
    copy = obj.copy()
    copy.data = obj.data.copy()
    copy.name = copy.data.name = f"{obj.name} (Tessera UVs)"
    try:
        loops = _smart_project(copy, min(MAX_ISLAND_MARGIN, 2.0 * bake_margin / exported.bake_size))
    except RuntimeError as e:  # bpy.ops reports a failed operator this way
        _remove(copy)
        return None, f"{obj.name} has no UV map, and Smart UV Project failed on it: {str(e).strip()}"
    for mesh in meshes:
        uvs = next((uv for points, uv in loops if same_corners(mesh, points, UsdGeom)), None)
        if uvs is None:
            _remove(copy)
            return None, f"{obj.name} has no UV map, and its exported mesh {mesh.GetPath()} is not Blender's corner for corner"
        primvar = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
        primvar.Set(uvs.tolist())
    exported.corrections.append(f"{obj.name}: no UV map, so one by Smart UV Project to bake over (primvars:st)")
    return copy, None


def _smart_project(copy, island_margin):
    """Unwraps `copy`'s mesh in a scratch scene; returns (corner positions, corner UVs) of its
    cage and of its evaluated mesh, the two orders the exporter may have written."""
    scratch = bpy.data.scenes.new("tessera-unwrap")
    try:
        scratch.collection.objects.link(copy)
        layer = scratch.view_layers[0]
        copy.data.uv_layers.new(name="st")
        with bpy.context.temp_override(scene=scratch, view_layer=layer, active_object=copy, object=copy, selected_objects=[copy], edit_object=copy):
            layer.objects.active = copy
            copy.select_set(True, view_layer=layer)
            bpy.ops.object.mode_set(mode="EDIT")
            bpy.ops.mesh.select_all(action="SELECT")
            bpy.ops.uv.smart_project(angle_limit=ANGLE_LIMIT, island_margin=island_margin)
            bpy.ops.object.mode_set(mode="OBJECT")
        depsgraph = layer.depsgraph
        depsgraph.update()
        evaluated = copy.evaluated_get(depsgraph)
        try:
            return [_corners(copy.data), _corners(evaluated.to_mesh())]
        finally:
            evaluated.to_mesh_clear()
    finally:
        for o in list(scratch.collection.objects):
            scratch.collection.objects.unlink(o)
        bpy.data.scenes.remove(scratch)


def _corners(mesh):
    """(each corner's position, each corner's UV) of `mesh`, in loop order."""
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers["st"].uv.foreach_get("vector", uv)
    return corner_positions(mesh), uv.reshape(-1, 2)


def corner_positions(mesh):
    """Each corner's position in the Blender mesh `mesh`, in loop order."""
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    index = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", index)
    return co.reshape(-1, 3)[index]


def same_corners(mesh, points, UsdGeom) -> bool:
    """True when the exported `mesh`'s corners are `points`, in order."""
    geom = UsdGeom.Mesh(mesh)
    exported = np.asarray(geom.GetPointsAttr().Get() or [], np.float32)
    index = np.asarray(geom.GetFaceVertexIndicesAttr().Get() or [], np.int64)
    if len(index) != len(points) or len(index) == 0 or index.max() >= len(exported):
        return False
    size = max(float(np.abs(points).max()), 1.0)
    return float(np.abs(exported[index] - points).max()) <= SAME_CORNER * size


def _remove(copy) -> None:
    mesh = copy.data
    bpy.data.objects.remove(copy)
    bpy.data.meshes.remove(mesh)
