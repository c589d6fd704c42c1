#!/usr/bin/env python3
"""Anchor measurements for Tessera's benchmarks, run by the Rust benches on the same data.

    python3 bench/anchors.py rays DIR [THREADS]   Embree (embreex) on DIR/{vertices,indices,rays}.bin,
        on one thread, and with THREADS 2 (the default) also on two sharing the scene (embreex
        lets go of the GIL while it traces)
    python3 bench/anchors.py cornell ARGS    Mitsuba 3 on fixtures/cornell_box.usda (read with usd-core);
        ARGS: USD W H SPP MAX_DEPTH REF_SPP OUT_DIR VARIANT [SAMPLER] (SAMPLER: independent,
        the default, or multijitter / ldsampler / stratified / orthogonal; VARIANT llvm_ad_rgb:avx2
        runs the LLVM variant eight lanes wide on AVX2, as on a CPU without AVX-512)
    python3 bench/anchors.py production USD W H SPP MAX_DEPTH OUT_DIR VARIANT
        Mitsuba 3 on the scene bench/production_scene.py writes (read with usd-core)

Each prints one JSON object on its last line. Needs: pip install embreex mitsuba usd-core numpy,
and Debian's libllvm19 for Mitsuba's llvm variants.
"""

import json
import math
import os
import sys
import time

if __name__ == "__main__" and (len(sys.argv) < 3 or sys.argv[1] not in ("rays", "cornell", "production")):
    # Without a workload, say how the benches call it (before needing numpy).
    print(__doc__.strip())
    sys.exit(0 if len(sys.argv) < 2 or sys.argv[1] in ("-h", "--help") else 2)

import numpy as np  # noqa: E402


def rays(d, threads=2):
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
    result = {
        "build_s": build,
        "closest_mrays": n / best_closest / 1e6,
        "occluded_mrays": n / best_occluded / 1e6,
        "closest_hits": int((hits >= 0).sum()),
        "occluded_hits": int((occluded >= 0).sum()),
    }
    if threads == 2:
        closest_2t = min(on_two_threads(lambda a, b: scene.run(origins[a:b], directions[a:b]), n) for _ in range(3))
        occluded_2t = min(
            on_two_threads(lambda a, b: scene.run(origins[a:b], directions[a:b], query="OCCLUDED", dists=tmax[a:b]), n) for _ in range(3)
        )
        # Per thread, as the Rust bench reports its own two-thread rows.
        result["closest_mrays_2t"] = n / closest_2t / 2e6
        result["occluded_mrays_2t"] = n / occluded_2t / 2e6
    return result


def on_two_threads(trace, n):
    """Seconds for two threads to run trace(start, end) over the two halves of n rays."""
    import threading

    halves = [threading.Thread(target=trace, args=(k * n // 2, (k + 1) * n // 2)) for k in range(2)]
    t0 = time.perf_counter()
    for t in halves:
        t.start()
    for t in halves:
        t.join()
    return time.perf_counter() - t0


def cornell_scene_dict(usd_path, width, height, max_depth, spp, ply_dir, sampler="independent"):
    """The Cornell box fixture as a Mitsuba scene: same meshes, materials, light, camera."""
    import mitsuba as mi
    from pxr import Usd, UsdGeom, UsdShade, UsdLux, Gf

    stage = Usd.Stage.Open(usd_path)
    cache = UsdGeom.XformCache()
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
            shader = mat.ComputeSurfaceSource()[0]
            rgb = shader.GetInput("diffuseColor").Get()
            ply = os.path.join(ply_dir, prim.GetName() + ".ply")
            write_ply(ply, *mesh_arrays(prim, cache.GetLocalToWorldTransform(prim)))
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
                # A UsdLux light emits but neither reflects nor blocks (Tessera, Arnold, Karma):
                # without `null` Mitsuba's rectangle is an opaque diffuse panel hiding the
                # ceiling, 0.7-1.2% darker (docs/benchmarks.md, 2026-12-03).
                "bsdf": {"type": "null"},
            }
        elif prim.IsA(UsdGeom.Camera):
            scene["sensor"] = sensor(prim, cache, width, height, spp, sampler)
    return scene


def sensor(prim, cache, width, height, spp, sampler):
    """A USD camera as Mitsuba's perspective sensor, box-filtered like Tessera's film."""
    import mitsuba as mi
    from pxr import Gf, UsdGeom

    cam = UsdGeom.Camera(prim).GetCamera()
    m = cache.GetLocalToWorldTransform(prim)
    eye = m.Transform(Gf.Vec3d(0, 0, 0))
    target = m.Transform(Gf.Vec3d(0, 0, -1))
    up = m.TransformDir(Gf.Vec3d(0, 1, 0))
    fov = 2 * math.degrees(math.atan(0.5 * cam.horizontalAperture / cam.focalLength))
    return {
        "type": "perspective",
        "fov": fov,
        "fov_axis": "x",
        "to_world": mi.ScalarTransform4f().look_at(origin=list(eye), target=list(target), up=list(up)),
        "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
        "sampler": {"type": sampler, "sample_count": spp},
    }


def best_of_three(scene, spp):
    """Seconds of the fastest of three renders at `spp`, after an untimed one of the same spp
    and seed: the LLVM variants compile a kernel per distinct spp and seed (both are literals in
    it), and compiling is not rendering."""
    import mitsuba as mi

    np.array(mi.render(scene, spp=spp, seed=0))  # JIT warm-up, not timed
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        np.array(mi.render(scene, spp=spp, seed=0))  # forces evaluation
        best = min(best, time.perf_counter() - t0)
    return best


def cornell(usd_path, width, height, spp, max_depth, ref_spp, out_dir, variant, sampler="independent"):
    import mitsuba as mi

    variant, _, isa = variant.partition(":")
    mi.set_variant(variant)
    if isa == "avx2":
        jit_on_avx2()
    scene = mi.load_dict(cornell_scene_dict(usd_path, width, height, max_depth, spp, out_dir, sampler))
    best = best_of_three(scene, spp)
    image = os.path.join(out_dir, f"mitsuba_{sampler}{'_' + isa if isa else ''}.bin")
    np.array(mi.render(scene, spp=spp, seed=7))[:, :, :3].astype(np.float32).tofile(image)
    result = {"variant": variant, "isa": isa or "host", "sampler": sampler, "seconds": best, "paths_per_s": width * height * spp / best}
    if ref_spp > 0:
        t0 = time.perf_counter()
        ref = np.array(mi.render(scene, spp=ref_spp, seed=11))[:, :, :3]
        result["ref_seconds"] = time.perf_counter() - t0
        ref.astype(np.float32).tofile(os.path.join(out_dir, "mitsuba_ref.bin"))
    return result


def jit_on_avx2():
    """Has Dr.Jit's LLVM backend compile eight lanes wide for AVX2 and FMA (a Haswell-class
    CPU), as Tessera's x86-64-v3 builds run, instead of sixteen on a host with AVX-512. Dr.Jit
    1.5 does not bind `jit_llvm_set_target` in Python, so it is called in its core library by
    its C++ name; another Dr.Jit that lacks it fails here, and the bench leaves the row out."""
    import ctypes
    import drjit

    core = ctypes.CDLL(os.path.join(os.path.dirname(drjit.__file__), "libdrjit-core.so"))
    set_target = core["_Z19jit_llvm_set_targetPKcS0_j"]  # jit_llvm_set_target(cpu, features, width)
    set_target.argtypes = [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint]
    features = b"+avx,+avx2,+fma,+f16c,+bmi,+bmi2,+lzcnt,+popcnt,+sse4.2,-avx512f,-avx512vl,-avx512dq,-avx512bw,-avx512cd"
    set_target(b"haswell", features, 8)
    width = core["_Z21jit_llvm_vector_widthv"]
    width.restype = ctypes.c_uint
    if width() != 8:
        sys.exit(f"Dr.Jit kept a vector width of {width()}")


def write_ply(path, points, triangles):
    """A binary PLY of float32 points and int32 triangles (every Mitsuba variant reads it)."""
    with open(path, "wb") as f:
        f.write(f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\nproperty float x\nproperty float y\nproperty float z\n".encode())
        f.write(f"element face {len(triangles)}\nproperty list uchar int vertex_indices\nend_header\n".encode())
        f.write(np.ascontiguousarray(points, dtype="<f4").tobytes())
        faces = np.zeros(len(triangles), dtype=[("n", "u1"), ("v", "<i4", 3)])
        faces["n"], faces["v"] = 3, triangles
        f.write(faces.tobytes())


def mesh_arrays(prim, to_world=None):
    """A Mesh prim's points (placed by `to_world` if given) and its faces fanned into triangles."""
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(prim)
    points = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    if to_world is not None:
        m = np.array(to_world)
        points = points @ m[:3, :3] + m[3, :3]
    counts = np.array(mesh.GetFaceVertexCountsAttr().Get())
    idx = np.array(mesh.GetFaceVertexIndicesAttr().Get())
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    fans = []
    for k in range(1, counts.max() - 1):
        first = starts[counts >= k + 2]
        fans.append(np.stack([idx[first], idx[first + k], idx[first + k + 1]], axis=-1))
    return points.astype(np.float32), np.concatenate(fans)


def under_instancer(prim):
    """True for a prototype: a prim below a PointInstancer."""
    from pxr import UsdGeom

    parent = prim.GetParent()
    while parent:
        if parent.IsA(UsdGeom.PointInstancer):
            return True
        parent = parent.GetParent()
    return False


def preview_bsdf(prim):
    """Mitsuba's nearest BSDF to the UsdPreviewSurface bound to `prim`: diffuse, or for a metal
    a GGX conductor of the same alpha (roughness²) whose reflectance is the base colour."""
    from pxr import UsdShade

    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    shader = material.ComputeSurfaceSource()[0]
    rgb = {"type": "rgb", "value": list(shader.GetInput("diffuseColor").Get())}
    if shader.GetInput("metallic").Get() > 0.5:
        r = shader.GetInput("roughness").Get()
        return {"type": "roughconductor", "distribution": "ggx", "alpha": r * r, "material": "none", "specular_reflectance": rgb}
    return {"type": "diffuse", "reflectance": rgb}


def production_scene_dict(usd_path, width, height, max_depth, spp, ply_dir):
    """bench/production_scene.py's scene as a Mitsuba scene: the terrain, the rocks as instances
    of one shape group, the textured dome, the camera."""
    import mitsuba as mi
    from pxr import Gf, Usd, UsdGeom, UsdLux

    stage = Usd.Stage.Open(usd_path)
    cache = UsdGeom.XformCache()
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": max_depth}}
    transform = lambda m: mi.ScalarTransform4f(np.array(m).T.tolist())
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.PointInstancer):
            inst = UsdGeom.PointInstancer(prim)
            proto = stage.GetPrimAtPath(inst.GetPrototypesRel().GetTargets()[0])
            ply = os.path.join(ply_dir, proto.GetName() + ".ply")
            write_ply(ply, *mesh_arrays(proto))
            scene["protos"] = {"type": "shapegroup", "proto": {"type": "ply", "filename": ply, "face_normals": True, "bsdf": preview_bsdf(proto)}}
            world = cache.GetLocalToWorldTransform(prim)
            for k, m in enumerate(inst.ComputeInstanceTransformsAtTime(Usd.TimeCode.Default(), Usd.TimeCode.Default())):
                scene[f"instance_{k}"] = {"type": "instance", "shapegroup": {"type": "ref", "id": "protos"}, "to_world": transform(Gf.Matrix4d(m) * world)}
        elif prim.IsA(UsdGeom.Mesh) and not under_instancer(prim):
            ply = os.path.join(ply_dir, prim.GetName() + ".ply")
            write_ply(ply, *mesh_arrays(prim, cache.GetLocalToWorldTransform(prim)))
            scene[prim.GetName()] = {"type": "ply", "filename": ply, "face_normals": True, "bsdf": preview_bsdf(prim)}
        elif prim.IsA(UsdLux.DomeLight):
            light = UsdLux.DomeLight(prim)
            scene["sky"] = {"type": "envmap", "filename": light.GetTextureFileAttr().Get().resolvedPath, "scale": light.GetIntensityAttr().Get()}
        elif prim.IsA(UsdGeom.Camera):
            scene["sensor"] = sensor(prim, cache, width, height, spp, "independent")
    return scene


def relative_variance(a, b):
    """The mean over pixels and channels of half the squared difference of two independent
    renders, relative to their mean squared (floored at 0.1): the benches' Rust side computes
    the same (`anchors::relative_variance`)."""
    a, b = a.astype(np.float64), b.astype(np.float64)
    m = 0.5 * (a + b)
    return float(np.mean(0.5 * (a - b) ** 2 / (m * m + 0.01)))


def production(usd_path, width, height, spp, max_depth, out_dir, variant):
    import mitsuba as mi

    mi.set_variant(variant)
    scene = mi.load_dict(production_scene_dict(usd_path, width, height, max_depth, spp, out_dir))
    best = best_of_three(scene, spp)
    a, b = (np.array(mi.render(scene, spp=spp, seed=s))[:, :, :3] for s in (7, 8))
    mean = a.reshape(-1, 3).mean(axis=0)
    return {
        "variant": variant,
        "mean": [float(c) for c in mean],
        "seconds": best,
        "paths_per_s": width * height * spp / best,
        "noise": relative_variance(a, b),
    }


if __name__ == "__main__":
    if sys.argv[1] == "rays":
        print(json.dumps(rays(sys.argv[2], int(sys.argv[3]) if len(sys.argv) > 3 else 2)))
    elif sys.argv[1] == "production":
        usd, w, h, spp, depth, out, variant = sys.argv[2:9]
        print(json.dumps(production(usd, int(w), int(h), int(spp), int(depth), out, variant)))
    elif sys.argv[1] == "cornell":
        usd, w, h, spp, depth, ref_spp, out, variant = sys.argv[2:10]
        sampler = sys.argv[10] if len(sys.argv) > 10 else "independent"
        print(json.dumps(cornell(usd, int(w), int(h), int(spp), int(depth), int(ref_spp), out, variant, sampler)))
    else:
        sys.exit(__doc__)
