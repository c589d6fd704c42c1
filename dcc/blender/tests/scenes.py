"""The comparison scenes, built with bpy, and how each renderer renders them.

Every object carries a ``pass_index``: the region it is compared in.
"""

import os

import bpy
import numpy as np

#: Region names by pass index, per scene.
REGIONS = {
    "box": {1: "floor", 2: "red wall", 3: "green wall", 4: "back wall", 5: "rough metal sphere"},
    "box_matte": {1: "floor", 2: "red wall", 3: "green wall", 4: "back wall", 5: "rough metal sphere"},
    "glass": {1: "floor", 2: "glass sphere"},
    "textured": {1: "textured plane"},
    "linked": {1: "floor", 2: "key-lit sphere", 3: "unlinked sphere"},
    "emitter_linked": {1: "floor", 2: "panel-lit sphere", 3: "unlinked sphere"},
    "udim": {1: "tile 1001 plane", 2: "tile 1002 plane"},
    "subsurface": {1: "floor", 2: "subsurface sphere", 3: "half subsurface sphere"},
    "displaced": {1: "floor", 2: "displaced grid"},
    "emission_shader": {1: "diffuse floor", 2: "sphere"},
    "bumped": {1: "bump node plane", 2: "bump-only plane", 3: "flat plane"},
    "mixed": {1: "constant mix plane", 2: "masked mix plane"},
    "world": {0: "background", 1: "floor", 2: "sphere"},
    "procedural_world": {0: "background", 1: "floor", 2: "sphere"},
    "sky_world": {0: "background", 1: "floor", 2: "sphere"},
    "spot": {1: "floor"},
    "shaders": {1: "floor", 2: "glossy sphere", 3: "glass sphere", 4: "cutout plane", 5: "image cutout plane", 6: "glossy mix sphere", 7: "translucent plane"},
    "coats": {1: "floor", 2: "tinted coat sphere", 3: "tinted coat metal sphere", 4: "checkered coat metal sphere", 5: "untinted coat sphere"},
    "rough_diffuse": {1: "floor", 2: "rough principled sphere", 3: "rough diffuse sphere", 4: "checkered rough sphere"},
    "sheen": {1: "floor", 2: "white sheen sphere", 3: "tinted sheen sphere", 4: "specular tint sphere", 5: "edge-tinted metal sphere", 6: "checkered sheen sphere", 7: "checkered sheen tint sphere", 8: "checkered specular tint sphere"},
    "anisotropic": {1: "floor", 2: "brushed metal sphere", 3: "brushed metal panel", 4: "turned specular sphere", 5: "checkered specular sphere", 6: "uv-brushed panel", 7: "x-brushed sphere"},
    "thin_film": {1: "floor", 2: "soap film sphere", 3: "thin oil film sphere", 4: "filmed metal sphere", 5: "filmed gold sphere"},
    "glass_film": {2: "filmed glass sphere", 3: "soap bubble", 4: "filmed Glass BSDF sphere"},
    "hair": {1: "floor", 2: "melanin hair", 3: "coloured hair"},
    "procedural": {1: "noise ramp plane", 2: "small gradient plane", 3: "large gradient plane", 4: "glowing plane", 5: "wave bump plane", 6: "checker emission plane", 7: "checker mix plane", 8: "added glow plane", 9: "unwrapped noise sphere"},
}

def udim_image(directory):
    """A tiled image of two solid tiles, 1001 reddish and 1002 bluish, saved as
    `tiles.<UDIM>.png` in `directory` (the exporter copies each tile beside the scene)."""
    for tile, color in ((1001, (0.8, 0.2, 0.1)), (1002, (0.1, 0.4, 0.8))):
        img = bpy.data.images.new(f"tile{tile}", 8, 8)
        px = np.zeros((8, 8, 4), np.float32); px[..., :3] = color; px[..., 3] = 1
        img.pixels.foreach_set(px.ravel()); img.filepath_raw = os.path.join(directory, f"tiles.{tile}.png"); img.file_format = 'PNG'; img.save()
    tiled = bpy.data.images.load(os.path.join(directory, "tiles.1001.png"))
    tiled.source = 'TILED'
    assert sorted(t.number for t in tiled.tiles) == [1001, 1002], list(tiled.tiles)
    return tiled


def hdri_world(directory, strength=2.0):
    """A world of an equirectangular image (Environment Texture) at Background Strength
    `strength`: a blue sky over a brown ground and a bright sun 10° across, up and to the left
    of the camera, so a dome turned the wrong way lights the floor and sphere differently."""
    w, h = 1024, 512
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    # Blender's equirectangular mapping: u = atan2(y, -x) / 2π + 0.5, v = atan2(z, hypot(x, y)) / π + 0.5.
    longitude, latitude = (u[None, :] - 0.5) * 2 * np.pi, (v[:, None] - 0.5) * np.pi
    d = np.stack(np.broadcast_arrays(-np.cos(latitude) * np.cos(longitude), np.cos(latitude) * np.sin(longitude), np.sin(latitude) + 0 * longitude), -1)
    px = np.zeros((h, w, 4), np.float32); px[..., 3] = 1
    px[..., :3] = np.where(d[..., 2:3] > 0, (0.2, 0.3, 0.5), (0.06, 0.045, 0.03))
    sun = np.array([-1.0, -0.5, 1.0]) / np.linalg.norm([-1.0, -0.5, 1.0])
    px[(d @ sun) > np.cos(np.radians(5.0)), :3] = (40.0, 36.0, 30.0)
    img = bpy.data.images.new("sky", w, h, float_buffer=True)
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = os.path.join(directory, "sky.exr"); img.file_format = 'OPEN_EXR'; img.save()
    world = bpy.data.worlds.new("sky")
    tree = world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment"); env.image = bpy.data.images.load(img.filepath_raw)
    background = tree.nodes["Background"]; background.inputs["Strength"].default_value = strength
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    return world


def direction_world():
    """A procedural world the export cannot carry: red growing towards +x, green towards the
    zenith, a little blue everywhere (Texture Coordinate's Generated, the ray's direction, at
    Strength 1.5), so a dome turned or mirrored lights the sphere's sides differently."""
    world = bpy.data.worlds.new("directions")
    tree = world.node_tree
    coords, split, join = (tree.nodes.new(k) for k in ("ShaderNodeTexCoord", "ShaderNodeSeparateXYZ", "ShaderNodeCombineColor"))
    tree.links.new(coords.outputs["Generated"], split.inputs[0])
    for axis, channel in (("X", "Red"), ("Z", "Green")):
        ramp = _node(tree, "ShaderNodeMapRange", From_Min=-1.0, From_Max=1.0, To_Min=0.0, To_Max=1.0)
        tree.links.new(split.outputs[axis], ramp.inputs[0]); tree.links.new(ramp.outputs[0], join.inputs[channel])
    join.inputs["Blue"].default_value = 0.2
    background = tree.nodes["Background"]; background.inputs["Strength"].default_value = 1.5
    tree.links.new(join.outputs[0], background.inputs["Color"])
    return world


def sky_world():
    """Blender's default Sky Texture (its sun disc on) with the sun 35° up, turned 60°, at
    Strength 0.05: the sun, half a degree across, gives most of the light."""
    world = bpy.data.worlds.new("sky")
    tree = world.node_tree
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sun_elevation, sky.sun_rotation = np.radians(35.0), np.radians(60.0)
    background = tree.nodes["Background"]; background.inputs["Strength"].default_value = 0.05
    tree.links.new(sky.outputs["Color"], background.inputs["Color"])
    return world


def procedural_planes(mat, add, directory):
    """Inputs Blender's USD export cannot carry, which the add-on bakes, one plane (region) each
    but for the gradient's two, and a sphere without a UV map: see each builder below."""
    def plane(material, index, size, at):
        add(bpy.ops.mesh.primitive_plane_add, material, index, size=size, location=at)

    plane(_noise_ramp(mat), 1, 2, (-2.4, 0, 0))
    gradient = _object_gradient(mat)
    plane(gradient, 2, 1, (-0.6, 0, 0))
    plane(gradient, 3, 3, (1.6, 0, 0))
    plane(_image_glow(mat, directory), 4, 2, (0, 2.6, 0))
    plane(_wave_bump(mat), 5, 2, (-2.4, 2.6, 0))
    plane(_checker_emission(), 6, 2, (2.4, 2.6, 0))
    plane(_checker_mix(mat), 7, 2, (0, -2.4, 0))
    plane(_added_glow(mat), 8, 2, (2.4, -2.4, 0))
    sphere = add(bpy.ops.mesh.primitive_uv_sphere_add, _unwrapped_noise(mat), 9, radius=0.55, location=(-1.7, -1.9, 0.55), segments=16, ring_count=8)
    sphere.data.uv_layers.remove(sphere.data.uv_layers[0])
    subdivision = sphere.modifiers.new("Subdivision", "SUBSURF"); subdivision.levels = subdivision.render_levels = 2
    bpy.ops.object.shade_smooth()


def hair_patch(index, x, parametrization, **inputs):
    """A patch of 600 hair curves (six points each, 1.5 cm wide, leaning along +x) centred at
    `x`, with a Principled Hair BSDF of `parametrization` and `inputs`."""
    rng = np.random.default_rng(index)
    n, k = 600, 6
    curves = bpy.data.hair_curves.new(f"hair {index}")
    curves.add_curves([k] * n)
    roots = rng.uniform(-0.6, 0.6, (n, 2))
    along = np.arange(k) / (k - 1)
    pos = np.zeros((n, k, 3), np.float32)
    pos[..., 0] = x + roots[:, :1] + 0.3 * along ** 2
    pos[..., 1] = roots[:, 1:]
    pos[..., 2] = 1.0 * along
    curves.attributes["position"].data.foreach_set("vector", pos.ravel())
    radius = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
    radius.data.foreach_set("value", np.full(n * k, 0.0075, np.float32))
    obj = bpy.data.objects.new(f"hair {index}", curves)
    bpy.context.scene.collection.objects.link(obj)
    obj.pass_index = index
    m = bpy.data.materials.new(f"hair {index}"); tree = m.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    # The parametrization first: Blender does not find the inputs of another one by name.
    hair = tree.nodes.new("ShaderNodeBsdfHairPrincipled"); hair.parametrization = parametrization
    for name, value in inputs.items():
        hair.inputs[name].default_value = value
    tree.links.new(hair.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    curves.materials.append(m)


def shader_spheres_and_cutouts(mat, add, directory):
    """Shaders Blender's USD export drops, each a region: a Glossy BSDF sphere, a Glass BSDF
    sphere, a Mix Shader of a blue Diffuse and a gold Glossy BSDF by Fac 0.4 on a third, a green
    Translucent BSDF plane standing between the camera and a point light, and
    two planes tilted towards the camera, each a Mix Shader of a Transparent BSDF and a red
    Principled BSDF: by Fac 0.6 (Transparent first), and by an image's alpha, 1 on its left half
    and 0.25 on its right (Transparent second), over a Lambertian floor."""
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=20)
    glossy = _standalone_material("glossy", "ShaderNodeBsdfGlossy", Color=(0.9, 0.6, 0.3, 1), Roughness=0.35)
    add(bpy.ops.mesh.primitive_uv_sphere_add, glossy, 2, radius=0.8, location=(-2.6, 0, 0.8), segments=64, ring_count=32)
    glass = _standalone_material("glass", "ShaderNodeBsdfGlass", Roughness=0.0, IOR=1.5)
    add(bpy.ops.mesh.primitive_uv_sphere_add, glass, 3, radius=0.8, location=(-0.6, 0, 0.8), segments=64, ring_count=32)
    translucent = _standalone_material("translucent", "ShaderNodeBsdfTranslucent", Color=(0.3, 0.8, 0.2, 1))
    add(bpy.ops.mesh.primitive_plane_add, translucent, 7, size=1.6, location=(-1.4, 2.6, 1.2), rotation=(1.5708, 0, 0))
    # Behind the translucent plane: what the camera sees of it is this light, transmitted.
    bpy.ops.object.light_add(type='POINT', location=(-1.4, 3.6, 1.2)); bpy.context.object.data.energy = 100
    mix = _standalone_material("glossy mix", "ShaderNodeMixShader", Fac=0.4)
    tree = mix.node_tree
    blue, gold = _node(tree, "ShaderNodeBsdfDiffuse", Color=(0.1, 0.2, 0.7, 1)), _node(tree, "ShaderNodeBsdfGlossy", Color=(0.9, 0.6, 0.3, 1), Roughness=0.2)
    tree.links.new(blue.outputs[0], tree.nodes["Mix Shader"].inputs[1]); tree.links.new(gold.outputs[0], tree.nodes["Mix Shader"].inputs[2])
    add(bpy.ops.mesh.primitive_uv_sphere_add, mix, 6, radius=0.55, location=(-1.9, -2.2, 0.55), segments=64, ring_count=32)
    for index, fac, size, at in ((4, 0.6, 1.6, (1.4, -1.6, 0.6)), (5, _alpha_halves(directory), 2.4, (2.2, 1.2, 1.4))):
        add(bpy.ops.mesh.primitive_plane_add, _cutout(mat, fac, index), index, size=size, location=at, rotation=(0.6, 0, 0))


def _brushed_along(m, **tangent):
    """`m` with its Principled BSDF anisotropic (0.9, GGX) along a Tangent node set to `tangent`."""
    tree = m.node_tree
    p = tree.nodes["Principled BSDF"]
    p.inputs["Anisotropic"].default_value = 0.9
    p.inputs["IOR"].default_value = 1.5
    p.distribution = "GGX"
    node = _node(tree, "ShaderNodeTangent")
    for name, value in tangent.items():
        setattr(node, name, value)
    tree.links.new(node.outputs["Tangent"], p.inputs["Tangent"])
    return m


def _turn_uvs_a_quarter(mesh):
    """Turns `mesh`'s active UV map a quarter about the middle of the UV square: (u, v) -> (1 - v, u)."""
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers.active.uv.foreach_get("vector", uv)
    u, v = uv[0::2].copy(), uv[1::2].copy()
    uv[0::2], uv[1::2] = 1.0 - v, u
    mesh.uv_layers.active.uv.foreach_set("vector", uv)


def _checkered(m, socket):
    """`m` with its Principled BSDF's `socket` driven by a Checker's Fac (squares of 0 and 1)."""
    tree = m.node_tree
    checker = _node(tree, "ShaderNodeTexChecker", Scale=4.0)
    tree.links.new(checker.outputs["Fac"], tree.nodes["Principled BSDF"].inputs[socket])
    return m


def _standalone_material(name, kind, **inputs):
    """A material whose surface is one shader node of `kind`."""
    m = bpy.data.materials.new(name); tree = m.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    tree.links.new(_node(tree, kind, **inputs).outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return m


def _alpha_halves(directory):
    """An 8 × 8 grey image whose alpha is 1 on the left half and 0.25 on the right."""
    path = os.path.join(directory, "halves.png")
    img = bpy.data.images.new("halves", 8, 8, alpha=True)
    px = np.full((8, 8, 4), 0.5, np.float32); px[:, :4, 3] = 1.0; px[:, 4:, 3] = 0.25
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = path; img.file_format = 'PNG'; img.save()
    return bpy.data.images.load(path)


def _cutout(mat, fac, index):
    """A Mix Shader of a Transparent BSDF and a red Principled BSDF: Transparent first by a
    constant Fac, or second by an image's alpha."""
    m = mat(f"cutout {index}", (0.8, 0.1, 0.1)); tree = m.node_tree
    mix, clear = tree.nodes.new("ShaderNodeMixShader"), tree.nodes.new("ShaderNodeBsdfTransparent")
    red = tree.nodes["Principled BSDF"]
    if isinstance(fac, float):
        mix.inputs["Fac"].default_value = fac
        sides = (clear, red)
    else:
        image = tree.nodes.new("ShaderNodeTexImage"); image.image = fac
        tree.links.new(image.outputs["Alpha"], mix.inputs["Fac"])
        sides = (red, clear)
    tree.links.new(sides[0].outputs[0], mix.inputs[1]); tree.links.new(sides[1].outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return m


def _node(tree, kind, **inputs):
    """A new node of `kind` in `tree`, with the given input values (names with spaces as _)."""
    node = tree.nodes.new(kind)
    for name, value in inputs.items():
        node.inputs[name.replace("_", " ")].default_value = value
    return node


def _shader_pair(tree, kind, first, second):
    """A Mix or Add Shader of `first` and `second` as the material's surface."""
    node = tree.nodes.new(kind)
    offset = 1 if kind == "ShaderNodeMixShader" else 0
    tree.links.new(first.outputs[0], node.inputs[offset]); tree.links.new(second.outputs[0], node.inputs[offset + 1])
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return node


def _noise_ramp(mat):
    """A Noise through a red-to-blue Color Ramp into Base Color."""
    m = mat("noise ramp", (0.8, 0.8, 0.8)); tree = m.node_tree
    noise, ramp = _node(tree, "ShaderNodeTexNoise", Scale=3.0), tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.8, 0.1, 0.05, 1); ramp.color_ramp.elements[1].color = (0.05, 0.2, 0.8, 1)
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"]); tree.links.new(ramp.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def _unwrapped_noise(mat):
    """A Noise over Generated coordinates through a green-to-orange Color Ramp, for a sphere
    whose UV map is removed: baked over the add-on's own unwrap (tessera_blender/unwrap.py)."""
    m = mat("unwrapped noise", (0.8, 0.8, 0.8)); tree = m.node_tree
    noise, ramp = _node(tree, "ShaderNodeTexNoise", Scale=4.0), tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.1, 0.7, 0.1, 1); ramp.color_ramp.elements[1].color = (0.9, 0.4, 0.05, 1)
    tree.links.new(noise.outputs["Fac"], ramp.inputs["Fac"]); tree.links.new(ramp.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def _object_gradient(mat):
    """A Gradient over Object coordinates through a Color Ramp into Base Color: on planes of
    different sizes it differs (the 1 m plane reads 0.125 on average, the 3 m one 0.5), so each
    needs its own bake."""
    m = mat("gradient", (0.8, 0.8, 0.8)); tree = m.node_tree
    coords, gradient, ramp = (tree.nodes.new(k) for k in ("ShaderNodeTexCoord", "ShaderNodeTexGradient", "ShaderNodeValToRGB"))
    tree.links.new(coords.outputs["Object"], gradient.inputs["Vector"]); tree.links.new(gradient.outputs["Fac"], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], tree.nodes["Principled BSDF"].inputs["Base Color"])
    return m


def _image_glow(mat, directory):
    """An image's Emission Color at Strength 4, which the export drops."""
    path = os.path.join(directory, "warm.png")
    img = bpy.data.images.new("warm", 8, 8)
    px = np.zeros((8, 8, 4), np.float32); px[..., :3] = (0.5, 0.35, 0.2); px[..., 3] = 1
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = path; img.file_format = 'PNG'; img.save()
    m = mat("glowing", (0.0, 0.0, 0.0)); tree = m.node_tree
    t = tree.nodes.new("ShaderNodeTexImage"); t.image = bpy.data.images.load(path)
    principled = tree.nodes["Principled BSDF"]
    tree.links.new(t.outputs["Color"], principled.inputs["Emission Color"]); principled.inputs["Emission Strength"].default_value = 4.0
    return m


def _wave_bump(mat):
    """A saw-profile Wave texture bumping the plane into ramps: a procedural normal, baked as a
    tangent-space normal map."""
    m = mat("wave bump", (0.8, 0.8, 0.8)); tree = m.node_tree
    wave = _node(tree, "ShaderNodeTexWave", Scale=2.0, Distortion=0.0, Detail=0.0); wave.wave_profile = 'SAW'
    bump = _node(tree, "ShaderNodeBump", Distance=0.05)
    tree.links.new(wave.outputs["Fac"], bump.inputs["Height"]); tree.links.new(bump.outputs["Normal"], tree.nodes["Principled BSDF"].inputs["Normal"])
    return m


def _checker_emission():
    """An Emission shader whose Color is a Checker texture: baked whole, Color × Strength."""
    m = bpy.data.materials.new("checker emission"); tree = m.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    checker = _node(tree, "ShaderNodeTexChecker", Scale=4.0, Color1=(1.0, 0.5, 0.2, 1), Color2=(0.1, 0.3, 0.9, 1))
    emission = _node(tree, "ShaderNodeEmission", Strength=2.0)
    tree.links.new(checker.outputs["Color"], emission.inputs["Color"]); tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    return m


def _checker_mix(mat):
    """A Mix Shader, by a Checker's Fac, of a red Principled BSDF and a Diffuse BSDF coloured by
    a Noise: the mask baked, and the Diffuse BSDF's colour, which the export drops with it."""
    m = mat("checker mix", (0.8, 0.1, 0.1)); tree = m.node_tree
    diffuse, noise = tree.nodes.new("ShaderNodeBsdfDiffuse"), _node(tree, "ShaderNodeTexNoise", Scale=5.0)
    tree.links.new(noise.outputs["Color"], diffuse.inputs["Color"])
    checker = _node(tree, "ShaderNodeTexChecker", Scale=3.0)
    node = _shader_pair(tree, "ShaderNodeMixShader", tree.nodes["Principled BSDF"], diffuse)
    tree.links.new(checker.outputs["Fac"], node.inputs["Fac"])
    return m


def _added_glow(mat):
    """An Add Shader of a grey Principled BSDF and an Emission shader of a Brick texture: the
    glow baked onto the BSDF."""
    m = mat("added glow", (0.5, 0.5, 0.5)); tree = m.node_tree
    bricks, emission = _node(tree, "ShaderNodeTexBrick", Scale=3.0), _node(tree, "ShaderNodeEmission", Strength=0.5)
    tree.links.new(bricks.outputs["Color"], emission.inputs["Color"])
    _shader_pair(tree, "ShaderNodeAddShader", tree.nodes["Principled BSDF"], emission)
    return m


def _sheen_spheres(mat, add, scene):
    """The `sheen` scene's objects; its world."""
    # A Principled BSDF's sheen (Zeltner et al.'s in Cycles, the fuzz coat in Tessera) over
    # dark bases, in a uniform white world, where sheen shows as a bright rim: white at the
    # default roughness 0.5, and orange at roughness 0.2.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.5, 0.5, 0.5)), 1, size=20)
    for index, x, base, inputs in (
        (2, -1.2, (0.05, 0.05, 0.05), {"Sheen Weight": 1.0}),
        (3, 1.2, (0.1, 0.02, 0.02), {"Sheen Weight": 1.0, "Sheen Roughness": 0.2, "Sheen Tint": (1.0, 0.6, 0.2, 1)}),
    ):
        m = mat(f"sheen {index}", base)
        for name, value in inputs.items():
            m.node_tree.nodes["Principled BSDF"].inputs[name].default_value = value
        add(bpy.ops.mesh.primitive_uv_sphere_add, m, index, radius=1.0, location=(x, 0, 1.0), segments=64, ring_count=32)
    # Behind them, a near-black sphere whose specular (IOR 1.5, roughness 0.3) is tinted
    # orange head-on and stays white at grazing angles.
    m = mat("specular tint", (0.02, 0.02, 0.02), rough=0.3)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["IOR"].default_value = 1.5
    p.inputs["Specular Tint"].default_value = (1.0, 0.4, 0.1, 1)
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 4, radius=1.0, location=(0, 2.5, 1.0), segments=64, ring_count=32)
    # And a gold metal whose Specular Tint is its F82 edge tint.
    m = mat("edge tint", (0.9, 0.6, 0.3), rough=0.3, metal=1.0)
    m.node_tree.nodes["Principled BSDF"].inputs["Specular Tint"].default_value = (1.0, 0.5, 0.2, 1)
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 5, radius=1.0, location=(2.4, 2.5, 1.0), segments=64, ring_count=32)
    # And in front, a dark sphere whose Sheen Weight is a Checker (0 and 1): baked at 256².
    scene.tessera.bake_size = 256
    m = _checkered(mat("checkered sheen", (0.05, 0.05, 0.05)), "Sheen Weight")
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 6, radius=0.7, location=(0.0, -2.3, 0.7), segments=64, ring_count=32)
    # Front right, a full sheen whose Sheen Tint is a Checker of orange and blue and whose
    # Sheen Roughness runs from 0.2 to 0.4 across the object (a Gradient); front left, a
    # near-black specular whose Specular Tint is a Checker of orange and white. All baked.
    # (A roughness from the Checker itself read 0.896: Tessera filters a baked image over
    # each pixel's footprint, the squares are about three pixels wide, and the sheen is not
    # linear in its roughness; the same bakes at one roughness read 0.996-1.007.)
    m = mat("checkered sheen tint", (0.05, 0.05, 0.05))
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Sheen Weight"].default_value = 1.0
    checker = _node(m.node_tree, "ShaderNodeTexChecker", Scale=4.0, Color1=(1.0, 0.5, 0.1, 1), Color2=(0.2, 0.4, 1.0, 1))
    m.node_tree.links.new(checker.outputs["Color"], p.inputs["Sheen Tint"])
    ramp = _node(m.node_tree, "ShaderNodeMath"); ramp.operation = "MULTIPLY_ADD"
    ramp.inputs[1].default_value, ramp.inputs[2].default_value = 0.2, 0.2
    m.node_tree.links.new(_node(m.node_tree, "ShaderNodeTexGradient").outputs["Fac"], ramp.inputs[0])
    m.node_tree.links.new(ramp.outputs[0], p.inputs["Sheen Roughness"])
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 7, radius=0.45, location=(1.25, -2.4, 0.45), segments=64, ring_count=32)
    m = mat("checkered specular tint", (0.02, 0.02, 0.02), rough=0.3)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["IOR"].default_value = 1.5
    checker = _node(m.node_tree, "ShaderNodeTexChecker", Scale=4.0, Color1=(1.0, 0.4, 0.1, 1), Color2=(1.0, 1.0, 1.0, 1))
    m.node_tree.links.new(checker.outputs["Color"], p.inputs["Specular Tint"])
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 8, radius=0.45, location=(-1.3, -2.4, 0.45), segments=64, ring_count=32)
    world = bpy.data.worlds.new("white")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    return world


def _anisotropic_objects(mat, add, scene):
    """The `anisotropic` scene's objects; its world."""
    # A Principled BSDF's Anisotropic along Cycles' default tangent (radial around the
    # object's Z in Generated coordinates), under an area light: on a silver sphere, on a
    # metal panel turned towards the camera (brushed in circles around its middle), and on a
    # near-black dielectric sphere whose specular tangent is turned a quarter. Single
    # scattering in both renderers (Cycles' GGX, Tessera without energy compensation): the
    # two compensate differently, which the anisotropic lobes show most (docs/blender.md).
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.5, 0.5, 0.5)), 1, size=20)
    for index, kind_, inputs in (
        (2, "sphere", {"Anisotropic": 0.9}),
        (3, "panel", {"Anisotropic": 0.9}),
        (4, "dielectric", {"Anisotropic": 0.9, "Anisotropic Rotation": 0.25}),
    ):
        metal = 0.0 if kind_ == "dielectric" else 1.0
        m = mat(f"brushed {index}", (0.0, 0.0, 0.0) if metal == 0.0 else (0.9, 0.9, 0.9), rough=0.35, metal=metal)
        inputs = {**inputs, "IOR": 1.5} if metal == 0.0 else inputs
        for name, value in inputs.items():
            m.node_tree.nodes["Principled BSDF"].inputs[name].default_value = value
        m.node_tree.nodes["Principled BSDF"].distribution = "GGX"
        if kind_ == "panel":
            # Stretched along its X (Cycles places a tangent as a normal, so the add-on
            # writes it for Tessera to place as a direction to the same place) and moved
            # along it by a Displace modifier (Cycles takes Generated coordinates from the
            # undeformed mesh: the circles stay centred on the undeformed panel).
            panel = add(bpy.ops.mesh.primitive_plane_add, m, index, size=2.2, location=(2.4, 2.0, 1.4), rotation=(1.2, 0, 0.3))
            panel.scale = (1.4, 0.7, 1.0)
            shift = panel.modifiers.new("Shift", "DISPLACE")
            shift.direction, shift.strength = "X", -0.8
        else:
            add(bpy.ops.mesh.primitive_uv_sphere_add, m, index, radius=1.0, location=(-1.6 if metal else 0.0, 0 if metal else 2.5, 1.0), segments=64, ring_count=32)
    # In front of them, a black dielectric (IOR 1.5) whose Anisotropic is a Checker (0 and
    # 1): baked. Not a metal: a metal there would throw caustics on the floor that Tessera
    # resolves with more noise than Cycles at 256 spp (the floor read 1.034). Baked at 256².
    scene.tessera.bake_size = 256
    m = _checkered(mat("checkered brushed", (0.0, 0.0, 0.0), rough=0.35), "Anisotropic")
    m.node_tree.nodes["Principled BSDF"].inputs["IOR"].default_value = 1.5
    m.node_tree.nodes["Principled BSDF"].distribution = "GGX"
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 5, radius=0.7, location=(1.0, -2.2, 0.7), segments=64, ring_count=32)
    # Tangents from a Tangent node, on black dielectrics (metals' caustics on the floor are
    # what Tessera resolves noisier, above): a panel brushed along its UV map's U, whose UVs
    # are turned a quarter (U runs up the panel: straight strokes where the default would
    # draw circles), turned to mirror the light into the camera, and a sphere brushed
    # radially around the object's X.
    m = _brushed_along(mat("uv brushed", (0.0, 0.0, 0.0), rough=0.35), direction_type="UV_MAP", uv_map="UVMap")
    panel = add(bpy.ops.mesh.primitive_plane_add, m, 6, size=1.1, location=(-1.6, -2.4, 0.75), rotation=(0.93, 0, 0.72))
    _turn_uvs_a_quarter(panel.data)
    m = _brushed_along(mat("x brushed", (0.0, 0.0, 0.0), rough=0.35), direction_type="RADIAL", axis="X")
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 7, radius=0.4, location=(-0.3, -3.0, 0.4), segments=64, ring_count=32)
    bpy.ops.object.light_add(type='AREA', location=(1.0, -3.0, 4.0), rotation=(0.7, 0.2, 0)); l = bpy.context.object.data; l.energy = 600; l.size = 1.5
    scene.tessera.energy_compensation = False
    world = bpy.data.worlds.new("dim")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.2, 0.2, 0.2, 1)
    return world


def _thin_film_spheres(mat, add):
    """The `thin_film` scene's objects; its world."""
    # A Principled BSDF's Thin Film over black dielectrics (IOR 1.5, Roughness 0.2) in a
    # uniform white world, which each reflects by its film's colours: 500 nm of IOR 1.33 (a
    # soap film's greens and magentas) and 250 nm of IOR 1.45.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.5, 0.5, 0.5)), 1, size=20)
    for index, x, inputs in ((2, -1.2, {"Thin Film Thickness": 500.0, "Thin Film IOR": 1.33}), (3, 1.2, {"Thin Film Thickness": 250.0, "Thin Film IOR": 1.45})):
        m = mat(f"film {index}", (0.0, 0.0, 0.0), rough=0.2)
        for name, value in {**inputs, "IOR": 1.5}.items():
            m.node_tree.nodes["Principled BSDF"].inputs[name].default_value = value
        add(bpy.ops.mesh.primitive_uv_sphere_add, m, index, radius=1.0, location=(x, 0, 1.0), segments=64, ring_count=32)
    # In front, films over metals: 300 nm of IOR 1.5 over a silver-white metal, and
    # 200 nm of IOR 2.0 over gold with an orange Specular Tint (Cycles estimates the metal's
    # complex index from the colour and the tint, Tessera too).
    for index, x, base, tint, nm, ior in ((4, -1.0, (0.9, 0.9, 0.9), (1, 1, 1, 1), 300.0, 1.5), (5, 1.0, (1.0, 0.78, 0.34), (1.0, 0.6, 0.3, 1), 200.0, 2.0)):
        m = mat(f"metal film {index}", base, rough=0.5, metal=1.0)
        p = m.node_tree.nodes["Principled BSDF"]
        p.inputs["Specular Tint"].default_value = tint
        p.inputs["Thin Film Thickness"].default_value, p.inputs["Thin Film IOR"].default_value = nm, ior
        add(bpy.ops.mesh.primitive_uv_sphere_add, m, index, radius=0.45, location=(x, -2.9, 0.45), segments=64, ring_count=32)
    world = bpy.data.worlds.new("white")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    return world


def _glass_film_spheres(mat, add):
    """The `glass_film` scene's objects; its world. Films on glass in a white world, seen
    against a black floor and backdrop, so a sphere shows what its film reflects of the sky
    beside what it lets through of the black: a Principled glass under 400 nm of IOR 1.33, a
    soap bubble (a Principled BSDF of IOR 1, Transmission 1, under 500 nm of IOR 1.33) and a
    Glass BSDF of roughness 0.1 under 300 nm of IOR 1.45. Black, not dark, so that what a
    sphere shows is its film and the sky alone. (A dark floor read 3-5% brighter in Tessera
    than in Cycles while Cycles' Filter Glossy was on; with it off, as `render` sets it, a
    floor of 0.2 beside clear glass agrees to 0.1%.)"""
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.0, 0.0, 0.0)), 0, size=20)
    add(bpy.ops.mesh.primitive_plane_add, mat("backdrop", (0.0, 0.0, 0.0)), 0, size=20, location=(0, 4, 0), rotation=(1.5708, 0, 0))
    for index, x, ior, nm, film_ior in ((2, -2.2, 1.5, 400.0, 1.33), (3, 0.0, 1.0, 500.0, 1.33)):
        m = mat(f"glass film {index}", (1.0, 1.0, 1.0), rough=0.0, trans=1.0)
        p = m.node_tree.nodes["Principled BSDF"]
        p.inputs["IOR"].default_value = ior
        p.inputs["Thin Film Thickness"].default_value, p.inputs["Thin Film IOR"].default_value = nm, film_ior
        add(bpy.ops.mesh.primitive_uv_sphere_add, m, index, radius=1.0, location=(x, 0, 1.0), segments=64, ring_count=32)
    m = _standalone_material("glass_bsdf_film", "ShaderNodeBsdfGlass", Roughness=0.1, IOR=1.5)
    glass = next(n for n in m.node_tree.nodes if n.type == "BSDF_GLASS")
    glass.inputs["Thin Film Thickness"].default_value, glass.inputs["Thin Film IOR"].default_value = 300.0, 1.45
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 4, radius=1.0, location=(2.2, 0, 1.0), segments=64, ring_count=32)
    world = bpy.data.worlds.new("white")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (1, 1, 1, 1)
    return world


def _box_scene(kind, scene, directory, mat, add):
    add(bpy.ops.mesh.primitive_plane_add, mat("white", (0.8, 0.8, 0.8)), 1, size=4)
    add(bpy.ops.mesh.primitive_plane_add, mat("red", (0.8, 0.1, 0.1)), 2, size=4, location=(-2, 0, 2), rotation=(0, 1.5708, 0))
    add(bpy.ops.mesh.primitive_plane_add, mat("green", (0.1, 0.8, 0.1)), 3, size=4, location=(2, 0, 2), rotation=(0, 1.5708, 0))
    add(bpy.ops.mesh.primitive_plane_add, mat("back", (0.8, 0.8, 0.8)), 4, size=4, location=(0, 2, 2), rotation=(1.5708, 0, 0))
    add(bpy.ops.mesh.primitive_uv_sphere_add, mat("metal", (0.9, 0.6, 0.3), rough=0.4, metal=1.0), 5, radius=0.7, location=(0, 0.3, 0.7), segments=64, ring_count=32)
    bpy.ops.object.light_add(type='AREA', location=(0, 0, 3.9)); l = bpy.context.object.data; l.energy = 200; l.size = 1
    cam = (0, -7, 2); rot = (1.5708, 0, 0)
    return cam, rot, None


def _hair_scene(kind, scene, directory, mat, add):
    # Two patches of hair curves (exported as BasisCurves) whose Principled Hair BSDFs the
    # add-on writes as tessera:Hair: by melanin, and by colour (direct colouring).
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=20)
    hair_patch(2, -0.9, parametrization="MELANIN", Melanin=0.3)
    hair_patch(3, 0.9, parametrization="COLOR", Color=(0.6, 0.3, 0.1, 1))
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.5, 0.2, 0)); bpy.context.object.data.energy = 3
    # Light hair scatters many times between fibres, where the two renderers' budgets part
    # (Tessera's counts every event, Cycles' each kind apart): at 8 the coloured hair read
    # 0.883, at 32 in both 0.985 (`render` reads this).
    scene["bounces"] = 32
    cam = (0, -5, 1.6); rot = (1.35, 0, 0)
    return cam, rot, None


def _coats_scene(kind, scene, directory, mat, add):
    # A Principled BSDF's orange-tinted coat, which UsdPreviewSurface cannot hold, over a
    # grey Lambertian base (IOR 1): written as tessera:SolidDielectric's clearcoat.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=20)
    m = mat("tinted coat", (0.6, 0.6, 0.6))
    for name, value in {"Coat Weight": 1.0, "Coat Roughness": 0.1, "Coat Tint": (0.9, 0.5, 0.2, 1)}.items():
        m.node_tree.nodes["Principled BSDF"].inputs[name].default_value = value
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 2, radius=1.0, location=(0, 0, 1.0), segments=64, ring_count=32)
    # Behind it, the same coat over a silver metal: tessera:Metal's clearcoat.
    m = mat("tinted coat metal", (0.9, 0.9, 0.9), rough=0.3, metal=1.0)
    for name, value in {"Coat Weight": 1.0, "Coat Roughness": 0.1, "Coat Tint": (0.9, 0.5, 0.2, 1)}.items():
        m.node_tree.nodes["Principled BSDF"].inputs[name].default_value = value
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 3, radius=1.0, location=(2.4, 2.5, 1.0), segments=64, ring_count=32)
    # Beside it, a silver metal whose Coat Tint is a Checker of orange and white: baked.
    scene.tessera.bake_size = 256
    m = mat("checkered coat metal", (0.9, 0.9, 0.9), rough=0.3, metal=1.0)
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Coat Weight"].default_value, p.inputs["Coat Roughness"].default_value = 1.0, 0.1
    checker = _node(m.node_tree, "ShaderNodeTexChecker", Scale=2.0, Color1=(0.9, 0.5, 0.2, 1), Color2=(1.0, 1.0, 1.0, 1))
    m.node_tree.links.new(checker.outputs["Color"], p.inputs["Coat Tint"])
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 4, radius=1.0, location=(-2.4, 2.5, 1.0), segments=64, ring_count=32)
    # In front, an untinted coat of IOR 1.8 over grey: tessera:SolidDielectric's clear coat.
    m = mat("untinted coat", (0.6, 0.6, 0.6))
    for name, value in {"Coat Weight": 1.0, "Coat Roughness": 0.1, "Coat IOR": 1.8}.items():
        m.node_tree.nodes["Principled BSDF"].inputs[name].default_value = value
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 5, radius=0.5, location=(-1.5, -1.8, 0.5), segments=64, ring_count=32)
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.5, 0.2, 0)); bpy.context.object.data.energy = 3
    cam = (0, -7, 2.2); rot = (1.3, 0, 0)
    return cam, rot, None


def _rough_diffuse_scene(kind, scene, directory, mat, add):
    # Oren-Nayar at roughness 1 (energy-preserving in both): a Principled BSDF's Diffuse
    # Roughness and a Diffuse BSDF's Roughness, lit by a sun from behind the camera, where
    # rough facets send light back and a Lambertian sphere would read darker.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=20)
    m = mat("rough principled", (0.8, 0.8, 0.8))
    m.node_tree.nodes["Principled BSDF"].inputs["Diffuse Roughness"].default_value = 1.0
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 2, radius=1.0, location=(-1.2, 0, 1.0), segments=64, ring_count=32)
    d = _standalone_material("rough diffuse", "ShaderNodeBsdfDiffuse", Color=(0.8, 0.8, 0.8, 1), Roughness=1.0)
    add(bpy.ops.mesh.primitive_uv_sphere_add, d, 3, radius=1.0, location=(1.2, 0, 1.0), segments=64, ring_count=32)
    # Behind them, Diffuse Roughness from a Checker (0 and 1): baked, as any linked input,
    # at 256² (the checker's 4 × 4 squares need no more).
    scene.tessera.bake_size = 256
    m = _checkered(mat("checkered rough", (0.8, 0.8, 0.8)), "Diffuse Roughness")
    add(bpy.ops.mesh.primitive_uv_sphere_add, m, 4, radius=1.0, location=(0, 2.5, 1.0), segments=64, ring_count=32)
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(1.1, 0, 0)); bpy.context.object.data.energy = 3
    cam = (0, -7, 2.2); rot = (1.3, 0, 0)
    return cam, rot, None


def _sheen_scene(kind, scene, directory, mat, add):
    world = _sheen_spheres(mat, add, scene)
    cam = (0, -7, 2.2); rot = (1.3, 0, 0)
    return cam, rot, world


def _anisotropic_scene(kind, scene, directory, mat, add):
    world = _anisotropic_objects(mat, add, scene)
    cam = (0, -7, 2.2); rot = (1.3, 0, 0)
    return cam, rot, world


def _thin_film_scene(kind, scene, directory, mat, add):
    world = _thin_film_spheres(mat, add)
    cam = (0, -7, 2.2); rot = (1.3, 0, 0)
    return cam, rot, world


def _glass_film_scene(kind, scene, directory, mat, add):
    world = _glass_film_spheres(mat, add)
    cam = (0, -7, 2.2); rot = (1.3, 0, 0)
    return cam, rot, world


def _shaders_scene(kind, scene, directory, mat, add):
    shader_spheres_and_cutouts(mat, add, directory)
    # The `glass` scene's sun: lower, the glass sphere's shadow holds a caustic, which
    # neither renderer converges on at these samples.
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.5, 0.2, 0)); bpy.context.object.data.energy = 3
    cam = (0, -8, 3); rot = (1.2, 0, 0)
    return cam, rot, None


def _glass_scene(kind, scene, directory, mat, add):
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.7, 0.7, 0.7)), 1, size=20)
    add(bpy.ops.mesh.primitive_uv_sphere_add, mat("glass", (1, 1, 1), rough=0.0, trans=1.0), 2, radius=1, location=(0, 0, 1), segments=64, ring_count=32)
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.5, 0.2, 0)); bpy.context.object.data.energy = 3
    cam = (0, -8, 3); rot = (1.2, 0, 0)
    return cam, rot, None


def _linked_scene(kind, scene, directory, mat, add):
    # Light linking: the key reaches the left sphere alone (its receiver collection
    # includes it); the right sphere casts none of the fill's shadows (excluded from the
    # fill's blocker collection).
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=8)
    left = add(bpy.ops.mesh.primitive_uv_sphere_add, mat("left", (0.8, 0.8, 0.8)), 2, radius=0.7, location=(-1.2, 0, 0.7), segments=64, ring_count=32)
    right = add(bpy.ops.mesh.primitive_uv_sphere_add, mat("right", (0.8, 0.8, 0.8)), 3, radius=0.7, location=(1.2, 0, 0.7), segments=64, ring_count=32)
    bpy.ops.object.light_add(type='AREA', location=(0, 0, 3)); key = bpy.context.object; key.data.energy = 300; key.data.size = 1
    receivers = bpy.data.collections.new("key receivers"); receivers.objects.link(left)
    key.light_linking.receiver_collection = receivers
    bpy.ops.object.light_add(type='POINT', location=(2.5, -1, 2.5)); fill = bpy.context.object; fill.data.energy = 200; fill.data.shadow_soft_size = 0.2
    blockers = bpy.data.collections.new("fill blockers"); blockers.objects.link(right)
    blockers.collection_objects[0].light_linking.link_state = 'EXCLUDE'
    fill.light_linking.blocker_collection = blockers
    cam = (0, -7, 2.5); rot = (1.25, 0, 0)
    return cam, rot, None


def _emitter_linked_scene(kind, scene, directory, mat, add):
    # An emissive object's own light linking: the panel lights the left sphere alone (its
    # receiver collection); a dim point light reaches everything, so no region is black.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=8)
    left = add(bpy.ops.mesh.primitive_uv_sphere_add, mat("left", (0.8, 0.8, 0.8)), 2, radius=0.7, location=(-1.2, 0, 0.7), segments=64, ring_count=32)
    add(bpy.ops.mesh.primitive_uv_sphere_add, mat("right", (0.8, 0.8, 0.8)), 3, radius=0.7, location=(1.2, 0, 0.7), segments=64, ring_count=32)
    glow = mat("glow", (0.0, 0.0, 0.0))
    p = glow.node_tree.nodes["Principled BSDF"]
    p.inputs["Emission Color"].default_value = (1.0, 0.9, 0.8, 1)
    p.inputs["Emission Strength"].default_value = 20.0
    panel = add(bpy.ops.mesh.primitive_plane_add, glow, 0, size=1, location=(-1.2, 0, 2.6), rotation=(3.14159, 0, 0))
    panel.name = "Panel"
    receivers = bpy.data.collections.new("panel receivers"); receivers.objects.link(left)
    panel.light_linking.receiver_collection = receivers
    bpy.ops.object.light_add(type='POINT', location=(2.5, -1, 2.5)); fill = bpy.context.object.data; fill.energy = 100; fill.shadow_soft_size = 0.2
    cam = (0, -7, 2.5); rot = (1.25, 0, 0)
    return cam, rot, None


def _udim_scene(kind, scene, directory, mat, add):
    # One material over a UDIM set; the left plane's UVs lie in tile 1001, the right
    # plane's in tile 1002, so each region shows one tile's colour (Lambertian, IOR 1).
    m = mat("tiles", (1, 1, 1))
    t = m.node_tree.nodes.new("ShaderNodeTexImage"); t.image = udim_image(directory)
    m.node_tree.links.new(t.outputs["Color"], m.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    for index, x in ((1, -1.05), (2, 1.05)):
        plane = add(bpy.ops.mesh.primitive_plane_add, m, index, size=2, location=(x, 0, 0))
        for loop in plane.data.uv_layers.active.data:
            loop.uv.x += index - 1
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.3, 0.2, 0)); bpy.context.object.data.energy = 3
    cam = (0, -5, 4); rot = (0.9, 0, 0)
    return cam, rot, None


def _subsurface_scene(kind, scene, directory, mat, add):
    # Random-walk subsurface scattering (Cycles' default method) behind a rough boundary
    # of IOR 1.4, all of the base on the left sphere and half of it on the right; the mean
    # free path (Blender's default radius × 0.05) is 0.05 in red, a fourteenth of the
    # spheres' radius, and a fifth and a tenth of that in green and blue.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=8)
    for index, x, weight in ((2, -1.0, 1.0), (3, 1.0, 0.5)):
        skin = mat(f"skin{index}", (0.8, 0.45, 0.3), rough=0.4)
        p = skin.node_tree.nodes["Principled BSDF"]
        p.inputs["IOR"].default_value = 1.4
        p.inputs["Subsurface Weight"].default_value = weight
        p.inputs["Subsurface Scale"].default_value = 0.05
        add(bpy.ops.mesh.primitive_uv_sphere_add, skin, index, radius=0.7, location=(x, 0, 0.7), segments=64, ring_count=32)
    # A large light in front: a small one lights a medium through its rough boundary as
    # fireflies in both renderers.
    bpy.ops.object.light_add(type='AREA', location=(0, -2.5, 3.5), rotation=(0.6, 0, 0)); key = bpy.context.object.data; key.energy = 800; key.size = 3
    cam = (0, -6, 2.2); rot = (1.3, 0, 0)
    return cam, rot, None


def _displaced_scene(kind, scene, directory, mat, add):
    # True displacement (Displacement Only) on a smooth-shaded grid just above the floor: a
    # height map (raw) whose middle quarter is 1 raises a block 0.6 high, which shades the
    # floor under a low sun. A plane behind the camera asks for Bump Only, which the export
    # drops with a warning.
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=8)
    path = os.path.join(directory, "height.png")
    img = bpy.data.images.new("height", 64, 64)
    px = np.zeros((64, 64, 4), np.float32); px[..., 3] = 1; px[16:48, 16:48, :3] = 1
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = path; img.file_format = 'PNG'; img.save()
    for name, method, index, location in (("block", 'DISPLACEMENT', 2, (0, 0, 0.002)), ("bumps", 'BUMP', 0, (0, -9, 0))):
        m = mat(name, (0.8, 0.8, 0.8))
        m.displacement_method = method
        t = m.node_tree.nodes.new("ShaderNodeTexImage"); t.image = bpy.data.images.load(path)
        t.image.colorspace_settings.name = 'Non-Color'
        d = m.node_tree.nodes.new("ShaderNodeDisplacement")
        d.inputs["Scale"].default_value, d.inputs["Midlevel"].default_value = 0.6, 0.0
        m.node_tree.links.new(t.outputs["Color"], d.inputs["Height"])
        m.node_tree.links.new(d.outputs["Displacement"], m.node_tree.nodes["Material Output"].inputs["Displacement"])
        add(bpy.ops.mesh.primitive_grid_add, m, index, x_subdivisions=96, y_subdivisions=96, size=2, location=location)
        bpy.ops.object.shade_smooth()
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.8, 0.5, 0)); bpy.context.object.data.energy = 3
    cam = (0, -5, 4); rot = (0.9, 0, 0)
    return cam, rot, None


def _bumped_scene(kind, scene, directory, mat, add):
    # A height ramp along u (256 columns, code x at column x, Non-Color) bumps one plane
    # through a Bump node (Distance 0.5) and another through Bump Only displacement (Scale
    # 0.5): both lean 14° away from +x, towards which the sun (30° off the zenith) does not
    # lie, so they read about 17% darker than the flat plane between them.
    path = os.path.join(directory, "ramp.png")
    img = bpy.data.images.new("ramp", 256, 256)
    px = np.zeros((256, 256, 4), np.float32); px[..., 3] = 1; px[..., :3] = (np.arange(256, dtype=np.float32) / 255.0)[None, :, None]
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = path; img.file_format = 'PNG'; img.save()
    ramp = bpy.data.images.load(path); ramp.colorspace_settings.name = 'Non-Color'
    node_bump = mat("bump node", (0.8, 0.8, 0.8))
    tree = node_bump.node_tree
    t = tree.nodes.new("ShaderNodeTexImage"); t.image = ramp; t.extension = 'EXTEND'
    b = tree.nodes.new("ShaderNodeBump"); b.inputs["Distance"].default_value = 0.5
    tree.links.new(t.outputs["Color"], b.inputs["Height"]); tree.links.new(b.outputs["Normal"], tree.nodes["Principled BSDF"].inputs["Normal"])
    add(bpy.ops.mesh.primitive_plane_add, node_bump, 1, size=2, location=(-2.2, 0, 0))
    bump_only = mat("bump only", (0.8, 0.8, 0.8))
    bump_only.displacement_method = 'BUMP'
    tree = bump_only.node_tree
    t = tree.nodes.new("ShaderNodeTexImage"); t.image = ramp; t.extension = 'EXTEND'
    d = tree.nodes.new("ShaderNodeDisplacement")
    d.inputs["Scale"].default_value, d.inputs["Midlevel"].default_value = 0.5, 0.0
    tree.links.new(t.outputs["Color"], d.inputs["Height"]); tree.links.new(d.outputs["Displacement"], tree.nodes["Material Output"].inputs["Displacement"])
    add(bpy.ops.mesh.primitive_plane_add, bump_only, 2, size=2, location=(2.2, 0, 0))
    add(bpy.ops.mesh.primitive_plane_add, mat("flat", (0.8, 0.8, 0.8)), 3, size=2, location=(0, 0, 0))
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0, 0.5236, 0)); bpy.context.object.data.energy = 3
    cam = (0, -6, 5); rot = (0.9, 0, 0)
    return cam, rot, None


def _mixed_scene(kind, scene, directory, mat, add):
    # Mix Shaders (Lambertian sides, IOR 1): red Principled and blue Diffuse BSDF at Fac 0.3;
    # green and white Principled BSDFs by an image mask, black on its left half and white
    # on its right (Non-Color).
    def principled(tree, color):
        p = tree.nodes.new("ShaderNodeBsdfPrincipled")
        p.inputs["Base Color"].default_value = (*color, 1); p.inputs["IOR"].default_value = 1.0
        return p
    m = bpy.data.materials.new("constant mix")
    tree = m.node_tree
    red = tree.nodes["Principled BSDF"]; red.inputs["Base Color"].default_value = (0.8, 0.1, 0.1, 1); red.inputs["IOR"].default_value = 1.0
    blue = tree.nodes.new("ShaderNodeBsdfDiffuse"); blue.inputs["Color"].default_value = (0.1, 0.1, 0.8, 1)
    node = tree.nodes.new("ShaderNodeMixShader"); node.inputs["Fac"].default_value = 0.3
    tree.links.new(red.outputs[0], node.inputs[1]); tree.links.new(blue.outputs[0], node.inputs[2])
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    add(bpy.ops.mesh.primitive_plane_add, m, 1, size=2, location=(-1.1, 0, 0))
    path = os.path.join(directory, "half.png")
    img = bpy.data.images.new("half", 64, 64)
    px = np.zeros((64, 64, 4), np.float32); px[..., 3] = 1; px[:, 32:, :3] = 1
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = path; img.file_format = 'PNG'; img.save()
    mask = bpy.data.images.load(path); mask.colorspace_settings.name = 'Non-Color'
    m = bpy.data.materials.new("masked mix")
    tree = m.node_tree
    green = tree.nodes["Principled BSDF"]; green.inputs["Base Color"].default_value = (0.1, 0.7, 0.1, 1); green.inputs["IOR"].default_value = 1.0
    white = principled(tree, (0.8, 0.8, 0.8))
    node = tree.nodes.new("ShaderNodeMixShader")
    t = tree.nodes.new("ShaderNodeTexImage"); t.image = mask
    tree.links.new(t.outputs["Color"], node.inputs["Fac"])
    tree.links.new(green.outputs[0], node.inputs[1]); tree.links.new(white.outputs[0], node.inputs[2])
    tree.links.new(node.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    add(bpy.ops.mesh.primitive_plane_add, m, 2, size=2, location=(1.1, 0, 0))
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.3, 0.2, 0)); bpy.context.object.data.energy = 3
    cam = (0, -5, 4); rot = (0.9, 0, 0)
    return cam, rot, None


def _spot_scene(kind, scene, directory, mat, add):
    # One spot light straight down, a wide blend: its falloff decides how much light lands.
    # Radius 0, Blender 5's default: a point light in Tessera (the `linked` scene's spot
    # has a radius).
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=10)
    bpy.ops.object.light_add(type='SPOT', location=(0, 0, 3)); s = bpy.context.object.data
    s.energy, s.spot_size, s.spot_blend, s.shadow_soft_size = 300, 1.2, 0.6, 0.0
    cam = (0, -6, 5); rot = (0.9, 0, 0)
    return cam, rot, None


def _world_scene(kind, scene, directory, mat, add):
    add(bpy.ops.mesh.primitive_plane_add, mat("floor", (0.8, 0.8, 0.8)), 1, size=8)
    add(bpy.ops.mesh.primitive_uv_sphere_add, mat("sphere", (0.8, 0.8, 0.8)), 2, radius=0.7, location=(0, 0, 0.7), segments=64, ring_count=32)
    world = {"world": lambda: hdri_world(directory), "procedural_world": direction_world, "sky_world": sky_world}[kind]()
    cam = (0, -7, 2.5); rot = (1.25, 0, 0)
    return cam, rot, world


def _procedural_scene(kind, scene, directory, mat, add):
    procedural_planes(mat, add, directory)
    bpy.ops.object.light_add(type='SUN', location=(0, 0, 5), rotation=(0.3, 0.2, 0)); bpy.context.object.data.energy = 3
    cam = (0, -6, 5); rot = (0.9, 0, 0)
    return cam, rot, None


def _emission_shader_scene(kind, scene, directory, mat, add):
    # Lit by a panel whose surface is an Emission shader alone (which Blender's USD export
    # drops) over a floor whose surface is a Diffuse BSDF (exported with a specular layer).
    floor = bpy.data.materials.new("diffuse floor")
    tree = floor.node_tree
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse"); diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1)
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    tree.links.new(diffuse.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    add(bpy.ops.mesh.primitive_plane_add, floor, 1, size=8)
    add(bpy.ops.mesh.primitive_uv_sphere_add, mat("sphere", (0.8, 0.8, 0.8)), 2, radius=0.7, location=(0, 0, 0.7), segments=64, ring_count=32)
    glow = bpy.data.materials.new("glow")
    tree = glow.node_tree
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Color"].default_value = (1.0, 0.9, 0.8, 1); emission.inputs["Strength"].default_value = 15.0
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    tree.links.new(emission.outputs[0], tree.nodes["Material Output"].inputs["Surface"])
    add(bpy.ops.mesh.primitive_plane_add, glow, 0, size=1.5, location=(0.8, -0.5, 2.6), rotation=(3.14159, 0, 0))
    cam = (0, -7, 2.5); rot = (1.25, 0, 0)
    return cam, rot, None


def _textured_scene(kind, scene, directory, mat, add):
    checker = os.path.join(directory, "checker.png")
    img = bpy.data.images.new("checker", 64, 64)
    px = np.zeros((64, 64, 4), np.float32); px[..., 3] = 1
    px[(np.add.outer(np.arange(64) // 8, np.arange(64) // 8) % 2) == 0, :3] = (0.8, 0.7, 0.2)
    px[(np.add.outer(np.arange(64) // 8, np.arange(64) // 8) % 2) == 1, :3] = (0.1, 0.2, 0.6)
    img.pixels.foreach_set(px.ravel()); img.filepath_raw = checker; img.file_format = 'PNG'; img.save()
    m = mat("tex", (1, 1, 1), rough=0.6)
    t = m.node_tree.nodes.new("ShaderNodeTexImage"); t.image = bpy.data.images.load(checker)
    m.node_tree.links.new(t.outputs["Color"], m.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    add(bpy.ops.mesh.primitive_plane_add, m, 1, size=6)
    bpy.ops.object.light_add(type='POINT', location=(1.5, -1, 2)); bpy.context.object.data.energy = 300; bpy.context.object.data.shadow_soft_size = 0.1
    bpy.ops.object.light_add(type='SPOT', location=(-1.5, 0, 3)); s = bpy.context.object.data; s.energy = 500; s.spot_size = 1.0; s.spot_blend = 0.2; s.shadow_soft_size = 0.1
    cam = (0, -6, 5); rot = (0.9, 0, 0)
    return cam, rot, None


#: Each kind's scene (a key of REGIONS): a function of (kind, scene, directory, mat, add),
#: `mat` and `add` being `build`'s, that adds the objects and lights and returns the camera's
#: location and rotation and the world (None: Blender's empty one).
SCENES = {
    "box": _box_scene,
    "box_matte": _box_scene,
    "hair": _hair_scene,
    "coats": _coats_scene,
    "rough_diffuse": _rough_diffuse_scene,
    "sheen": _sheen_scene,
    "anisotropic": _anisotropic_scene,
    "thin_film": _thin_film_scene,
    "glass_film": _glass_film_scene,
    "shaders": _shaders_scene,
    "glass": _glass_scene,
    "linked": _linked_scene,
    "emitter_linked": _emitter_linked_scene,
    "udim": _udim_scene,
    "subsurface": _subsurface_scene,
    "displaced": _displaced_scene,
    "bumped": _bumped_scene,
    "mixed": _mixed_scene,
    "spot": _spot_scene,
    "world": _world_scene,
    "procedural_world": _world_scene,
    "sky_world": _world_scene,
    "procedural": _procedural_scene,
    "emission_shader": _emission_shader_scene,
    "textured": _textured_scene,
}


#: Scene kinds whose non-metal Principled BSDFs get IOR 1 (no specular layer: Lambertian
#: in both renderers).
LAMBERTIAN_KINDS = ("box_matte", "linked", "emitter_linked", "udim", "subsurface", "displaced", "emission_shader", "bumped", "mixed", "procedural", "world", "procedural_world", "sky_world", "spot", "shaders", "coats", "rough_diffuse", "sheen", "anisotropic", "thin_film", "glass_film", "hair")


def build(kind, directory):
    """A fresh scene of `kind` (a key of REGIONS); files it needs go in `directory`."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    def mat(name, color, rough=0.5, metal=0.0, trans=0.0):
        m = bpy.data.materials.new(name)
        p = m.node_tree.nodes["Principled BSDF"]
        p.inputs["Base Color"].default_value = (*color, 1)
        p.inputs["Roughness"].default_value = rough
        p.inputs["Metallic"].default_value = metal
        p.inputs["Transmission Weight"].default_value = trans
        if kind in LAMBERTIAN_KINDS and metal == 0.0:
            # IOR 1: no specular layer, so the walls are Lambertian in both renderers.
            p.inputs["IOR"].default_value = 1.0
        return m
    def add(op, mat_, index, **kw):
        op(**kw); o = bpy.context.object; o.pass_index = index
        if mat_: o.data.materials.append(mat_)
        return o
    cam, rot, world = SCENES[kind](kind, scene, directory, mat, add)
    bpy.ops.object.camera_add(location=cam, rotation=rot); scene.camera = bpy.context.object
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 96, 72, 100
    scene.view_settings.view_transform = 'Standard'
    scene.render.image_settings.media_type = 'MULTI_LAYER_IMAGE'
    scene.render.image_settings.file_format = 'OPEN_EXR_MULTILAYER'
    scene.render.image_settings.color_depth = '32'
    scene.world = world
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    return scene

def render(scene, engine, path, spp):
    """Renders with `engine` ('TESSERA' or 'CYCLES') at `spp` to a linear multilayer EXR."""
    scene.render.engine = engine
    # Tessera's max depth counts every scattering event; Cycles limits each kind too. 8 unless
    # the scene asks for more.
    bounces = scene.get("bounces", 8)
    if engine == "CYCLES":
        c = scene.cycles
        c.samples, c.use_denoising, c.device, c.use_adaptive_sampling = spp, False, "CPU", False
        c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
        # Filter Glossy (on by default at 1.0) roughens glossy and glass lobes a path meets
        # after a diffuse bounce, a bias Tessera has no counterpart of: left on, a dark floor
        # beside clear glass spheres in a white world read 3.6% darker in Cycles (1.000 off).
        c.blur_glossy = 0.0
        c.sample_clamp_indirect = 0.0
    else:
        scene.tessera.samples, scene.tessera.max_depth = spp, bounces
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def ngon_tangent(tree, p):
    """`node_trees`' anisotropy along a UV map's tangents on a disk of one 32-cornered face,
    which Blender's MikkTSpace cannot take: said, with the mesh."""
    p.inputs["Anisotropic"].default_value = 0.5
    t = tree.nodes.new("ShaderNodeTangent"); t.direction_type = "UV_MAP"
    tree.links.new(t.outputs[0], p.inputs["Tangent"])


def geometry_tangent(tree, p):
    """`node_trees`' anisotropy along a Geometry node's Tangent: Cycles' default tangent, carried."""
    p.inputs["Anisotropic"].default_value = 0.5
    tree.links.new(tree.nodes.new("ShaderNodeNewGeometry").outputs["Tangent"], p.inputs["Tangent"])


def combined_tangent(tree, p):
    """`node_trees`' anisotropy along a vector built by a Combine XYZ, which the add-on does not
    write: said."""
    p.inputs["Anisotropic"].default_value = 0.5
    tree.links.new(tree.nodes.new("ShaderNodeCombineXYZ").outputs[0], p.inputs["Tangent"])


def node_trees(directory):
    """One plane per node set-up Blender's USD export translates, or does not, each material
    named for its case (docs/blender.md): the add-on must correct or report each."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    image = bpy.data.images.new("plain", 8, 8)
    image.filepath_raw = os.path.join(directory, "plain.png"); image.file_format = 'PNG'; image.save()

    def texture(tree):
        t = tree.nodes.new("ShaderNodeTexImage"); t.image = image
        return t

    def link(tree, a, b):
        tree.links.new(a, b)

    def ramp(tree, p):
        r = tree.nodes.new("ShaderNodeValToRGB")
        link(tree, texture(tree).outputs["Color"], r.inputs["Fac"]); link(tree, r.outputs["Color"], p.inputs["Base Color"])

    def math(tree, p):
        m = tree.nodes.new("ShaderNodeMath"); m.operation = 'MULTIPLY'
        link(tree, texture(tree).outputs["Alpha"], m.inputs[0]); link(tree, m.outputs[0], p.inputs["Roughness"])

    def bump(tree, p):
        b = tree.nodes.new("ShaderNodeBump")
        link(tree, texture(tree).outputs["Alpha"], b.inputs["Height"]); link(tree, b.outputs[0], p.inputs["Normal"])

    def ramp_bump(tree, p):
        r = tree.nodes.new("ShaderNodeValToRGB"); b = tree.nodes.new("ShaderNodeBump")
        link(tree, texture(tree).outputs["Alpha"], r.inputs["Fac"]); link(tree, r.outputs["Alpha"], b.inputs["Height"])
        link(tree, b.outputs[0], p.inputs["Normal"])

    def normal_map(tree, p):
        n = tree.nodes.new("ShaderNodeNormalMap"); n.inputs["Strength"].default_value = 0.5
        t = tree.nodes.new("ShaderNodeTexImage"); t.image = bpy.data.images.load(image.filepath_raw, check_existing=False)
        t.image.colorspace_settings.name = 'Non-Color'  # as a normal map's image is
        link(tree, t.outputs["Color"], n.inputs["Color"]); link(tree, n.outputs[0], p.inputs["Normal"])

    def mapped(tree, p):
        m = tree.nodes.new("ShaderNodeMapping"); c = tree.nodes.new("ShaderNodeTexCoord"); t = texture(tree)
        link(tree, c.outputs["UV"], m.inputs["Vector"]); link(tree, m.outputs[0], t.inputs["Vector"])
        s = tree.nodes.new("ShaderNodeSeparateColor")
        link(tree, t.outputs["Color"], s.inputs["Color"]); link(tree, s.outputs["Green"], p.inputs["Roughness"])

    def rgb(tree, p):
        c = tree.nodes.new("ShaderNodeRGB"); c.outputs[0].default_value = (0, 1, 0, 1)
        link(tree, c.outputs[0], p.inputs["Base Color"])

    def mix_shader(tree, p):
        # A Principled and a Glossy BSDF: a tessera:Layer of the exported Principled and the
        # Glossy written as a metal (the `mixed` and `shaders` scenes measure such layers).
        m = tree.nodes.new("ShaderNodeMixShader"); d = tree.nodes.new("ShaderNodeBsdfGlossy")
        link(tree, p.outputs[0], m.inputs[1]); link(tree, d.outputs[0], m.inputs[2])
        link(tree, m.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    def glossy(tree, p):
        g = tree.nodes.new("ShaderNodeBsdfGlossy"); tree.nodes.remove(p)
        link(tree, g.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    def fresnel_mix(tree, p):
        # A Diffuse and a Glossy BSDF mixed by a Fresnel: its view dependence cannot be baked.
        m = tree.nodes.new("ShaderNodeMixShader"); f = tree.nodes.new("ShaderNodeFresnel")
        d, g = tree.nodes.new("ShaderNodeBsdfDiffuse"), tree.nodes.new("ShaderNodeBsdfGlossy"); tree.nodes.remove(p)
        link(tree, f.outputs[0], m.inputs["Fac"]); link(tree, d.outputs[0], m.inputs[1]); link(tree, g.outputs[0], m.inputs[2])
        link(tree, m.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    def toon(tree, p):
        # A Toon BSDF: not carried, said, the default surface rendered.
        t = tree.nodes.new("ShaderNodeBsdfToon"); tree.nodes.remove(p)
        link(tree, t.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    def beckmann_glass(tree, p):
        # A Glass BSDF (written as tessera:Principled glass) whose Beckmann lobe is rendered as GGX.
        g = tree.nodes.new("ShaderNodeBsdfGlass"); g.distribution = "BECKMANN"; tree.nodes.remove(p)
        link(tree, g.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    def add_glow(tree, p):
        e = tree.nodes.new("ShaderNodeEmission"); e.inputs["Color"].default_value = (1, 0.5, 0, 1); e.inputs["Strength"].default_value = 2.0
        a = tree.nodes.new("ShaderNodeAddShader")
        link(tree, p.outputs[0], a.inputs[0]); link(tree, e.outputs[0], a.inputs[1])
        link(tree, a.outputs[0], tree.nodes["Material Output"].inputs["Surface"])

    def no_uvs(tree, p):
        # A Noise on a plane whose UV map is removed below: baked over the add-on's own unwrap.
        n = tree.nodes.new("ShaderNodeTexNoise")
        link(tree, n.outputs["Color"], p.inputs["Base Color"])

    def render_levels(tree, p):
        # The same, on a plane subdivided once at render time only (below): the export writes
        # the render's mesh, which an unwrap in the viewport's cannot match, so it is said.
        no_uvs(tree, p)

    def sheen(tree, p):
        # On a half metal: the fuzz is carried on opaque dielectrics and full metals only (the
        # `sheen` scene's).
        p.inputs["Metallic"].default_value = 0.5
        p.inputs["Sheen Weight"].default_value = 0.5
        p.inputs["Coat Weight"].default_value = 0.0
        p.inputs["Coat Tint"].default_value = (1, 0, 0, 1)  # no coat: nothing to say of its tint

    cases = (ramp, math, bump, ramp_bump, normal_map, mapped, rgb, mix_shader, glossy, toon, beckmann_glass, fresnel_mix, add_glow, no_uvs, render_levels, sheen, ngon_tangent, geometry_tangent, combined_tangent)
    for x, case in enumerate(cases):
        m = bpy.data.materials.new(case.__name__)
        case(m.node_tree, m.node_tree.nodes["Principled BSDF"])
        if case is ngon_tangent:
            bpy.ops.mesh.primitive_circle_add(vertices=32, fill_type="NGON", location=(3 * x, 0, 0))
        else:
            bpy.ops.mesh.primitive_plane_add(location=(3 * x, 0, 0))
        bpy.context.object.data.materials.append(m)
        if case in (no_uvs, render_levels):
            bpy.context.object.data.uv_layers.remove(bpy.context.object.data.uv_layers[0])
        if case is render_levels:
            # Not the last modifier, so the export applies it rather than writing a scheme.
            subdivision = bpy.context.object.modifiers.new("Subdivision", "SUBSURF")
            subdivision.levels, subdivision.render_levels = 0, 1
            bpy.context.object.modifiers.new("Weld", "WELD")
    return bpy.context.scene
