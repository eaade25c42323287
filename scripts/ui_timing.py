"""Timings of the add-on as a user meets them, inside Blender with its UI (run by
``scripts/ui_timing_run.py``, which starts Xvfb and Blender; not by hand).

Keys are pressed as a user presses them: through the X server (XTest, on a connection of this
process's own), so Blender sees real key events and runs its own render job; nothing of the
add-on is stubbed. The add-on's methods are only wrapped to note *when* they ran.

Modes (``PHOTIC_UI_MODE``):

- ``f12``: F12 over the 3D view; the time from the key to the first streamed update of the render
  view (``update_result``) and, with ``PHOTIC_UI_ESC_AFTER`` seconds set, from Esc to the end of
  Blender's render job (``bpy.app.is_job_running('RENDER')`` false) and to the engine's
  ``render`` returning. Several Esc times may be given, comma-separated: one F12 each.
- ``viewport``: the largest 3D view switched to Rendered shading; the time from the switch to
  the first image drawn (the first texture the add-on's ``view_draw`` uploads) and its size.

Settings from the environment: ``PHOTIC_UI_OUT`` (JSON results), ``PHOTIC_UI_RESOLUTION``
(``1920x1080``), ``PHOTIC_UI_DENOISE`` (``1``), ``PHOTIC_UI_THREADS`` (``2``),
``PHOTIC_UI_SAMPLES`` (the file's when unset), ``PHOTIC_UI_REPEAT`` (runs of each, default 1).
"""
import ctypes
import json
import os
import time
import traceback

import bpy

OUT = os.environ.get("PHOTIC_UI_OUT", "/tmp/photic_ui_timing.json")
MODE = os.environ.get("PHOTIC_UI_MODE", "f12")
REPEAT = int(os.environ.get("PHOTIC_UI_REPEAT", "1"))
ESC_AFTER = [float(x) for x in os.environ.get("PHOTIC_UI_ESC_AFTER", "").split(",") if x.strip()]
TIMEOUT_S = float(os.environ.get("PHOTIC_UI_TIMEOUT", "600"))
results = {"mode": MODE, "blender": bpy.app.version_string, "runs": [], "error": None}
marks: dict = {}


def log(msg):
    print(f"ui_timing: {msg}", flush=True)


def finish(error=None):
    if error:
        results["error"] = error
        log(error)
    with open(OUT, "w") as f:
        json.dump(results, f, indent=1)
    bpy.ops.wm.quit_blender()


# ---- real key presses through the X server --------------------------------------------------
class XKeys:
    """XTest on a display connection of our own: events reach Blender through the X server."""

    def __init__(self):
        self.x11 = ctypes.CDLL("libX11.so.6")
        self.xtst = ctypes.CDLL("libXtst.so.6")
        self.x11.XOpenDisplay.restype = ctypes.c_void_p
        self.x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
        self.x11.XKeysymToKeycode.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
        self.x11.XStringToKeysym.restype = ctypes.c_ulong
        self.x11.XStringToKeysym.argtypes = [ctypes.c_char_p]
        self.x11.XFlush.argtypes = [ctypes.c_void_p]
        self.xtst.XTestFakeKeyEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_ulong]
        self.xtst.XTestFakeMotionEvent.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                                                   ctypes.c_ulong]
        self.dpy = self.x11.XOpenDisplay(os.environ["DISPLAY"].encode())
        if not self.dpy:
            raise RuntimeError("cannot open the X display")

    def move(self, x, y):
        self.xtst.XTestFakeMotionEvent(self.dpy, -1, int(x), int(y), 0)
        self.x11.XFlush(self.dpy)

    def press(self, name: str):
        code = self.x11.XKeysymToKeycode(self.dpy, self.x11.XStringToKeysym(name.encode()))
        self.xtst.XTestFakeKeyEvent(self.dpy, code, 1, 0)
        self.xtst.XTestFakeKeyEvent(self.dpy, code, 0, 0)
        self.x11.XFlush(self.dpy)


# ---- when the add-on did what -------------------------------------------------------------
def addon_module(name):
    import importlib
    for pkg in ("photic_blender", "bl_ext.user_default.photic"):
        try:
            return importlib.import_module(f"{pkg}.{name}")
        except ImportError:
            continue
    raise ImportError(f"the Photic add-on's {name} module is not loaded")


def wrap(cls, name, key, first_only=True):
    original = getattr(cls, name)

    def wrapper(*a, **kw):
        t = time.perf_counter()
        if not first_only or key not in marks:
            marks[key] = t
        try:
            return original(*a, **kw)
        finally:
            marks[key + "_end"] = time.perf_counter()
            marks.setdefault(key + "_durations", []).append(marks[key + "_end"] - t)
    setattr(cls, name, wrapper)


def instrument():
    fr = addon_module("final_render")
    for name in ("_show_rows", "_show"):
        if hasattr(fr.FinalRender, name):
            wrap(fr.FinalRender, name, "first_update")
    wrap(fr.FinalRender, "run", "render_call")
    vp = addon_module("viewport")
    original = vp.ViewportRender.draw

    def draw(self, engine, context, depsgraph):
        out = original(self, engine, context, depsgraph)
        if getattr(self, "texture", None) is not None and "viewport_first_image" not in marks:
            marks["viewport_first_image"] = time.perf_counter()
            marks["viewport_size"] = [self.texture.width, self.texture.height]
        return out
    vp.ViewportRender.draw = draw


def view3d():
    window = bpy.context.window_manager.windows[0]
    areas = [a for a in window.screen.areas if a.type == "VIEW_3D"]
    area = max(areas, key=lambda a: a.width * a.height)
    region = next(r for r in area.regions if r.type == "WINDOW")
    return window, area, region


def setup_scene():
    scene = bpy.context.scene
    w, h = (int(v) for v in os.environ.get("PHOTIC_UI_RESOLUTION", "1920x1080").split("x"))
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    p = scene.photic
    p.denoise = os.environ.get("PHOTIC_UI_DENOISE", "1") == "1"
    p.threads = int(os.environ.get("PHOTIC_UI_THREADS", "2"))
    if os.environ.get("PHOTIC_UI_SAMPLES"):
        p.samples = int(os.environ["PHOTIC_UI_SAMPLES"])
    results["settings"] = {"resolution": [w, h], "denoise": p.denoise, "threads": p.threads,
                           "samples": p.samples, "file": bpy.data.filepath}


# ---- F12 ------------------------------------------------------------------------------------
def f12_runs():
    plan = [e for e in (ESC_AFTER or [None]) for _ in range(REPEAT)]
    keys = XKeys()
    state = {"i": 0, "phase": "idle", "t": 0.0}

    def step():
        try:
            now = time.perf_counter()
            if state["phase"] == "idle":
                if state["i"] >= len(plan):
                    finish()
                    return None
                if bpy.app.is_job_running("RENDER"):
                    return 0.05
                marks.clear()
                window, area, region = view3d()
                keys.move(window.x + region.x + region.width // 2,
                          window.height - (region.y + region.height // 2))
                state.update(phase="pressed", t=time.perf_counter(), esc=None, seen_job=False)
                if os.environ.get("PHOTIC_UI_PERF"):  # where the main thread's time goes
                    import subprocess
                    subprocess.Popen(["perf", "record", "-t", str(os.getpid()), "-g", "-o",
                                      os.environ["PHOTIC_UI_PERF"], "--", "sleep", "8"],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                keys.press("F12")
                return 0.005
            running = bpy.app.is_job_running("RENDER")
            state["seen_job"] |= running
            esc_after = plan[state["i"]]
            if esc_after is not None and state["esc"] is None and now - state["t"] >= esc_after:
                state["esc"] = time.perf_counter()
                keys.press("Escape")
            if now - state["t"] > TIMEOUT_S:
                finish(f"run {state['i']}: the render did not end within {TIMEOUT_S} s")
                return None
            if state["seen_job"] and not running:
                t0 = state["t"]
                run = {"esc_after_s": esc_after,
                       "first_update_s": marks["first_update"] - t0 if "first_update" in marks else None,
                       "render_call_s": marks["render_call"] - t0 if "render_call" in marks else None,
                       "job_end_s": now - t0}
                # how long each streamed update took in the render thread (update_result with
                # the interpreter lock held: the interface's Python waits meanwhile)
                run["update_durations_s"] = [round(d, 3) for d in marks.get("first_update_durations", [])]
                if state["esc"] is not None:
                    run["esc_to_job_end_s"] = now - state["esc"]
                    if "render_call_end" in marks:
                        run["esc_to_render_return_s"] = marks["render_call_end"] - state["esc"]
                try:
                    fr = addon_module("final_render")
                    s = fr.LAST_RENDER
                    run["summary"] = {k: s.get(k) for k in ("cancelled", "cancel_latency_s", "samples",
                                                            "denoise_s", "export_s", "time_s", "error")}
                    run["summary"]["updates"] = s.get("updates")
                    if state["esc"] is not None and s.get("cancel_at") is not None:
                        # Esc to the add-on's test_break() seeing it: Blender's part of Esc
                        run["esc_to_test_break_s"] = s["cancel_at"] - state["esc"]
                except Exception:  # noqa: BLE001
                    traceback.print_exc()
                results["runs"].append(run)
                log(json.dumps(run))
                state.update(i=state["i"] + 1, phase="idle")
                # back to the main window for the next run: close the render view (Esc there)
                return 1.0
            return 0.005
        except Exception:  # noqa: BLE001
            finish(traceback.format_exc())
            return None
    return step


# ---- viewport -------------------------------------------------------------------------------
def viewport_runs():
    state = {"i": 0, "phase": "idle", "t": 0.0}

    def step():
        try:
            window, area, region = view3d()
            space = area.spaces.active
            if state["phase"] == "idle":
                if state["i"] >= REPEAT:
                    finish()
                    return None
                space.shading.type = "SOLID"
                marks.clear()
                state.update(phase="solid")
                return 1.0
            if state["phase"] == "solid":
                # What a click on the Rendered shading button does.
                state.update(phase="rendered", t=time.perf_counter())
                space.shading.type = "RENDERED"
                return 0.005
            now = time.perf_counter()
            if "viewport_first_image" in marks:
                run = {"first_image_s": marks["viewport_first_image"] - state["t"],
                       "region": [region.width, region.height],
                       "image": marks.get("viewport_size")}
                results["runs"].append(run)
                log(json.dumps(run))
                state.update(i=state["i"] + 1, phase="idle")
                return 0.5
            if now - state["t"] > TIMEOUT_S:
                finish(f"viewport run {state['i']}: no image within {TIMEOUT_S} s")
                return None
            return 0.005
        except Exception:  # noqa: BLE001
            finish(traceback.format_exc())
            return None
    return step


def watchdog():
    """PHOTIC_UI_WATCHDOG=1: the main thread's longest stalls (a 10 ms timer that did not run),
    and what the other Python threads were doing meanwhile (printed)."""
    import sys
    import threading
    beat = {"t": time.perf_counter()}
    stalls = results.setdefault("main_thread_stalls_s", [])

    def heartbeat():
        now = time.perf_counter()
        if now - beat["t"] > 0.25:
            stalls.append(round(now - beat["t"], 3))
        beat["t"] = now
        return 0.01

    def dog():
        dumped = 0.0
        while True:
            time.sleep(0.1)
            if time.perf_counter() - beat["t"] > 1.0 and time.perf_counter() - dumped > 2.0:
                dumped = time.perf_counter()
                if os.environ.get("PHOTIC_UI_GDB") == "1":  # the main thread's native stack
                    import subprocess
                    out = subprocess.run(["gdb", "-p", str(os.getpid()), "-batch", "-ex", "thread apply 1 bt 30"],
                                         capture_output=True, text=True).stdout
                    print("ui_timing: gdb main thread:\n" + "\n".join(
                        l for l in out.splitlines() if l.startswith("#"))[:4000], flush=True)
                frames = sys._current_frames()
                print(f"ui_timing: main thread stalled {time.perf_counter() - beat['t']:.1f} s; threads:", flush=True)
                for t in threading.enumerate():
                    f = frames.get(t.ident)
                    if f is not None:
                        print(f"  {t.name}: " + " <- ".join(f"{c.f_code.co_name}:{c.f_lineno}" for c in _stack(f)[:8]),
                              flush=True)

    def _stack(f):
        out = []
        while f is not None:
            out.append(f)
            f = f.f_back
        return out
    bpy.app.timers.register(heartbeat, first_interval=0.01, persistent=True)
    threading.Thread(target=dog, daemon=True).start()


def start():
    try:
        if os.environ.get("PHOTIC_UI_WATCHDOG") == "1":
            watchdog()
        bpy.context.preferences.view.show_splash = False
        instrument()
        setup_scene()
        bpy.app.timers.register(f12_runs() if MODE == "f12" else viewport_runs(), first_interval=2.0)
    except Exception:  # noqa: BLE001
        finish(traceback.format_exc())
    return None


bpy.app.timers.register(start, first_interval=1.0)
