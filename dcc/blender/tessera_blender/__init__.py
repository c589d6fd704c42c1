"""Tessera for Blender: a render engine that renders through a Tessera server.

Final renders export the evaluated scene with Blender's USD exporter (corrected where it
departs from Cycles, see ``export.py``), sync it to a session and write the streamed tiles
into the render result. The viewport keeps a session and sends edits as deltas.
"""

import bpy

from . import engine

# Panels of Blender's own UI that work for any engine that uses its shading nodes.
_COMPAT_PANELS = [
    "RENDER_PT_format",
    "RENDER_PT_dimensions",
    "RENDER_PT_output",
    "RENDER_PT_color_management",
    "VIEWLAYER_PT_layer_passes",
    "DATA_PT_light",
    "DATA_PT_lens",
    "DATA_PT_camera",
    "MATERIAL_PT_preview",
    "EEVEE_MATERIAL_PT_surface",
]


class TesseraPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    server_url: bpy.props.StringProperty(
        name="Server URL",
        description="Tessera render server (http://host:port or https://); empty starts one inside Blender",
        default="",
    )
    token: bpy.props.StringProperty(name="Token", description="Bearer token for the server", default="", subtype="PASSWORD")

    def draw(self, context):
        self.layout.prop(self, "server_url")
        self.layout.prop(self, "token")


class TesseraSceneSettings(bpy.types.PropertyGroup):
    samples: bpy.props.IntProperty(name="Samples", description="Samples per pixel", default=64, min=1, max=1 << 20)
    max_depth: bpy.props.IntProperty(name="Max Depth", description="Scattering events per path", default=8, min=1, max=1024)
    noise_threshold: bpy.props.FloatProperty(
        name="Noise Threshold",
        description="Adaptive sampling target (relative standard error); 0 is off",
        default=0.0,
        min=0.0,
        max=1.0,
        precision=4,
    )
    caustics: bpy.props.EnumProperty(
        name="Caustics",
        items=[("FULL", "Full", "Unbiased path tracing"), ("AVOID", "Avoid", "Imageworks' caustic avoidance: biased, far less noisy")],
        default="FULL",
    )
    clamp: bpy.props.FloatProperty(name="Clamp Indirect", description="Firefly clamp; 0 is off", default=0.0, min=0.0)
    energy_compensation: bpy.props.BoolProperty(
        name="Energy Compensation", description="Kulla-Conty multiple scattering in rough microfacets", default=True
    )
    animate_seed: bpy.props.BoolProperty(name="Animate Seed", description="Use the frame number as the seed", default=False)
    denoise: bpy.props.BoolProperty(
        name="Denoise",
        description="Open Image Denoise on the final render (pip install pyoidn); the raw image goes to the Noisy Image pass",
        default=False,
    )
    bake_size: bpy.props.IntProperty(
        name="Bake Size",
        description="Texels along each side of the images procedural inputs are baked into",
        default=1024,
        min=16,
        max=8192,
    )


class TESSERA_PT_sampling(bpy.types.Panel):
    bl_label = "Tessera"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {"TESSERA"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        settings = context.scene.tessera
        layout = self.layout
        layout.use_property_split = True
        for prop in ("samples", "max_depth", "noise_threshold", "caustics", "clamp", "energy_compensation", "animate_seed", "denoise", "bake_size"):
            layout.prop(settings, prop)


_CLASSES = [TesseraPreferences, TesseraSceneSettings, TESSERA_PT_sampling, engine.TesseraRenderEngine]


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.tessera = bpy.props.PointerProperty(type=TesseraSceneSettings)
    for name in _COMPAT_PANELS:
        panel = getattr(bpy.types, name, None)
        if panel is not None and hasattr(panel, "COMPAT_ENGINES"):
            panel.COMPAT_ENGINES.add("TESSERA")


def unregister():
    for name in _COMPAT_PANELS:
        panel = getattr(bpy.types, name, None)
        if panel is not None and hasattr(panel, "COMPAT_ENGINES"):
            panel.COMPAT_ENGINES.discard("TESSERA")
    del bpy.types.Scene.tessera
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
