"""Radiometers without a camera: Render > Render Radiometers (``photic.render_radiometers``)
and its headless form (``render_radiometers``; ``photic blend`` uses it for a file without a
camera, or with ``--radiometers-only``).

F12 needs a camera (Blender refuses without one); a radiometer-only scene is what analysts
build. This renders the scene's radiometers alone, in a worker thread, with progress and Esc
in the window (a modal operator) or a progress callback headless, and writes the tables as a
final render does (``final_render.write_radiometer_results``).
"""
from __future__ import annotations

import threading
import time
import traceback

import bpy

from . import final_render
from .engine_loader import engine_error, load_engine
from .export import ExportCancelled, ExportError, export_scene


class RadiometerRun:
    """One radiometer-only render of an evaluated depsgraph: ``start`` it, ``poll`` it."""

    def __init__(self, depsgraph):
        self.depsgraph = depsgraph
        self.bscene = depsgraph.scene_eval
        self.photic = None
        self.renderer = None
        self.thread = None
        self.holder: dict = {}
        self.error = None
        self.summary = {"tables": [], "cancelled": False, "error": None}

    def start(self) -> bool:
        """Export and start; False (with ``error`` set) when it cannot."""
        self.photic = photic = load_engine()
        if photic is None:
            self.error = engine_error()
            return False
        try:
            scene, info = export_scene(self.depsgraph, photic)
        except (ExportError, ExportCancelled, photic.scene.SceneError) as exc:
            self.error = str(exc)
            return False
        self.warnings = list(info.warnings)
        scene.cameras = []
        if not scene.radiometers and not scene.radiometer_arrays:
            self.error = (f"Scene '{self.bscene.name}': no Photic radiometers to render (give an "
                          f"object the role Radiometer or Radiometer Array)")
            return False
        try:
            self.renderer = photic.render.Renderer(scene)
        except photic.scene.SceneError as exc:
            self.error = str(exc)
            return False

        def work():
            try:
                self.holder["result"] = self.renderer.run()
            except Exception as exc:  # reported by finish()
                self.holder["error"] = exc
                traceback.print_exc()

        self.t0 = time.perf_counter()
        self.thread = threading.Thread(target=work, name="photic-radiometers", daemon=True)
        self.thread.start()
        return True

    @property
    def running(self) -> bool:
        return self.thread is not None and self.thread.is_alive()

    @property
    def progress(self) -> float:
        return self.renderer.progress if self.renderer is not None else 0.0

    def cancel(self) -> None:
        if self.renderer is not None:
            self.renderer.cancel()
        self.summary["cancelled"] = True

    def finish(self, report) -> dict:
        """Join the worker, write the tables; ``report(level, text)``. Returns the summary."""
        if self.thread is not None:
            self.thread.join()
        if "error" in self.holder:
            self.summary["error"] = f"render failed: {self.holder['error']}"
            report("ERROR", self.summary["error"])
            return self.summary
        final = self.holder.get("result")
        if final is None:
            return self.summary
        self.summary["cancelled"] = bool(final.cancelled)
        self.summary["stats"] = final.stats
        self.summary["warnings"] = list(final.warnings)
        for w in final.warnings:
            report("WARNING", f"Photic: {w}")
        self.summary["time_s"] = time.perf_counter() - self.t0
        self.summary["tables"] = final_render.write_radiometer_results(self.photic, final, self.bscene, report)
        self.summary["radiometers"] = len(final.radiometers)
        return self.summary


def render_radiometers(depsgraph, progress=None, should_stop=None) -> dict:
    """Render the radiometers of an evaluated depsgraph and write their tables (headless).
    ``progress(fraction, text)`` is called as it goes; ``should_stop()`` True cancels. Raises
    RuntimeError with the message when it cannot render."""
    run = RadiometerRun(depsgraph)
    if not run.start():
        raise RuntimeError(run.error)
    messages = []
    while run.running:
        run.thread.join(0.1)
        if should_stop is not None and should_stop():
            run.cancel()
        if progress is not None and run.renderer is not None:
            progress(run.progress, f"radiometers {100 * run.progress:.0f} %")
    summary = run.finish(lambda level, text: messages.append(f"{level}: {text}"))
    summary["messages"] = messages
    if summary.get("error"):
        raise RuntimeError(summary["error"])
    return summary


class PHOTIC_OT_render_radiometers(bpy.types.Operator):
    """Render the scene's Photic radiometers only (no camera needed): values with standard
    errors in the Radiometer Results panel and tables beside the render output. Esc stops it
    (a partial result says so)"""

    bl_idname = "photic.render_radiometers"
    bl_label = "Render Radiometers"
    bl_options = {"REGISTER"}

    _timer = None
    _run = None

    def invoke(self, context, event):
        from . import natural_waters
        natural_waters.read_volumes(context.scene)
        run = RadiometerRun(context.evaluated_depsgraph_get())
        if not run.start():
            self.report({"ERROR"}, run.error)
            return {"CANCELLED"}
        for w in run.warnings:
            self.report({"WARNING"}, w)
        self._run = run
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):  # no window (scripts, background): render and wait
        try:
            summary = render_radiometers(context.evaluated_depsgraph_get())
        except RuntimeError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        final_render.keep_results(context.scene)
        for m in summary.get("messages", []):
            self.report({"WARNING"}, m)
        self.report({"INFO"}, f"{summary.get('radiometers', 0)} radiometers rendered"
                              + (f"; tables {summary['tables'][0]}" if summary["tables"] else ""))
        return {"FINISHED"}

    def modal(self, context, event):
        run = self._run
        wm = context.window_manager
        if event.type == "ESC":
            run.cancel()
        if event.type != "TIMER" and event.type != "ESC":
            return {"PASS_THROUGH"}
        wm.progress_update(int(100 * run.progress))
        if context.area:
            context.area.header_text_set(f"Photic: radiometers {100 * run.progress:.0f} % (Esc stops)")
        if run.running:
            return {"RUNNING_MODAL"}
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.area:
            context.area.header_text_set(None)
        summary = run.finish(lambda level, text: self.report({level}, text))
        final_render.keep_results(context.scene)
        for area in context.screen.areas if context.screen else []:
            area.tag_redraw()
        if summary.get("error"):
            return {"CANCELLED"}
        self.report({"INFO"}, f"Photic: {summary.get('radiometers', 0)} radiometers"
                              + (" (cancelled: partial)" if summary["cancelled"] else "")
                              + (f"; tables {summary['tables'][0]}" if summary["tables"] else ""))
        return {"FINISHED"}


def menu_render(self, context):
    if context.scene.render.engine == "PHOTIC":
        self.layout.operator(PHOTIC_OT_render_radiometers.bl_idname, icon="LIGHT_SUN")


classes = (PHOTIC_OT_render_radiometers,)


def register():
    bpy.types.TOPBAR_MT_render.append(menu_render)


def unregister():
    bpy.types.TOPBAR_MT_render.remove(menu_render)
