#!/usr/bin/env python3
"""Anchor measurements for Tessera's benchmarks, run by the Rust benches on the same data.

    python3 bench/anchors.py rays DIR        Embree (embreex) on DIR/{vertices,indices,rays}.bin
    python3 bench/anchors.py cornell ARGS    Mitsuba 3 on fixtures/cornell_box.usda (read with usd-core);
        ARGS: USD W H SPP MAX_DEPTH REF_SPP OUT_DIR VARIANT [SAMPLER] (SAMPLER: independent,
        the default, or multijitter / ldsampler / stratified / orthogonal)

Each prints one JSON object on its last line. Needs: pip install embreex mitsuba usd-core numpy,
and Debian's libllvm19 for Mitsuba's llvm variants.
"""

import json
import math
import os
import sys
import time

if __name__ == "__main__" and (len(sys.argv) < 3 or sys.argv[1] not in ("rays", "cornell")):
    # Without a workload, say how the benches call it (before needing numpy).
    print(__doc__.strip())
    sys.exit(0 if len(sys.argv) < 2 or sys.argv[1] in ("-h", "--help") else 2)

import numpy as np  # noqa: E402


def rays(d):
    import embreex.rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    vertices = np.fromfile(os.path.join(d, "vertices.bin"), dtype=np.float32).reshape(-1, 3)
    indices = np.fromfile(os.path.join(d, "indices.bin"), dtype=np.uint32).reshape(-1, 3)
    r = np.fromfile(os.path.join(d, "rays.bin"), dtype=np.float32).reshape(-1, 7)
    origins, directions, tmax = np.ascontiguousarray(r[:, 0:3]), np.ascontiguousarray(r[:, 3:6]), np.ascontiguousarray(r[:, 6])
    t0 = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, vertices, indices)
    # Embree builds lazily on the first query: time a one-ray query as the build.
    scene.run(origins[:1], directions[:1])
    build = time.perf_counter() - t0
    best_closest = best_occluded = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        hits = scene.run(origins, directions)
        best_closest = min(best_closest, time.perf_counter() - t0)
        t0 = time.perf_counter()
        occluded = scene.run(origins, directions, query="OCCLUDED", dists=tmax)
        best_occluded = min(best_occluded, time.perf_counter() - t0)
    n = len(origins)
    return {
        "build_s": build,
        "closest_mrays": n / best_closest / 1e6,
        "occluded_mrays": n / best_occluded / 1e6,
        "closest_hits": int((hits >= 0).sum()),
        "occluded_hits": int((occluded >= 0).sum()),
    }


def cornell_scene_dict(usd_path, width, height, max_depth, spp, ply_dir, sampler="independent"):
    """The Cornell box fixture as a Mitsuba scene: same meshes, materials, light, camera."""
    import mitsuba as mi
    from pxr import Usd, UsdGeom, UsdShade, UsdLux, Gf

    stage = Usd.Stage.Open(usd_path)
    cache = UsdGeom.XformCache()
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(prim)
            m = cache.GetLocalToWorldTransform(prim)
            pts = [m.Transform(Gf.Vec3d(p)) for p in mesh.GetPointsAttr().Get()]
            counts, idx = mesh.GetFaceVertexCountsAttr().Get(), mesh.GetFaceVertexIndicesAttr().Get()
            tris, base = [], 0
            for c in counts:
                for k in range(1, c - 1):
                    tris.append((idx[base], idx[base + k], idx[base + k + 1]))
                base += c
            mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
            shader = mat.ComputeSurfaceSource()[0]
            rgb = shader.GetInput("diffuseColor").Get()
            # PLY files work in every variant (scalar ones cannot take buffers from numpy).
            ply = os.path.join(ply_dir, prim.GetName() + ".ply")
            with open(ply, "w") as f:
                f.write(f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\nproperty float x\nproperty float y\nproperty float z\n")
                f.write(f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n")
                f.writelines(f"{p[0]} {p[1]} {p[2]}\n" for p in pts)
                f.writelines(f"3 {a} {b} {c}\n" for a, b, c in tris)
            scene[prim.GetName()] = {"type": "ply", "filename": ply, "face_normals": True, "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(rgb)}}}
        elif prim.IsA(UsdLux.RectLight):
            light = UsdLux.RectLight(prim)
            m = cache.GetLocalToWorldTransform(prim)
            w, h = light.GetWidthAttr().Get(), light.GetHeightAttr().Get()
            radiance = [c * light.GetIntensityAttr().Get() for c in light.GetColorAttr().Get()]
            # Mitsuba's rectangle spans [-1, 1]^2 facing +Z; a RectLight faces -Z: flip, scale, place.
            local = Gf.Matrix4d().SetScale(Gf.Vec3d(w / 2, h / 2, 1)) * Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 0, 0), 180))
            world = local * m
            scene["light"] = {
                "type": "rectangle",
                "to_world": mi.ScalarTransform4f(np.array(world).T.tolist()),
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": radiance}},
            }
        elif prim.IsA(UsdGeom.Camera):
            cam = UsdGeom.Camera(prim).GetCamera()
            m = cache.GetLocalToWorldTransform(prim)
            eye = m.Transform(Gf.Vec3d(0, 0, 0))
            target = m.Transform(Gf.Vec3d(0, 0, -1))
            up = m.TransformDir(Gf.Vec3d(0, 1, 0))
            fov = 2 * math.degrees(math.atan(0.5 * cam.horizontalAperture / cam.focalLength))
            scene["sensor"] = {
                "type": "perspective",
                "fov": fov,
                "fov_axis": "x",
                "to_world": mi.ScalarTransform4f().look_at(origin=list(eye), target=list(target), up=list(up)),
                "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
                "sampler": {"type": sampler, "sample_count": spp},
            }
    return scene


def cornell(usd_path, width, height, spp, max_depth, ref_spp, out_dir, variant, sampler="independent"):
    import mitsuba as mi

    mi.set_variant(variant)
    scene = mi.load_dict(cornell_scene_dict(usd_path, width, height, max_depth, spp, out_dir, sampler))
    mi.render(scene, spp=1)  # JIT warm-up, not timed
    best = float("inf")
    for seed in range(3):
        t0 = time.perf_counter()
        img = mi.render(scene, spp=spp, seed=seed)
        arr = np.array(img)  # forces evaluation
        best = min(best, time.perf_counter() - t0)
    np.array(mi.render(scene, spp=spp, seed=7))[:, :, :3].astype(np.float32).tofile(os.path.join(out_dir, f"mitsuba_{sampler}.bin"))
    result = {"variant": variant, "sampler": sampler, "seconds": best, "paths_per_s": width * height * spp / best}
    if ref_spp > 0:
        t0 = time.perf_counter()
        ref = np.array(mi.render(scene, spp=ref_spp, seed=11))[:, :, :3]
        result["ref_seconds"] = time.perf_counter() - t0
        ref.astype(np.float32).tofile(os.path.join(out_dir, "mitsuba_ref.bin"))
    return result


if __name__ == "__main__":
    if sys.argv[1] == "rays":
        print(json.dumps(rays(sys.argv[2])))
    elif sys.argv[1] == "cornell":
        usd, w, h, spp, depth, ref_spp, out, variant = sys.argv[2:10]
        sampler = sys.argv[10] if len(sys.argv) > 10 else "independent"
        print(json.dumps(cornell(usd, int(w), int(h), int(spp), int(depth), int(ref_spp), out, variant, sampler)))
    else:
        sys.exit(__doc__)
