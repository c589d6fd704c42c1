"""Viewport rendering: one session per viewport, kept for its lifetime. The first update
exports and syncs the scene and starts one long progressive render; every later edit goes
as deltas (moved objects and the view as transforms, other changes as a re-export whose
``sync_usd`` sends only the prims that changed). The server restarts the render on each
edit, coarse passes first, and ``view_draw`` draws whatever arrived last.
"""

from __future__ import annotations

import threading

import numpy as np

from . import engine as _engine
from . import export

#: Samples per pixel a viewport converges to.
VIEWPORT_SPP = 1024
#: Block edge of the coarse passes after each edit (see RenderSettings.coarse_start).
COARSE_START = 8
#: With Denoise on, the viewport denoises at a pass end at most this often (seconds):
#: OIDN costs about 10 s per megapixel on two cores.
DENOISE_EVERY = 1.0


class Viewport:
    def __init__(self, engine, client):
        self.engine = engine
        self.session = client.session("blender-viewport")
        self.exported = None
        self.size = None
        self.camera_prim = None
        self.last_view = None
        self.pixels = None
        self.lock = threading.Lock()
        self.thread = None
        self.stopped = False

    def update(self, context, depsgraph):
        if self.exported is None:
            self.exported = export.export_scene(depsgraph)
            self.session.sync_usd(self.exported.path)
            cam = depsgraph.scene.camera
            self.camera_prim = next(iter(self.exported.prims.get(cam.name, [])), None) if cam else None
            return
        _, reexport = _engine.object_edits(self.session, self.exported, depsgraph)
        if reexport:
            fresh = export.export_scene(depsgraph)
            self.session.sync_usd(fresh.path)
            self.exported = fresh

    def _follow_view(self, context):
        """The viewport's view as the camera's transform (a delta when it moved)."""
        if self.camera_prim is None:
            return
        view = context.region_data.view_matrix.inverted()
        rows = [list(r) for r in view]
        if rows != self.last_view:
            self.session.set_transform(self.camera_prim, rows)
            self.last_view = rows

    def _start(self, width, height, scene):
        self.size = (width, height)
        self.pixels = np.zeros((height, width, 4), np.float32)
        settings = _engine.render_settings(scene) | {"coarse_start": COARSE_START}
        denoise = scene.tessera.denoise
        aovs = ["albedo", "normal"] if denoise else []

        def run():
            import time

            import tessera

            guides = tessera.Framebuffer(width, height)
            last_denoise = 0.0
            for event in self.session.render(width, height, spp=VIEWPORT_SPP, aovs=aovs, **settings):
                if self.stopped:
                    break
                kind = type(event).__name__
                if kind == "Tile":
                    guides.add(event)
                    with self.lock:
                        self.pixels[event.y : event.y + event.height, event.x : event.x + event.width] = event.layers["beauty"]
                    self.engine.tag_redraw()
                elif kind == "Progress" and denoise and time.monotonic() - last_denoise > DENOISE_EVERY:
                    # A pass is whole: denoise it on a time budget, then keep drawing raw tiles.
                    with self.lock:
                        raw = self.pixels.copy()
                    rgb = tessera.denoise(raw, guides.layers["albedo"], guides.layers["normal"])
                    with self.lock:
                        self.pixels[..., :3] = rgb
                    last_denoise = time.monotonic()
                    self.engine.tag_redraw()

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()

    def draw(self, context):
        import gpu
        from gpu_extras.presets import draw_texture_2d

        region = context.region
        width, height = region.width, region.height
        self._follow_view(context)
        if self.size != (width, height):
            self.stop()
            self.stopped = False
            self._start(width, height, context.scene)
        with self.lock:
            flipped = np.ascontiguousarray(self.pixels[::-1]).ravel()
        buffer = gpu.types.Buffer("FLOAT", flipped.size, flipped)
        texture = gpu.types.GPUTexture((width, height), format="RGBA16F", data=buffer)
        gpu.state.blend_set("ALPHA_PREMULT")
        self.engine.bind_display_space_shader(context.scene)
        draw_texture_2d(texture, (0, 0), width, height)
        self.engine.unbind_display_space_shader()
        gpu.state.blend_set("NONE")

    def stop(self):
        self.stopped = True
        if self.thread is not None:
            self.session.cancel()
            self.thread.join(timeout=5)
            self.thread = None
        self.session.close()
