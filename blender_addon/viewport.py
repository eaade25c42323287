"""Rendered viewport shading: a progressive Photic render of the 3D view, drawn with ``gpu``.

The scene is exported again when the depsgraph reports an edit, and the render restarts when
the scene or the view changes; the engine thread is cancelled first, so it never outlives an
edit. A coarse first image (about 6000 pixels, at least 4 times smaller each way, one sample
per pixel, the same beams' kind: a few tenths of a second) comes first and stays until the first
full-resolution pass covers the whole view, then the passes sharpen it; until the coarse image
arrives the previous image stays on screen.
"""
from __future__ import annotations

import math
import threading
import traceback

import numpy as np

from . import bands as bandmod
from . import scene_notes
from .engine_loader import engine_error, load_engine
from .export import ExportCancelled, ExportError, ViewCamera, export_scene


def view_camera(context, width: int, height: int) -> ViewCamera:
    """The engine camera of a 3D viewport (its view and projection matrices)."""
    rv3d = context.region_data
    world = np.array(rv3d.view_matrix.inverted(), float)
    p = np.array(rv3d.window_matrix, float)
    if rv3d.is_perspective:
        return ViewCamera(False, world, 1.0 / p[0, 0], 2.0, (p[0, 2] / 2.0, p[1, 2] * p[0, 0] / (2.0 * p[1, 1])),
                          0.0)
    # Orthographic views see objects on both sides of the view point: start the rays behind.
    back = 10.0 * max(1.0, float(rv3d.view_distance))
    world[:3, 3] += world[:3, 2] * back
    return ViewCamera(True, world, 1.0, 2.0 / p[0, 0], (-p[0, 3] / 2.0, -p[1, 3] * p[0, 0] / (2.0 * p[1, 1])),
                      0.0)


class ViewportRender:
    """The viewport state of one RenderEngine instance.

    It keeps no reference to the engine (``draw`` is given it): a reference cycle would keep
    the engine's Python object alive after Blender frees the engine, and its ``__del__``, which
    stops the render thread, would then run late, on a removed StructRNA, and fail."""

    def __init__(self):
        self.renderer = None
        self.thread = None
        self.key = None
        self.dirty = True
        self.message = None
        self.texture = None
        self.texture_samples = -1  # the most samples a pixel of the texture has
        self.texture_version = -1  # the renderer's version of the sums the texture shows
        self.final = None          # {"result": ..., "preview": ...} of the running render
        self.bands = None
        self.preview = None        # the coarse first image's Renderer, while it matters
        self.full_shown = False    # whether the texture shows the full-resolution render

    # The coarse first image: about PREVIEW_PIXELS pixels (at least PREVIEW_MIN_FACTOR times
    # smaller in each direction), for views larger than PREVIEW_MIN_PIXELS (smaller ones are
    # quick anyway). A pixel-sample of the main example costs about 25 us on two busy cores:
    # 6000 pixels are 0.15 s, after the beams (0.2-0.3 s).
    PREVIEW_PIXELS = 6_000
    PREVIEW_MIN_FACTOR = 4
    PREVIEW_MIN_PIXELS = 40_000

    @classmethod
    def preview_factor(cls, width: int, height: int) -> int:
        return max(cls.PREVIEW_MIN_FACTOR, math.ceil(math.sqrt(width * height / cls.PREVIEW_PIXELS)))

    def stop(self) -> None:
        for r in (self.preview, self.renderer):
            if r is not None:
                r.cancel()
        if self.thread is not None:
            self.thread.join()
        self.renderer = self.thread = self.preview = None

    def update(self, context, depsgraph) -> None:
        """The scene changed: render again at the next draw."""
        self.dirty = True

    def _start(self, context, depsgraph, width, height) -> None:
        self.stop()
        self.message = None
        photic = load_engine()
        if photic is None:
            self.message = engine_error()
            return
        try:
            scene, info = export_scene(depsgraph, photic, view_camera=view_camera(context, width, height),
                                       resolution=(width, height))
        except (ExportError, ExportCancelled, photic.scene.SceneError) as exc:
            self.message = str(exc)
            return
        scene_notes.remember(depsgraph.scene_eval.name, info)
        scene.radiometers, scene.radiometer_arrays = [], []  # final renders measure them
        scene.settings.samples = int(depsgraph.scene_eval.photic.viewport_samples)
        self.bands = [(b.name, b.center_nm, b.width_nm) for b in scene.bands]
        try:
            self.renderer = photic.render.Renderer(scene)
            self.preview = (photic.render.Renderer(coarse_scene(scene, self.preview_factor(width, height)),
                                                   samples=1)
                            if width * height > self.PREVIEW_MIN_PIXELS else None)
        except photic.scene.SceneError as exc:
            self.message = str(exc)
            return
        self.full_shown = False

        holder = self.final = {}

        def work(renderer=self.renderer, preview=self.preview):
            from .final_render import lower_priority
            try:
                if preview is not None:  # (at the interface's priority: the first image)
                    first = preview.run()
                    if first.cancelled:
                        return
                    holder["preview"] = first
                lower_priority()  # (the interface draws this viewport: it must not starve)
                holder["result"] = renderer.run()
            except Exception:
                traceback.print_exc()

        self.thread = threading.Thread(target=work, name="photic-viewport", daemon=True)
        self.thread.start()

    FINISHED = 1 << 62  # the texture's version once it shows the finished render's image

    PREVIEW = -2  # the texture's version while it shows the coarse first image

    def _next_frame(self, renderer, height: int):
        """(display rows bottom first, (width, height), version, samples) of what the texture
        does not show yet, or None: the coarse first image, then the running sums once the
        first pass covers the whole view and while they change, then the finished render's
        image, which holds the last pieces the sums, spent by then, no longer show."""
        changed = renderer.changed_rows("viewport", self.texture_version)
        if changed is not None and not self.full_shown:
            rendered = renderer.changed_rows("viewport", -1)  # (the rows rendered so far)
            if rendered is None or rendered[0] != 0 or rendered[1] < height:
                changed = None  # the first pass is still on its way down the view
        got = renderer.total_sums("viewport", rows=(0, height)) if changed is not None else None
        if got is not None:
            h, w = got.total.shape[:2]
            return bandmod.total_to_rows(got.total, got.n, self.bands), (w, h), changed[2], int(np.max(got.n))
        done = self.final.get("result") if self.final is not None else None
        if done is not None and "viewport" in done.images:
            self.final = None
            img = done.images["viewport"]
            h, w = img.mean.shape[:2]
            return (bandmod.bands_to_rgba(img.mean, self.bands)[::-1].reshape(-1, 4), (w, h),
                    self.FINISHED, img.samples)
        first = self.final.get("preview") if self.final is not None else None
        if first is not None and not self.full_shown and self.texture_version != self.PREVIEW:
            img = first.images["viewport"]
            h, w = img.mean.shape[:2]
            return bandmod.bands_to_rgba(img.mean, self.bands)[::-1].reshape(-1, 4), (w, h), self.PREVIEW, 0
        return None

    def draw(self, engine, context, depsgraph) -> None:
        import gpu
        from gpu_extras.presets import draw_texture_2d

        region = context.region
        scale = depsgraph.scene_eval.photic.viewport_scale / 100.0
        width, height = max(1, int(region.width * scale)), max(1, int(region.height * scale))
        rv3d = context.region_data
        key = (tuple(map(tuple, rv3d.view_matrix)), tuple(map(tuple, rv3d.window_matrix)),
               width, height)
        if self.dirty or key != self.key:
            self.key, self.dirty = key, False
            self._start(context, depsgraph, width, height)
            self.texture_samples = self.texture_version = -1
        if self.message:
            engine.update_stats("", f"Photic: {self.message}")
        renderer = self.renderer
        if renderer is not None:
            frame = self._next_frame(renderer, height)
            if frame is not None:
                rows, size, version, samples = frame
                self.full_shown = self.full_shown or version != self.PREVIEW
                scene = depsgraph.scene_eval
                if scene.photic.auto_exposure:  # display only: the net exposure is the image's
                    stops = bandmod.auto_exposure(rows)
                    if stops is not None:
                        rows[:, :3] *= 2.0 ** (stops - scene.view_settings.exposure)
                buf = gpu.types.Buffer("FLOAT", rows.size, rows.ravel())
                self.texture = gpu.types.GPUTexture(size, format="RGBA16F", data=buf)
                self.texture_version, self.texture_samples = version, samples
                engine.update_stats("", f"Photic: sample {samples}/{renderer.samples}" if samples
                                    else "Photic: first image (coarse)")
            if (self.thread is not None and self.thread.is_alive()) or \
                    (self.final is not None and (self.final.get("result") is not None
                                                 or self.final.get("preview") is not None)):
                engine.tag_redraw()  # (until the finished render's image is shown)
        if self.texture is not None:
            gpu.state.blend_set("ALPHA_PREMULT")
            engine.bind_display_space_shader(depsgraph.scene_eval)
            draw_texture_2d(self.texture, (0, 0), region.width, region.height)
            engine.unbind_display_space_shader()
            gpu.state.blend_set("NONE")


def coarse_scene(scene, factor: int):
    """The scene with its camera's resolution divided by ``factor`` (at least 1 x 1) and one
    sample per pixel: the viewport's quick first image (the rest is shared, read only)."""
    from dataclasses import replace
    cams = [replace(c, resolution=(max(1, -(-c.resolution[0] // factor)), max(1, -(-c.resolution[1] // factor))))
            for c in scene.cameras]
    return replace(scene, cameras=cams, settings=replace(scene.settings, samples=1))
