"""Final renders (F12, ``blender -b ... -f``, ``bpy.ops.render.render``).

The engine renders in a background thread; ``FinalRender.run`` polls it every few hundredths
of a second: Esc (``test_break``) cancels it, the current estimate streams into the render
view with ``update_result`` twice a second, progress and stats (samples, rays/s, estimated
error) are reported, and the partial image of a cancelled render is kept. It needs only the
RenderEngine methods it calls, so tests drive it with a stand-in engine as well as through
Blender. With a Dask scheduler address in the render settings (Scene.photic.dask_scheduler)
the frame is rendered as work units on that cluster instead (photic.distributed) and the
merged image streams back the same way; an animation renders frame after frame so.
"""
from __future__ import annotations

import tempfile
import threading
import time
import traceback
from pathlib import Path

import numpy as np

from . import bands as bandmod
from . import scene_notes
from .engine_loader import load_engine, engine_error
from .export import ExportCancelled, ExportError, export_scene
from .export_settings import RAMAN_SETTING

#: Render passes besides Combined: (Blender pass name, engine component).
COMPONENT_PASSES = (("Photic Beam Surface", "beam_surface"),
                    ("Photic Beam Volume", "beam_volume"),
                    ("Photic Path", "path"))
VARIANCE_PASS = "Photic Variance"
PASS_NAMES = tuple(p for p, _ in COMPONENT_PASSES) + (VARIANCE_PASS,)
RAMAN_PASS = "Photic Raman"  # (when a render has Raman light: light Raman-scattered by water)
CHLOROPHYLL_PASS, CDOM_PASS = "Photic Chlorophyll", "Photic CDOM"
#: Where a water fluoresces (Object > Photic > Inelastic Light): (pass, engine component, the
#: water object's property that turns it on).
FLUORESCENCE_PASSES = ((CHLOROPHYLL_PASS, "chlorophyll", "chl_fluorescence"),
                       (CDOM_PASS, "cdom", "cdom_fluorescence"))
ALBEDO_PASS, NORMAL_PASS, NOISY_PASS = "Denoising Albedo", "Denoising Normal", "Noisy Image"
UPDATE_INTERVAL_S = 0.5
FRAME_INTERVAL_S = 0.9  # the render view's image at most this often (each costs a full-image write)
STREAM = True  # False: the render view gets the image at the end only (to measure streaming's cost)
POLL_S = 0.02
DASK_CONNECT_TIMEOUT_S = 10.0  # how long a render waits for its Dask scheduler to answer

#: Radiometer results of the last render per scene name (shown in the Render panel), and a
#: summary of the last render (updates streamed, cancel latency) for tests and the console.
LAST_RADIOMETERS: dict = {}
LAST_RENDER: dict = {}

#: When set, a final render only exports its scene and hands it to this callable (the
#: .blend inputs of ``photic batch`` jobs: see ``batch.export_frames``).
EXPORT_HOOK = None

def apply_auto_exposure(scene) -> float | None:
    """Set the scene's display exposure from the last render (its Auto Exposure option): on
    the main thread, after the render job (a render must not edit scene data while it runs).
    Returns the exposure set, or None."""
    props = getattr(scene, "photic", None)
    stops = LAST_RENDER.get("auto_exposure")
    if props is None or not props.auto_exposure or stops is None or LAST_RENDER.get("scene") != scene.name:
        return None
    scene.view_settings.exposure = stops
    return stops


#: When set, called as PROGRESS_HOOK(fraction, text) with the render's progress and status
#: (a background Blender shows neither): ``photic blend`` draws its progress bar with it.
PROGRESS_HOOK = None

#: Set (by ``photic blend``'s Ctrl-C handler) to stop the render as Esc does: the worker is
#: cancelled and joined, and what is finished is kept.
CANCEL = threading.Event()


def stop_requested(engine) -> bool:
    """Esc in Blender (``engine.test_break()``) or a Ctrl-C of ``photic blend`` (CANCEL)."""
    return CANCEL.is_set() or bool(engine.test_break())


def set_rect(render_pass, image: np.ndarray) -> None:
    """Write an (H, W, C) top-row-first image into a render pass (bottom row first).

    Blender 3.x takes an (H*W, C) array, Blender 4.x and 5.x a flat one."""
    h, w, c = image.shape
    write_rows(render_pass, np.ascontiguousarray(image[::-1].reshape(h * w, c), dtype=np.float32))


def write_rows(render_pass, rows: np.ndarray) -> None:
    """Write (H*W, C) float32 bottom-row-first pixels into a render pass. ``foreach_set`` on
    the pass's rect is a memory copy (0.02 s at 1920x1080); assigning an array goes through a
    Python sequence per pixel (seconds). Stand-ins and old Blenders take the assignment."""
    rect = getattr(render_pass, "rect", None)
    if hasattr(rect, "foreach_set"):
        try:
            rect.foreach_set(rows.ravel())
            return
        except (TypeError, ValueError, RuntimeError):
            pass
    if _copy_into_pass(render_pass, rows):
        return
    rows = rows.copy()  # (an assignment may keep the array: the caller's buffer changes)
    try:
        render_pass.rect = rows.ravel()
    except (TypeError, ValueError):
        render_pass.rect = rows


#: How much lower the priority of the engine's threads is than Blender's interface, in a Blender
#: with a window (Linux nice steps; 0: the same). Blender draws the render view and sees Esc on
#: its main thread; where the screen is drawn by the CPU too (software OpenGL, a virtual
#: machine) a render on every core starved it: Esc waited seconds for a redraw to finish.
RENDER_NICE = 4


def lower_priority(tid: int | None = None) -> None:
    """Lower a thread's priority (the calling thread's when ``tid`` is None; else the native
    id of a thread of this process) by RENDER_NICE (the threads it starts later inherit it),
    when Blender has a window; nothing in background renders or where it is not supported."""
    import os
    try:
        import bpy
        if RENDER_NICE <= 0 or bpy.app.background or not hasattr(os, "setpriority"):
            return
        tid = threading.get_native_id() if tid is None else tid
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + RENDER_NICE)
    except Exception:  # noqa: BLE001  (a priority is a nicety)
        pass


# Blender 3.x's RenderPass (source/blender/render/RE_pipeline.h): next, prev, channels at 16,
# name[64] at 20, chan_id[8], the float *rect at 96, rectx and recty at 104 and 108.
_PASS_LAYOUT = {"channels": 16, "name": 20, "rect": 96, "rectx": 104, "recty": 108}


def _copy_into_pass(render_pass, rows: np.ndarray) -> bool:
    """Copy (H*W, C) float32 pixels straight into a Blender 3.x render pass's buffer; whether
    it was done. Blender 3.x's ``rect.foreach_set`` takes the first dimension of the (H*W, C)
    array for its size and fails, and the assignment that remains converts pixel by pixel
    through Python sequences holding the interpreter lock (1.5 s at 1920 x 1080, during which
    Blender's interface, which draws with Python, cannot even see Esc). The pass's fields are
    checked against its RNA values first (channels, name, size): any other layout is left to
    the assignment."""
    import ctypes
    try:
        import bpy
        if bpy.app.version >= (4, 0, 0) or not hasattr(render_pass, "as_pointer"):
            return False
        ptr = render_pass.as_pointer()
        lay = _PASS_LAYOUT
        channels = ctypes.c_int.from_address(ptr + lay["channels"]).value
        name = ctypes.string_at(ptr + lay["name"], 64).split(b"\0")[0].decode("utf-8", "replace")
        rectx = ctypes.c_int.from_address(ptr + lay["rectx"]).value
        recty = ctypes.c_int.from_address(ptr + lay["recty"]).value
        rect = ctypes.c_void_p.from_address(ptr + lay["rect"]).value
        if (channels != render_pass.channels or name != render_pass.name or not rect
                or rows.dtype != np.float32 or rows.size != rectx * recty * channels
                or rows.shape[-1] != channels):
            return False
        rows = np.ascontiguousarray(rows)
        ctypes.memmove(rect, rows.ctypes.data, rows.nbytes)
        return True
    except Exception:  # noqa: BLE001  (any doubt: the slow, safe assignment)
        return False


class DisplayStream:
    """The render view's pixels, prepared in a thread of their own while the engine renders:
    the running sums of the total in display RGB (``bands.total_to_rows``), redone only for the
    rows that changed, and now and then the image's noise figure from every eighth row and
    column. The main thread only hands a ready frame to Blender (``show``), so Esc is seen at
    once and streaming costs the main thread almost nothing. The thread looks for news every
    MIN_INTERVAL_S, or 20 times the time one frame took to prepare (its share of the machine
    about 5 %) but at most MAX_INTERVAL_S."""

    MIN_INTERVAL_S, MAX_INTERVAL_S = 0.25, 0.5
    FIRST_INTERVAL_S = 0.03  # until the first piece has come
    ERROR_INTERVAL_S = 2.0
    ERROR_STRIDE = 8  # the noise figure from every 8th row and column (32k pixels at 1080p)
    BLOCK_ROWS = 64  # rows converted at a time: small temporaries, the engine's lock held briefly

    def __init__(self, renderer, camera: str, size: tuple[int, int], bands):
        self.renderer, self.camera, self.bands = renderer, camera, bands
        self.width, self.height = size
        self._fresh = False
        self._dirty = None  # (first, end) rows, bottom first, changed since the last show
        self.samples = 0
        self.error = None
        self.prep_times: list[float] = []
        self._version = -1
        self._rows = np.zeros((self.height, self.width, 4), np.float32)  # bottom row first
        self._rows[..., 3] = 1.0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="photic-display", daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        interval, last_error = self.FIRST_INTERVAL_S, -1e9
        while not self._stop.wait(interval):
            try:
                t0 = time.perf_counter()
                if not self._refresh():
                    if self._version < 0:
                        interval = self.FIRST_INTERVAL_S  # (the first pixels: looked for often)
                    continue
                if t0 - last_error >= self.ERROR_INTERVAL_S or (self.error is None and self.samples >= 2):
                    snap = self.renderer.snapshot(self.camera, stride=self.ERROR_STRIDE)
                    if snap is not None:
                        self.error = image_relative_error(snap)
                    last_error = t0
                prep = time.perf_counter() - t0
                self.prep_times.append(prep)
                interval = min(self.MAX_INTERVAL_S, max(self.MIN_INTERVAL_S, 20.0 * prep))
            except Exception:  # noqa: BLE001  (the display must never stop the render)
                traceback.print_exc()
                interval = self.MAX_INTERVAL_S

    def _refresh(self) -> bool:
        """Redo the rows that changed since the last look; whether any did."""
        changed = self.renderer.changed_rows(self.camera, self._version)
        if changed is None:
            return False
        first, end, version = changed
        for r0 in range(first, end, self.BLOCK_ROWS):
            got = self.renderer.total_sums(self.camera, rows=(r0, min(end, r0 + self.BLOCK_ROWS)))
            if got is None:
                return False
            r1 = r0 + got.total.shape[0]
            if got.n.size:
                self.samples = max(self.samples, int(got.n.max()))
            block = bandmod.total_to_rows(got.total, got.n, self.bands).reshape(r1 - r0, self.width, 4)
            with self._lock:
                lo, hi = self.height - r1, self.height - r0
                self._rows[lo:hi] = block
                self._dirty = (lo, hi) if self._dirty is None else (min(lo, self._dirty[0]),
                                                                    max(hi, self._dirty[1]))
                self._fresh = True
        self._version = version
        return True

    def show(self, write) -> bool:
        """Hand the newest image, when there is one not yet shown, to ``write(rows, span)``
        (rows: (H*W, 4) float32, bottom row first, valid during the call only; span: the
        (first, end) rows, bottom first, that changed since the last call); whether it was
        called."""
        with self._lock:
            if not self._fresh:
                return False
            self._fresh = False
            span, self._dirty = self._dirty or (0, self.height), None
            write(self._rows.reshape(-1, 4), span)
            return True

    def finish(self):
        """Stop, and the image as the sums stand now ((H*W, 4), bottom row first; None before
        the first piece of a pass): what a cancelled render keeps in its Combined pass."""
        self.stop()
        self._refresh()
        return self._rows.reshape(-1, 4) if self._version >= 0 else None

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()


def is_this_machine(host: str) -> bool:
    """Whether a scheduler host is this machine: a loopback IP address (127.0.0.0/8, ::1,
    parsed, not matched as text: 127.attacker.example is a name, resolved elsewhere), or the
    name 'localhost' when every address it resolves to is a loopback one. Any other name
    counts as another machine (what it resolves to may change)."""
    import ipaddress
    import socket
    host = host.strip().strip("[]")
    try:
        return ipaddress.ip_address(host.split("%", 1)[0]).is_loopback
    except ValueError:
        pass
    if host.lower().rstrip(".") != "localhost":
        return False
    try:
        infos = socket.getaddrinfo("localhost", None)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(i[4][0].split("%", 1)[0]).is_loopback for i in infos)


def remote_scheduler_refusal(address: str, allowed: bool) -> str | None:
    """Why a render must not go to the Dask scheduler at ``address``, or None: an address
    that is not one, or a plain tcp:// scheduler on another machine without the user's
    consent (Allow Unencrypted Remote Scheduler): a Dask scheduler runs the code its clients
    send, unauthenticated."""
    from photic.distributed import SchedulerError, check_scheduler_address
    try:
        scheme, host, _ = check_scheduler_address(address)
    except SchedulerError as exc:
        return f"Render > Photic > Dask Scheduler: {exc}"
    local = is_this_machine(host)
    if scheme == "tcp" and not local and not allowed:
        return (f"Render > Photic > Dask Scheduler: {address} is another machine over plain tcp:// "
                f"(unencrypted, unauthenticated: whoever reaches that scheduler runs code on its "
                f"workers). Use tls://, an SSH tunnel to 127.0.0.1, or tick 'Allow Unencrypted "
                f"Remote Scheduler' if you trust that network")
    return None


def raman_rendered(props) -> bool:
    """Whether a render with these Photic properties has Raman light: the engine's
    ``inelastic.raman_active`` for the settings and bands the export gives it (Blender needs
    the Raman pass declared before the render)."""
    mode = RAMAN_SETTING[props.raman]
    if mode != "auto":
        return mode
    photic = load_engine()
    if photic is None:
        return False  # (no engine: no render)
    try:
        bands = bandmod.scene_bands(props)
    except bandmod.BandError:
        return False  # (the export refuses these bands: no render)
    from photic.inelastic import raman_auto
    return raman_auto([photic.scene.Band(*b) for b in bands])


def fluorescing(scene, prop: str) -> bool:
    """Whether a render of ``scene`` has a water whose fluorescence ``prop`` is on (the engine
    then gives its component): a water object of the scene, not disabled in renders, with it
    on. (A water only in a collection excluded from the view layer still counts: its pass is
    then declared and left black.)"""
    from .natural_waters import WATER_ROLES
    for obj in scene.objects:
        p = getattr(getattr(obj, "original", obj), "photic", None)
        if p is not None and p.role in WATER_ROLES and getattr(p, prop) and not obj.hide_render:
            return True
    return False


def render_passes(scene) -> list[tuple[str, str, str]]:
    """(name, channels, type) of the passes a render of ``scene`` writes: Combined, the
    components and variance, the Raman pass when it has Raman light, the Chlorophyll and CDOM
    passes when a water fluoresces, and with Denoise or Denoising Data the denoising passes
    (named as Cycles names them, so the compositor's Denoise node takes them as it takes
    Cycles')."""
    out = [("Combined", "RGBA", "COLOR")] + [(n, "RGB", "COLOR") for n in PASS_NAMES]
    p = getattr(scene, "photic", None) if scene is not None else None
    if p is not None and raman_rendered(p):
        out.append((RAMAN_PASS, "RGB", "COLOR"))
    if p is not None:
        out += [(name, "RGB", "COLOR") for name, _, prop in FLUORESCENCE_PASSES
                if fluorescing(scene, prop)]
    if p is not None and (p.denoise or p.denoising_data):
        out += [(ALBEDO_PASS, "RGB", "COLOR"), (NORMAL_PASS, "XYZ", "VECTOR")]
    if p is not None and p.denoise:
        out.append((NOISY_PASS, "RGB", "COLOR"))
    return out


def image_passes(image, bands) -> dict:
    """The Combined, component (with Raman and fluorescence where the image has them) and
    variance passes of an engine ``ImageResult``, and with its denoising guides the Denoising
    Albedo and Normal passes."""
    out = {"Combined": bandmod.bands_to_rgba(image.mean, bands)}
    for name, comp in (*COMPONENT_PASSES, (RAMAN_PASS, "raman"),
                       *((name, comp) for name, comp, _ in FLUORESCENCE_PASSES)):
        if comp in image.components:
            out[name] = bandmod.bands_to_rgba(image.components[comp], bands)[:, :, :3]
    out[VARIANCE_PASS] = bandmod.bands_to_rgba(image.variance, bands, variance=True)[:, :, :3]
    albedo = getattr(image, "albedo", None)
    if albedo is not None:
        out[ALBEDO_PASS] = np.clip(bandmod.bands_to_rgba(albedo, bands)[:, :, :3], 0.0, 1.0)
        out[NORMAL_PASS] = np.asarray(image.normal, np.float32)
    return out


def denoise_passes(passes: dict) -> None:
    """Combined denoised by OpenImageDenoise with the guides among ``passes``, the noisy one
    kept as Noisy Image (in place; nothing changes when the denoiser raises)."""
    from photic.denoise import denoise_rgb
    noisy = passes["Combined"]
    clean = np.ones_like(noisy)
    clean[:, :, :3] = denoise_rgb(noisy[:, :, :3], passes.get(ALBEDO_PASS), passes.get(NORMAL_PASS))
    passes[NOISY_PASS] = noisy[:, :, :3].copy()
    passes["Combined"] = clean


def image_relative_error(image) -> float | None:
    """The image's noise as the eye meets it: the RMS over pixels and bands of each pixel's
    standard error, over the image's mean (what `photic bench --error` measures against a
    reference as RMS(x - ref) / mean(ref)). A median over pixels said 0 % for the stepped pool
    whose pool pixels had 16 % (its sky pixels, many and smooth, made the median). None while it
    cannot be estimated (fewer than 2 samples per pixel) or for a black image."""
    mean, var = np.asarray(image.mean, float), np.asarray(image.variance, float)
    m = float(np.mean(mean))
    if not np.all(np.isfinite(var)) or not m > 0:
        return None
    return float(np.sqrt(np.mean(var)) / m)


def radiometer_summary(result) -> list[dict]:
    """Rows for the Render panel: one per radiometer with values per band."""
    return [{"name": r.name, "quantity": r.quantity, "medium": r.medium,
             "value": r.mean[0].tolist(), "stderr": r.stderr[0].tolist(),
             "trusted": [bool(t) for t in (r.reliable[0] if getattr(r, "reliable", None) is not None
                                           else [True] * r.mean.shape[1])],
             "notes": list(getattr(r, "notes", [])),
             "bins": r.mean.shape[0], "units": r.units, "samples": int(r.samples),
             "target_error": getattr(r, "target_error", None),
             "target_reached": getattr(r, "target_reached", None)} for r in result.radiometers]


def table_stem(bscene, blend_path: str | None = None) -> tuple[Path, str]:
    """Directory and file stem of this frame's radiometer tables: those of the frame's render
    output (so a saved image and its tables share one stem, e.g. ``out/pool_0001.exr`` and
    ``out/pool_0001_radiometers.csv``). When the output is Blender's default, the temporary
    folder, they go beside the .blend file as ``<file>_<frame>`` instead (an unsaved file:
    the temporary folder, ``untitled_<frame>``)."""
    import bpy

    frame = bscene.frame_current
    path = Path(bscene.render.frame_path(frame=frame))
    temp = Path(tempfile.gettempdir()).resolve()
    raw = bscene.render.filepath.strip()
    if raw and path.parent.resolve() != temp:
        return path.parent, path.stem
    blend = blend_path if blend_path is not None else bpy.data.filepath
    if blend:
        return Path(blend).parent, f"{Path(blend).stem}_{frame:04d}"
    return temp, f"untitled_{frame:04d}"


def keep_results(scene) -> bool:
    """The last radiometer results of ``scene`` (LAST_RADIOMETERS) into its
    ``photic.last_results`` (JSON), so that they are saved with the .blend and shown again
    when it is opened; after a render job or the Render Radiometers operator, on the thread
    Blender runs its handlers on (a render must not edit scene data while it runs). Whether
    anything was kept."""
    import json
    last = LAST_RADIOMETERS.get(scene.name)
    props = getattr(scene, "photic", None)
    if last is None or props is None:
        return False
    text = json.dumps(last)
    if props.last_results != text:
        props.last_results = text
    return True


def shown_results(scene) -> dict | None:
    """The radiometer results the Radiometer Results panel shows: this session's last, else
    those saved in the .blend (``photic.last_results``); None when there are none."""
    import json
    last = LAST_RADIOMETERS.get(scene.name)
    if last is not None:
        return last
    text = getattr(getattr(scene, "photic", None), "last_results", "") or ""
    if not text:
        return None
    try:
        last = json.loads(text)
    except ValueError:
        return None
    return last if isinstance(last, dict) and "rows" in last else None


def short_units(units: str) -> str:
    """'W m^-2 sr^-1 (per unit of ...)' -> 'W m⁻² sr⁻¹' (the panel's column)."""
    head = units.split(" (", 1)[0]
    return head.replace("^-2", "⁻²").replace("^-1", "⁻¹")


def write_radiometer_results(photic, final, bscene, report) -> list[str]:
    """The radiometers of a finished (or cancelled) render: kept for the Radiometer Results
    panel, and written as tables beside the frame's output (``table_stem``) unless the scene
    turns them off. Radiometers that took no samples (a render cancelled before them) are left
    out, and nothing is written when none took any, so that a cancelled render never leaves
    tables of 0 +- 0 that look like results; a partial one says so in its tables.
    ``report(level, text)`` takes warnings. Returns the paths written."""
    done = [r for r in final.radiometers if r.samples > 0]
    if not done:
        if final.radiometers or final.cancelled:
            report("WARNING", "no radiometer results: the render was cancelled before any "
                              "radiometer took a sample")
        return []
    final.radiometers = done
    LAST_RADIOMETERS[bscene.name] = {"bands": [b.name for b in final.bands],
                                     "band_nm": [[float(b.center_nm), float(b.width_nm)] for b in final.bands],
                                     "rows": radiometer_summary(final),
                                     "cancelled": final.cancelled}
    if not bscene.photic.write_tables:
        return []
    out_dir, stem = table_stem(bscene)
    written = photic.output.write_outputs(out_dir, final, stem=f"{stem}", images=False)
    for failure in written["failed"]:  # each table on its own, kept elsewhere when it fails
        report("WARNING", f"radiometer table {failure}")
    paths = written["tables"]
    if paths:
        print("Photic: radiometer tables " + ", ".join(str(p) for p in paths))
    return [str(p) for p in paths] + [str(f.kept) for f in written["failed"] if f.kept]


class FinalRender:
    """One final render of a depsgraph by a RenderEngine (or a stand-in with its methods)."""

    def __init__(self, engine, depsgraph):
        self.engine = engine
        self.depsgraph = depsgraph
        self.summary = {"updates": 0, "update_times": [], "cancelled": False,
                        "cancel_latency_s": None, "tables": [], "error": None}
        self._fraction = 0.0

    # -- reporting ---------------------------------------------------------------------------
    def fail(self, message: str) -> None:
        self.summary["error"] = message
        print(f"Photic: {message}")
        self.engine.report({"ERROR"}, message)
        if hasattr(self.engine, "error_set"):
            self.engine.error_set(message)

    def stats(self, text: str) -> None:
        self.engine.update_stats("", f"Photic | {text}")
        if PROGRESS_HOOK is not None:
            PROGRESS_HOOK(self._fraction, text)

    def progress(self, fraction: float) -> None:
        self._fraction = fraction
        self.engine.update_progress(fraction)

    # -- the render --------------------------------------------------------------------------
    def run(self) -> dict:
        t0 = time.perf_counter()
        try:
            self._run(t0)
        except KeyboardInterrupt:  # outside the polling loop (the export): a cancel
            self.summary["cancelled"] = True
        except Exception as exc:  # never a crash of Blender: report and keep running
            traceback.print_exc()
            self.fail(f"internal error: {type(exc).__name__}: {exc} (details in the console)")
        self.summary["time_s"] = time.perf_counter() - t0
        self.summary["scene"] = getattr(getattr(self.depsgraph, "scene_eval", None), "name", None)
        LAST_RENDER.clear()
        LAST_RENDER.update(self.summary)
        return self.summary

    def _run(self, t0: float) -> None:
        photic = load_engine()
        if photic is None:
            self.fail(engine_error())
            return
        engine = self.engine
        bscene = self.depsgraph.scene_eval
        self.stats("exporting scene")

        def export_progress(fraction, text):
            self.progress(0.02 * fraction)
            self.stats(text)

        try:
            scene, info = export_scene(self.depsgraph, photic, progress=export_progress,
                                       test_break=lambda: stop_requested(engine))
        except ExportCancelled:
            self.summary["cancelled"] = True
            return
        except ExportError as exc:
            self.fail(str(exc))
            return
        except photic.scene.SceneError as exc:
            self.fail(str(exc))
            return
        scene_notes.remember(bscene.name, info)
        self.summary["export_warnings"] = list(info.warnings)
        for w in info.warnings:  # (each once, however many instances met it)
            engine.report({"WARNING"}, w)
        if EXPORT_HOOK is not None:
            EXPORT_HOOK(scene)
            return
        self.summary["export_s"] = info.time_s
        self.summary["triangles"] = info.triangles
        self.summary["instanced_meshes"] = info.instanced_meshes
        self.summary["instanced_copies"] = info.instanced_copies
        if info.instanced_meshes:  # (e.g. '3,200,000 triangles (10,000 copies of 1 mesh)')
            engine.report({"INFO"}, f"Photic: exported {info.describe()} in {info.time_s:.2f} s")
        bands = [(b.name, b.center_nm, b.width_nm) for b in scene.bands]
        camera = scene.cameras[0] if scene.cameras else None
        width, height = camera.resolution if camera else (1, 1)
        self._width = width
        address = (getattr(bscene.photic, "dask_scheduler", "") or "").strip()
        if address:
            self._run_distributed(photic, scene, bscene, address, bands, camera, t0)
            return

        props = bscene.photic
        self.denoise = bool(props.denoise)
        if self.denoise:
            from photic.denoise import denoiser, unavailable_reason

            from .oidn import use_blender_library
            use_blender_library(photic)  # (Blender's own OpenImageDenoise when it has one)
            self.summary["denoiser"] = denoiser()
            reason = unavailable_reason()
            if reason is not None:
                self.denoise = False
                engine.report({"WARNING"}, f"Photic: Denoise is off: {reason}. The image is left "
                                           f"noisy; the Denoising passes still work with the "
                                           f"compositor's Denoise node")
        try:
            renderer = photic.render.Renderer(scene, guides=bool(props.denoise or props.denoising_data))
        except photic.scene.SceneError as exc:
            self.fail(str(exc))
            return
        holder: dict = {}

        def work():
            try:
                holder["result"] = renderer.run()
            except Exception as exc:  # reported by the polling loop
                holder["error"] = exc
                traceback.print_exc()

        last = {"stats": 0.0, "frame": -FRAME_INTERVAL_S}
        display = (DisplayStream(renderer, camera.name, (width, height), bands)
                   if camera is not None and STREAM else None)

        def tick(result, now):
            if display is not None and now - last["frame"] >= FRAME_INTERVAL_S:
                # pixels prepared off this thread: only handed over here
                if display.show(lambda rows, span: self._show_rows(result, rows, now - t0, span)):
                    last["frame"] = now
            if now - last["stats"] >= UPDATE_INTERVAL_S:
                last["stats"] = now
                self._report_progress(renderer, display, now)

        def final_image():
            final = holder.get("result")
            return (final.images[camera.name] if final is not None and camera is not None
                    and camera.name in final.images else None)

        try:
            # Esc: the render view keeps the streamed image (the Combined pass; the others are
            # written by a render that finishes), brought up to the last piece of a pass, and
            # the engine skips assembling images nobody will see (a second at 1920 x 1080).
            self._poll(work, "photic-render", lambda: renderer.cancel(images=display is None), tick, final_image,
                       (width, height), bands, cancelled_rows=display.finish if display is not None else None)
        finally:
            if display is not None:
                display.stop()
                self.summary["display_prep_s"] = display.prep_times
        if "error" in holder:
            self.fail(f"render failed: {holder['error']}")
            return
        final = holder["result"]
        img = final.images.get(camera.name) if camera else None
        self.summary["samples"] = (img.samples if img is not None
                                   else display.samples if display is not None else 0)
        self.summary["stats"] = final.stats
        self.summary["warnings"] = list(final.warnings)
        for w in final.warnings:
            engine.report({"WARNING"}, f"Photic: {w}")
        self._radiometers(photic, final, bscene)
        self.progress(1.0)
        adaptive = ""
        if img is not None and img.noise_threshold is not None and img.pixel_samples is not None:
            adaptive = (f" (noise threshold: mean {float(np.mean(img.pixel_samples)):.0f}, "
                        f"{100 * float(np.mean(img.converged)):.0f} % of pixels reached it)")
        self.stats(f"{'cancelled, ' if final.cancelled else ''}{self.summary['samples']} "
                   f"samples{adaptive} in {final.stats['time_s']:.1f} s, "
                   f"{final.stats['segments_per_s'] / 1e6:.2f} M rays/s")

    def _run_distributed(self, photic, scene, bscene, address, bands, camera, t0) -> None:
        """The render as work units on the Dask scheduler at ``address``: the merged camera
        streams into the render view as units come back; the final image and radiometers are
        the exact merge, the same numbers as a render on this computer."""
        from photic.distributed import BatchStopped, CameraPreview, run_job, scene_job
        from photic.distributed.units import plan_round
        refusal = remote_scheduler_refusal(address, bool(getattr(bscene.photic, "dask_allow_remote", False)))
        if refusal is not None:
            self.fail(refusal)
            return

        width, height = camera.resolution if camera else (1, 1)
        if scene.settings.noise_threshold is not None:
            self.engine.report({"WARNING"}, "Noise Threshold is not applied on a Dask scheduler: "
                                            "every pixel takes all its samples")
        try:
            job = scene_job(scene, f"{bscene.name}_{bscene.frame_current:04d}")
        except photic.scene.SceneError as exc:
            self.fail(str(exc))
            return
        item = job.items[0]
        total = len(plan_round(item, job, 0))
        preview = CameraPreview(item, job) if camera is not None else None
        # Units are kept per scene fingerprint: rendering an unchanged frame again (or after
        # an interruption) reuses the units already computed.
        # (in this user's private cache: a shared, predictable /tmp/photic_dask let others
        # read the units or plant their own)
        from photic.distributed.store import cache_dir, private_dir
        try:
            cache = private_dir(cache_dir() / "dask") / item.fingerprint[:16]
        except OSError as exc:
            self.fail(f"Dask render: cannot keep its units: {exc}")
            return
        done = [0]
        stop = threading.Event()
        holder: dict = {}

        def on_unit(unit, res):
            done[0] += 1
            if preview is not None:
                preview.add(unit, res)

        def work():
            try:
                holder["report"] = run_job(
                    job, cache, scheduler=address, progress=False, on_unit_done=on_unit,
                    on_item_done=lambda _, r: holder.__setitem__("result", r),
                    should_stop=stop.is_set, write_results=False,
                    connect_timeout_s=DASK_CONNECT_TIMEOUT_S)
            except BatchStopped:
                pass
            except Exception as exc:  # reported by the polling loop
                holder["error"] = exc
                traceback.print_exc()

        self.stats(f"connecting to the Dask scheduler {address}")
        last = {"write": -UPDATE_INTERVAL_S, "stats": 0.0, "version": 0}

        def tick(result, now):
            # New units in: shown at once, then at most twice a second.
            if (preview is not None and preview.version != last["version"]
                    and now - last["write"] >= UPDATE_INTERVAL_S):
                last["version"], last["write"] = preview.version, now
                self._show(result, preview.image(), bands, now - t0)
            if now - last["stats"] >= UPDATE_INTERVAL_S:
                last["stats"] = now
                self.progress(0.02 + 0.98 * done[0] / max(1, total))
                self.stats(f"Dask {address}: {done[0]}/{total} units")

        def final_image():
            final = holder.get("result")
            if final is not None and camera is not None:
                return final.images.get(camera.name)
            return preview.image() if preview is not None else None

        self._poll(work, "photic-dask", stop.set, tick, final_image, (width, height), bands)
        final = holder.get("result")
        report = holder.get("report")
        self.summary["distributed"] = {"scheduler": address, "units": total, "cache": str(cache)}
        if report is not None:
            self.summary["distributed"].update(computed=len(report.computed), reused=len(report.skipped))
        if "error" in holder:
            self.fail(f"render on the Dask scheduler {address} failed: {holder['error']}")
            return
        if final is None:
            if report is not None and report.failed:
                key, why = next(iter(report.failed.items()))
                self.fail(f"{len(report.failed)} work unit(s) failed on {address} (first: {key}: {why})")
            return  # cancelled: the partial image is kept
        img = final.images.get(camera.name) if camera else None
        self.summary["samples"] = img.samples if img is not None else 0
        self.summary["stats"] = final.stats
        self._radiometers(photic, final, bscene)
        self.progress(1.0)
        self.stats(f"{self.summary['samples']} samples, {total} units on Dask {address} in "
                   f"{time.perf_counter() - t0:.1f} s")

    def _poll(self, work, name: str, cancel, tick, final_image, size, bands, cancelled_rows=None) -> None:
        """Run work() in a thread while Blender waits, polling every POLL_S: Esc calls cancel()
        (once), otherwise tick(result, now) may update the render view. At the end, or after an
        error in the loop (then cancel() first), the thread is joined, the cancel latency
        recorded and final_image() (when not None) written into the render result; without one,
        after Esc, cancelled_rows() (when given and not None) as its Combined pass."""
        engine = self.engine
        # The worker runs at the interface's priority until the first pixels are shown (in
        # Blender's UI under load, at nice +4 they came 1.1-2.5 s after render() was called, at
        # nice 0 1.1-1.2 s), then at RENDER_NICE lower (Esc: the interface must get the CPU).
        worker = {}
        thread = threading.Thread(target=lambda: (worker.setdefault("tid", threading.get_native_id()),
                                                  work()), name=name, daemon=True)
        result = engine.begin_result(0, 0, *size)
        cancel_at = None
        try:
            thread.start()
            while thread.is_alive():
                interrupted = False
                try:
                    thread.join(POLL_S)
                except KeyboardInterrupt:  # Ctrl-C where Python raises it: a cancel, as Esc
                    interrupted = True
                now = time.perf_counter()
                if cancel_at is None and (interrupted or stop_requested(engine)):
                    cancel_at = now
                    cancel()
                    self.stats("cancelling")
                if cancel_at is None:
                    tick(result, now)
                if "lowered" not in worker and "tid" in worker and (
                        self.summary["updates"] or cancel_at is not None):
                    worker["lowered"] = True
                    lower_priority(worker["tid"])
        finally:
            if thread.is_alive():  # an exception in the loop: stop the worker first
                cancel()
            # Joined whatever happens: a worker left running when the interpreter unwinds
            # aborts the process (SIGABRT, 'terminate called without an active exception').
            while thread.is_alive():
                try:
                    thread.join()
                except KeyboardInterrupt:
                    cancel()
            if cancel_at is not None:
                self.summary["cancelled"] = True
                self.summary["cancel_at"] = cancel_at  # (perf_counter: when test_break said so)
                self.summary["cancel_latency_s"] = time.perf_counter() - cancel_at
            image = final_image()
            if image is not None:
                passes = self._write(result, image, bands, final=True)
                stops = bandmod.auto_exposure(passes["Combined"])
                if stops is not None:
                    self.summary["auto_exposure"] = stops
                    self._expose(stops)
            elif cancel_at is not None and cancelled_rows is not None:
                rows = cancelled_rows()
                if rows is not None:
                    write_rows(self._pass(result, "Combined"), rows)
            engine.end_result(result)

    def _expose(self, stops: float) -> None:
        """Auto Exposure: the scene's display exposure set before render() returns, because
        Blender writes a frame's file (``-f``, ``-a``, an animation from the UI) after render()
        and before any handler runs, with the scene's view settings then: set later (the
        render_complete handler, which still sets it for stand-ins), every 8-bit file was
        saved with the exposure the scene had before. The Combined pass, the EXR and the
        tables keep their radiometric values. Each frame of an animation gets its own."""
        scene = getattr(self.depsgraph, "scene", None)
        scene = getattr(scene, "original", scene)
        props = getattr(scene, "photic", None)
        if props is None or not props.auto_exposure or not hasattr(scene, "view_settings"):
            return
        try:
            scene.view_settings.exposure = stops
        except (AttributeError, TypeError, RuntimeError) as exc:  # (a read-only scene)
            print(f"Photic: auto exposure not set: {exc}")

    def _show(self, result, image, bands, t: float) -> None:
        """A streamed update of the render view, t seconds into the render."""
        self._write(result, image, bands)
        self.engine.update_result(result)
        self.summary["updates"] += 1
        self.summary["update_times"].append(t)

    def _write(self, result, image, bands, final: bool = False) -> dict:
        """Write an image's passes into the render result; ``final``: the finished render's,
        denoised when asked."""
        passes = image_passes(image, bands)
        if final and getattr(self, "denoise", False):
            t0 = time.perf_counter()
            try:
                denoise_passes(passes)
                self.summary["denoise_s"] = time.perf_counter() - t0
            except Exception as exc:  # noqa: BLE001  (the denoiser failed: keep the render, noisy)
                traceback.print_exc()
                self.engine.report({"WARNING"}, f"Photic: denoising failed ({type(exc).__name__}: "
                                                f"{exc}); the image is left noisy")
        for name, pixels in passes.items():
            p = self._pass(result, name)
            if p is not None:
                set_rect(p, pixels)
        return passes

    @staticmethod
    def _pass(result, name: str):
        """A pass of the render result by name, None when it has none of that name (Blender's
        passes collection, or a stand-in's dict)."""
        passes = result.layers[0].passes
        if hasattr(passes, "get"):
            return passes.get(name)
        try:
            return passes[name]
        except (KeyError, IndexError):
            return None

    #: A streamed update whose changed rows are less than this fraction of the image goes to
    #: the render view as a tile of those rows (a result of its own, ended at once), else as
    #: the whole image (update_result).
    TILE_FRACTION = 0.5

    def _show_rows(self, result, frame, t: float, span=None) -> None:
        """A streamed update of the render view: the Combined pass only (the others are
        written once, at the end), from rows the display thread prepared. Blender merges every
        pass of a result it is given and converts it for display, holding the interpreter
        lock (0.05-0.4 s for 1920 x 1080): a few changed rows (the first pixels, a piece of a
        pass) go as a tile of those rows only."""
        engine = self.engine
        height = len(frame) // max(1, self._width)
        if span is not None and 0 < span[1] - span[0] < self.TILE_FRACTION * height:
            lo, hi = span
            tile = engine.begin_result(0, lo, self._width, hi - lo)
            try:
                write_rows(self._pass(tile, "Combined"), frame[lo * self._width:hi * self._width])
            finally:
                engine.end_result(tile)
        else:
            write_rows(self._pass(result, "Combined"), frame)
            engine.update_result(result)
        self.summary["updates"] += 1
        self.summary["update_times"].append(t)

    def _report_progress(self, renderer, display, now) -> None:
        self.progress(0.02 + 0.98 * renderer.progress)
        elapsed = now - (renderer.t_start or now)
        rays = renderer.counters["segments"] / elapsed if elapsed > 0 else 0.0
        text = f"{rays / 1e6:.2f} M rays/s"
        if display is not None and display.samples:
            err = display.error
            noise = ("error: 2 samples per pixel needed" if err is None
                     else f"error {100 * err:.1f}% (image RMS, 1 sigma)")
            text = f"sample {display.samples}/{renderer.samples} | {text} | {noise}"
        remaining = elapsed * (1 - renderer.progress) / renderer.progress if renderer.progress > 0 else None
        if remaining is not None:
            text += f" | {remaining:.0f} s left"
        self.stats(text)

    def _radiometers(self, photic, final, bscene) -> None:
        if not final.radiometers and not final.cancelled:
            return
        self.summary["tables"] = write_radiometer_results(
            photic, final, bscene, lambda level, text: self.engine.report({level}, text))
