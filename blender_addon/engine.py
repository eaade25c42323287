"""The Photic RenderEngine: a thin class forwarding to ``final_render`` and ``viewport``."""
from __future__ import annotations

import bpy

from . import engine_loader, final_render, viewport


class PhoticRenderEngine(bpy.types.RenderEngine):
    bl_idname = "PHOTIC"
    bl_label = "Photic"
    bl_use_preview = False
    bl_use_shading_nodes_custom = False
    bl_use_postprocess = True

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.viewport = None

    def __del__(self):
        # The viewport's worker thread must not outlive the engine.
        try:
            vp = getattr(self, "viewport", None)
        except ReferenceError:  # Blender freed the engine first (a render that was stopped)
            return
        if vp is not None:
            vp.stop()

    def render(self, depsgraph):
        for name, channels, kind in final_render.render_passes(depsgraph.scene):
            if name != "Combined":
                self.add_pass(name, len(channels), channels)
        final_render.FinalRender(self, depsgraph).run()

    def update_render_passes(self, scene=None, renderlayer=None):
        # Makes the passes known to the compositor and the multilayer EXR output.
        for name, channels, kind in final_render.render_passes(scene):
            self.register_pass(scene, renderlayer, name, len(channels), channels, kind)

    def view_update(self, context, depsgraph):
        if self.viewport is None:
            self.viewport = viewport.ViewportRender()
        self.viewport.update(context, depsgraph)

    def view_draw(self, context, depsgraph):
        if self.viewport is None:
            self.viewport = viewport.ViewportRender()
        self.viewport.draw(self, context, depsgraph)


def compatible_panels():
    """Built-in panels that also apply to Photic (camera, light, output, material slots)."""
    wanted = {"DATA_PT_lens", "DATA_PT_camera", "DATA_PT_camera_display", "DATA_PT_context_light",
              "DATA_PT_light", "DATA_PT_sunlight", "EEVEE_LIGHT_PT_sun", "MATERIAL_PT_context_material",
              "RENDER_PT_format", "RENDER_PT_frame_range", "RENDER_PT_output",
              "RENDER_PT_color_management", "RENDER_PT_dimensions", "WORLD_PT_context_world",
              "DATA_PT_context_camera", "DATA_PT_context_mesh", "DATA_PT_normals",
              "DATA_PT_uv_texture", "DATA_PT_vertex_groups", "DATA_PT_customdata",
              "OBJECT_PT_transform", "OBJECT_PT_relations", "OBJECT_PT_visibility"}
    return [getattr(bpy.types, n) for n in wanted if hasattr(bpy.types, n)]


@bpy.app.handlers.persistent
def _auto_exposure_after_render(scene, *args):
    """After a render job: the display exposure of Auto Exposure, the radiometer results
    kept in the scene."""
    try:
        final_render.apply_auto_exposure(scene)
    except Exception as exc:  # noqa: BLE001  (a handler must not break Blender)
        print(f"Photic: auto exposure not set: {exc}")
    try:
        final_render.keep_results(scene)  # (the radiometers' results, saved with the .blend)
    except Exception as exc:  # noqa: BLE001
        print(f"Photic: radiometer results not kept in the file: {exc}")


@bpy.app.handlers.persistent
def _warm_up_after_load(*args):
    """A file whose scene renders with Photic: the engine imported in the background now."""
    try:
        if any(s.render.engine == PhoticRenderEngine.bl_idname for s in bpy.data.scenes):
            engine_loader.warm_up()
    except Exception as exc:  # noqa: BLE001  (a handler must not break Blender)
        print(f"Photic: the engine was not imported ahead: {exc}")


def register():
    if _warm_up_after_load not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(_warm_up_after_load)
    for panel in compatible_panels():
        if hasattr(panel, "COMPAT_ENGINES"):
            panel.COMPAT_ENGINES.add(PhoticRenderEngine.bl_idname)
    if _auto_exposure_after_render not in bpy.app.handlers.render_complete:
        bpy.app.handlers.render_complete.append(_auto_exposure_after_render)


def unregister():
    if _warm_up_after_load in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_warm_up_after_load)
    for panel in compatible_panels():
        if hasattr(panel, "COMPAT_ENGINES"):
            panel.COMPAT_ENGINES.discard(PhoticRenderEngine.bl_idname)
    if _auto_exposure_after_render in bpy.app.handlers.render_complete:
        bpy.app.handlers.render_complete.remove(_auto_exposure_after_render)
