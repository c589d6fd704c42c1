#!/usr/bin/env python3
"""Writes the production-sized scene of the speed comparison with Mitsuba (issue 22) as USD:

- a terrain of 999 698 triangles (707 x 707 quads, diffuse);
- 300 rocks (a 1 280-triangle icosphere, glossy metal) placed by a PointInstancer, turned and
  scaled at random (seeded);
- a DomeLight textured with fixtures/textures/maps/sky.hdr, and a camera.

    python3 bench/production_scene.py OUT.usdc

`cargo bench -p tessera --bench production` writes it once into a temporary folder, renders it
with Tessera, and has `bench/anchors.py production` render the same file with Mitsuba 3.
Needs: pip install usd-core numpy.
"""

import math
import os
import sys

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, Vt

TERRAIN_QUADS = 707
ROCKS = 300
SIZE = 40.0


def height(x, z):
    """The terrain's height: long swells and a finer ripple."""
    return 0.8 * np.sin(0.35 * x) * np.cos(0.27 * z) + 0.25 * np.sin(1.3 * x + 0.7 * z)


def terrain_mesh(stage, path, material):
    n = TERRAIN_QUADS
    u = np.linspace(-SIZE / 2, SIZE / 2, n + 1)
    x, z = np.meshgrid(u, u)
    points = np.stack([x, height(x, z), z], axis=-1).reshape(-1, 3).astype(np.float32)
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    a = (j * (n + 1) + i).ravel()
    # Counter-clockwise seen from above (+Y), USD's default orientation.
    quads = np.stack([a, a + n + 1, a + n + 2, a + 1], axis=-1).ravel().astype(np.int32)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(n * n, 4, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(quads))
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


def icosphere(levels):
    """A unit icosphere: 20·4^levels triangles."""
    t = (1 + 5 ** 0.5) / 2
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [np.array(v) / np.linalg.norm(v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid, out = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mid[key] = len(verts) - 1
            return mid[key]

        for a, b, c in faces:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = out
    return np.array(verts), np.array(faces)


def rock_mesh(stage, path, material):
    verts, faces = icosphere(3)
    rng = np.random.default_rng(7)
    # Lumpy: each vertex pushed in or out along its direction.
    verts = verts * (1 + 0.15 * rng.standard_normal(len(verts)))[:, None] * np.array([1.0, 0.6, 0.8])
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(verts.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.ravel().astype(np.int32)))
    mesh.CreateSubdivisionSchemeAttr("none")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(material)


def preview(stage, path, color, roughness, metallic):
    material = UsdShade.Material.Define(stage, path)
    shader = UsdShade.Shader.Define(stage, path + "/Surface")
    shader.CreateIdAttr("UsdPreviewSurface")
    shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*color))
    shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(roughness)
    shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(metallic)
    # IOR 1: no specular layer on the diffuse ground, which Mitsuba's `diffuse` matches.
    shader.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(1.0)
    material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
    return material


def main(out):
    stage = Usd.Stage.CreateNew(out)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    ground = preview(stage, "/World/Looks/Ground", (0.35, 0.3, 0.25), 1.0, 0.0)
    metal = preview(stage, "/World/Looks/Rock", (0.8, 0.6, 0.45), 0.35, 1.0)
    terrain_mesh(stage, "/World/Terrain", ground)
    rocks = UsdGeom.PointInstancer.Define(stage, "/World/Rocks")
    UsdGeom.Scope.Define(stage, "/World/Rocks/Prototypes")
    rock_mesh(stage, "/World/Rocks/Prototypes/Rock", metal)
    rocks.CreatePrototypesRel().SetTargets(["/World/Rocks/Prototypes/Rock"])
    rng = np.random.default_rng(11)
    xz = rng.uniform(-SIZE / 2 + 2, SIZE / 2 - 2, size=(ROCKS, 2))
    positions = np.stack([xz[:, 0], height(xz[:, 0], xz[:, 1]) + 0.2, xz[:, 1]], axis=-1).astype(np.float32)
    q = rng.standard_normal((ROCKS, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    scales = rng.uniform(0.3, 1.0, size=ROCKS)
    rocks.CreateProtoIndicesAttr(Vt.IntArray([0] * ROCKS))
    rocks.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(positions))
    rocks.CreateOrientationsAttr(Vt.QuathArray([Gf.Quath(float(w), Gf.Vec3h(float(x), float(y), float(z))) for w, x, y, z in q]))
    rocks.CreateScalesAttr(Vt.Vec3fArray([Gf.Vec3f(float(s)) for s in scales]))
    sky = UsdLux.DomeLight.Define(stage, "/World/Sky")
    sky_file = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fixtures", "textures", "maps", "sky.hdr")
    sky.CreateTextureFileAttr(Sdf.AssetPath(os.path.normpath(sky_file)))
    sky.CreateIntensityAttr(1.0)
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.CreateFocalLengthAttr(30.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(36.0 * 9 / 16)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 1000.0))
    xf = UsdGeom.Xformable(cam)
    xf.AddTranslateOp().Set(Gf.Vec3d(0, 7, 24))
    xf.AddRotateXOp().Set(-math.degrees(math.atan2(6.0, 24.0)))
    stage.GetRootLayer().Save()


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
