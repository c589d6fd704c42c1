"""Runs inside Blender (PyPI's `bpy`): enables the Tessera add-on, renders the comparison
scenes with Tessera and with Cycles, checks the interactive path, and writes every number to
a JSON file for the test (python/tests/test_blender.py) and for docs/blender.md.

    python run_in_blender.py OUT_DIR SPP
"""

import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import scenes  # noqa: E402
import tessera  # noqa: E402
import tessera_blender  # noqa: E402
from tessera_blender import engine, export  # noqa: E402


def regions_of(scene, exported):
    """Each pixel's region (its object's pass_index, 0 for none), from Tessera's primId AOV
    on the same export made opaque: the geometry is the same in both renderers, ids are exact
    labels, and a partly present surface (a Transparent BSDF's mix) covers its whole shape
    rather than the share of pixels whose one sample found it."""
    with engine.client_for(None).session("regions") as session:
        session.sync_usd(_opaque_copy(exported.path))
        fb, table = None, []
        for e in session.render(scene.render.resolution_x, scene.render.resolution_y, spp=1, aovs=["primId"]):
            if isinstance(e, tessera.Started):
                fb, table = tessera.Framebuffer(e.width, e.height), e.prim_paths
            elif isinstance(e, tessera.Tile):
                fb.add(e)
    owner = {p: name for name, prims in exported.prims.items() for p in prims}
    ids = fb.layers["primId"][..., 0].astype(int)
    index = np.zeros_like(ids)
    for k, path in enumerate(table, start=1):
        obj = bpy.data.objects.get(owner.get(path, ""))
        index[ids == k] = obj.pass_index if obj else 0
    return index


def _opaque_copy(path):
    """The exported file beside itself with every partly present surface made whole."""
    _, Usd, _, UsdShade = export._pxr()
    stage = Usd.Stage.Open(path)
    for prim in stage.Traverse():
        shader = UsdShade.Shader(prim)
        if prim.IsA(UsdShade.Shader) and shader.GetInput("opacityMode"):
            prim.RemoveProperty("inputs:opacity")
    opaque = os.path.join(os.path.dirname(path), "opaque.usdc")
    stage.Export(opaque)
    return opaque


def first_tile_seconds(scene):
    """F12 to the first tile in the render result: the add-on's own timing of one render."""
    starts = {}
    original = engine.TesseraRenderEngine._write_tile

    def timed(self, tile, height, view_layer):
        starts.setdefault("first", time.perf_counter())
        original(self, tile, height, view_layer)

    engine.TesseraRenderEngine._write_tile = timed
    try:
        t0 = time.perf_counter()
        scenes.render(scene, "TESSERA", os.path.join(OUT, "timing.exr"), 4)
        return starts["first"] - t0
    finally:
        engine.TesseraRenderEngine._write_tile = original


def cycles_first_sample_seconds(scene):
    """Cycles' time to a first sample: a one-sample render, start to finish."""
    t0 = time.perf_counter()
    scenes.render(scene, "CYCLES", os.path.join(OUT, "timing_cycles.exr"), 1)
    return time.perf_counter() - t0


def preview_inputs(path):
    """Every input name on the export's UsdPreviewSurface shaders."""
    _, Usd, _, UsdShade = export._pxr()
    stage = Usd.Stage.Open(path)
    shaders = (UsdShade.Shader(p) for p in stage.Traverse() if p.IsA(UsdShade.Shader))
    return sorted({i.GetBaseName() for s in shaders if s.GetIdAttr().Get() == "UsdPreviewSurface" for i in s.GetInputs()})


def compare(kind, spp):
    scene = scenes.build(kind, OUT)
    out = {}
    for eng in ("TESSERA", "CYCLES"):
        t0 = time.perf_counter()
        scenes.render(scene, eng, os.path.join(OUT, f"{kind}_{eng.lower()}.exr"), spp)
        out[f"{eng.lower()}_seconds"] = time.perf_counter() - t0
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    np.save(os.path.join(OUT, f"{kind}_regions.npy"), regions_of(scene, exported))
    out["corrections"] = exported.corrections
    out["warnings"] = exported.warnings
    out["preview_inputs"] = preview_inputs(exported.path)
    out["first_tile_seconds"] = first_tile_seconds(scene)
    out["cycles_first_sample_seconds"] = cycles_first_sample_seconds(scene)
    out["regions"] = scenes.REGIONS[kind]
    return out


def denoised(kind):
    """The final render at 16 spp with the add-on's Denoise on and off (Combined only: what
    Blender saves), for the test to hold against the 256-spp render."""
    scene = scenes.build(kind, OUT)
    for on in (True, False):
        scene.tessera.denoise = on
        scenes.render(scene, "TESSERA", os.path.join(OUT, f"{kind}_{'denoised' if on else 'raw'}16.exr"), 16)


def interactive():
    """The viewport's update path, headless: a session holding the box, one object moved,
    the add-on's depsgraph handler called. Exactly one transform delta goes, and the next
    image shows the move."""
    scene = scenes.build("box", OUT)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    exported = export.export_scene(depsgraph)
    session = engine.client_for(None).session("interactive")
    session.sync_usd(exported.path)
    w, h = scene.render.resolution_x, scene.render.resolution_y

    def image():
        fb = None
        for e in session.render(w, h, spp=4):
            if isinstance(e, tessera.Started):
                fb = tessera.Framebuffer(e.width, e.height)
            elif isinstance(e, tessera.Tile):
                fb.add(e)
        return fb.layers["beauty"]

    before = image()
    sent, reexport, t0 = _moved(session, exported, next(o for o in scene.objects if o.pass_index == 5), 0.6)
    # Edit to the first tile of the new image, with a render already running.
    stream = session.render(w, h, spp=64, coarse_start=8)
    first = next(e for e in stream if isinstance(e, tessera.Tile))
    edit_to_tile = time.perf_counter() - t0
    del stream
    after = image()
    session.close()
    return {
        "sent": sent,
        "reexport": reexport,
        "image_changed": bool(not np.array_equal(before, after)),
        "edit_to_first_tile_seconds": edit_to_tile,
        "first_tile_pixel_size": first.pixel_size,
    }


def _moved(session, exported, obj, dx):
    """Moves `obj` by `dx` along x while the add-on's function listens: what it sent, whether
    it asked for a re-export, and when it ran. Blender hands a depsgraph with its updates to
    view_update, and to this handler, which headless Blender does call."""
    edits = {}

    def handler(_scene, depsgraph):
        edits["t0"] = time.perf_counter()
        edits["sent"], edits["reexport"] = engine.object_edits(session, exported, depsgraph)

    bpy.app.handlers.depsgraph_update_post.append(handler)
    try:
        obj.location.x += dx
        bpy.context.view_layer.update()
    finally:
        bpy.app.handlers.depsgraph_update_post.remove(handler)
    return edits["sent"], edits["reexport"], edits["t0"]


def hair_move():
    """A hair object of the `hair` scene moved in a session holding it: one transform delta
    for its curves, no re-export."""
    scenes.build("hair", OUT)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    session = engine.client_for(None).session("hair move")
    session.sync_usd(exported.path)
    sent, reexport, _ = _moved(session, exported, bpy.data.objects["hair 2"], 0.3)
    session.close()
    return {"sent": sent, "reexport": reexport}


def node_reports():
    """The add-on's check of node trees against the export (scenes.node_trees): its warnings
    and corrections, and which inputs each corrected material still has connected."""
    scenes.node_trees(OUT)
    exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
    _, Usd, _, UsdShade = export._pxr()
    stage = Usd.Stage.Open(exported.path)
    connected = {}
    for prim in (p for p in stage.Traverse() if p.IsA(UsdShade.Material)):
        shader = export._surface_shader(prim, UsdShade)
        connected[prim.GetName()] = sorted(i.GetBaseName() for i in shader.GetInputs() if i.HasConnectedSource()) if shader else None
    texture = UsdShade.Shader(stage.GetPrimAtPath(export._surface_shader(stage.GetPrimAtPath("/root/_materials/normal_map"), UsdShade).GetInput("normal").GetConnectedSources()[0][0].source.GetPath()))
    normal_map = {k: list(texture.GetInput(k).Get()) for k in ("scale", "bias")}
    return {"warnings": exported.warnings, "corrections": exported.corrections, "connected": connected, "normal_map": normal_map}


def bake_reuse(size=64):
    """The `procedural` scene exported at Bake Size 64, five times: the bakes' size and how many
    bakes each export ran: first all, then none (the cache serves an unchanged scene), then
    after a Color Ramp's stop changes colour, after a node group is put between the Noise and
    the Color Ramp, and after a value inside that group changes; and each export's seconds
    (for docs/blender.md, not asserted)."""
    from tessera_blender import bake

    scene = scenes.build("procedural", OUT)
    scene.tessera.bake_size = size
    ran = []
    original = bake._bake

    def counted(*args):
        ran[-1] += 1
        return original(*args)

    bake._bake = counted
    try:
        sizes, seconds = [], []
        for edit in (None, None, "ramp", "group", "inside"):
            _edit_noise_ramp(edit)
            ran.append(0)
            t0 = time.perf_counter()
            exported = export.export_scene(bpy.context.evaluated_depsgraph_get())
            seconds.append(round(time.perf_counter() - t0, 3))
            baked = os.path.join(os.path.dirname(exported.path), "baked")
            sizes += [tuple(bpy.data.images.load(os.path.join(baked, f), check_existing=False).size) for f in sorted(os.listdir(baked))]
    finally:
        bake._bake = original
    # What the unwrap (tessera_blender/unwrap.py) leaves behind: nothing, and the sphere still
    # without a UV map.
    left = [d.name for d in (*bpy.data.objects, *bpy.data.meshes, *bpy.data.scenes) if "Tessera UVs" in d.name or d.name == "tessera-unwrap"]
    sphere_uvs = len(bpy.data.objects["Sphere"].data.uv_layers)
    return {"bakes": ran, "sizes": sorted(set(sizes)), "seconds": seconds, "left": left, "sphere_uvs": sphere_uvs}


def _edit_noise_ramp(edit):
    """One of bake_reuse's edits of the `noise ramp` material."""
    tree = bpy.data.materials["noise ramp"].node_tree
    ramp = next(n for n in tree.nodes if n.type == "VALTORGB")
    if edit == "ramp":
        ramp.color_ramp.elements[0].color = (0.1, 0.8, 0.1, 1)
    elif edit == "group":
        group = bpy.data.node_groups.new("squash", "ShaderNodeTree")
        group.interface.new_socket("Fac", in_out="INPUT", socket_type="NodeSocketFloat")
        group.interface.new_socket("Fac", in_out="OUTPUT", socket_type="NodeSocketFloat")
        inside, outside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
        power = group.nodes.new("ShaderNodeMath"); power.operation = "POWER"; power.inputs[1].default_value = 2.0
        group.links.new(inside.outputs[0], power.inputs[0]); group.links.new(power.outputs[0], outside.inputs[0])
        node = tree.nodes.new("ShaderNodeGroup"); node.node_tree = group
        noise = next(n for n in tree.nodes if n.type == "TEX_NOISE")
        tree.links.new(noise.outputs["Fac"], node.inputs[0]); tree.links.new(node.outputs[0], ramp.inputs["Fac"])
    elif edit == "inside":
        power = next(n for n in bpy.data.node_groups["squash"].nodes if n.type == "MATH")
        power.inputs[1].default_value = 3.0


def errors_reach_the_artist():
    """A render whose export cannot be synced reports the error (the operator fails with it,
    as F12 shows it in the status bar) rather than saving a silent black image."""
    scene = scenes.build("glass", OUT)
    scene.render.engine = "TESSERA"
    engine.REPORTED.clear()
    saved = export.export_scene
    export.export_scene = lambda depsgraph, directory=None: export.Export(path=os.path.join(OUT, "missing.usdc"))
    try:
        scene.render.filepath = os.path.join(OUT, "error.exr")
        bpy.ops.render.render(write_still=False)
        operator_error = None
    except RuntimeError as e:
        operator_error = str(e)
    finally:
        export.export_scene = saved
    return {"operator": operator_error, "reported": list(engine.REPORTED)}


if __name__ == "__main__":
    OUT, SPP = sys.argv[-2], int(sys.argv[-1])
    tessera_blender.register()
    results = {kind: compare(kind, SPP) for kind in scenes.REGIONS}
    denoised("box")
    results["interactive"] = interactive()
    results["hair_move"] = hair_move()
    results["error_reports"] = errors_reach_the_artist()
    results["node_reports"] = node_reports()
    results["bake_reuse"] = bake_reuse()
    with open(os.path.join(OUT, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
