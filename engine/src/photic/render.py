"""Progressive rendering of a scene: cameras and radiometers, with Monte Carlo errors.

Work is split into passes whose boundaries depend only on the sample counts, never on the
thread count, and the core sums each pass in a fixed order, so one seed gives the same numbers
bit for bit on any number of threads. Every pass reports progress; a cancel stops at the next
pass boundary (or sooner: the core checks its flag between rows and chunks) and the result
keeps only completed passes.
"""
from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .compile import band_groups, compile_scene
from .scene import IOPGrid, IOPProfile, Scene, SceneError

RADIOMETER_PASS = 1 << 16  # samples per radiometer pass (a multiple of the core's chunk)
UNITS_RADIANCE = "W m^-2 sr^-1 (per unit of the band's source spectrum, e.g. nm^-1)"
UNITS_IRRADIANCE = "W m^-2 (per unit of the band's source spectrum, e.g. nm^-1)"
IRRADIANCE_QUANTITIES = {"Ed", "Eu", "Eo", "Eod", "Eou"}


COMPONENTS = ("beam_surface", "beam_volume", "path", "beam_direct")


@dataclass
class ImageResult:
    name: str
    mean: np.ndarray          # (H, W, nbands) radiance
    variance: np.ndarray      # (H, W, nbands) variance of the per-pixel mean (standard error^2)
    samples: int              # samples per pixel
    components: dict = field(default_factory=dict)  # name -> (H, W, nbands) mean

    @property
    def units(self) -> str:
        return UNITS_RADIANCE


@dataclass
class RadiometerResult:
    name: str
    quantity: str
    position: np.ndarray
    medium: str               # "air" or the water body's name
    mean: np.ndarray          # (nbins, nbands); nbins = 1 except radiance distributions
    stderr: np.ndarray        # (nbins, nbands)
    samples: int              # total samples (shared by the bins of a distribution)
    bins: tuple[int, int] | None = None  # (polar, azimuth) for radiance distributions
    components: dict = field(default_factory=dict)  # name -> (mean, stderr), each (nbins, nbands)

    @property
    def units(self) -> str:
        return UNITS_IRRADIANCE if self.quantity in IRRADIANCE_QUANTITIES else UNITS_RADIANCE


@dataclass
class RenderResult:
    scene_name: str
    bands: list
    images: dict[str, ImageResult] = field(default_factory=dict)
    radiometers: list[RadiometerResult] = field(default_factory=list)
    stats: dict = field(default_factory=dict)
    cancelled: bool = False

    def radiometer(self, name: str) -> RadiometerResult:
        for r in self.radiometers:
            if r.name == name:
                return r
        raise KeyError(name)


def resolve_integrator(scene: Scene) -> str:
    """'hybrid' or 'path': the scene's choice, 'auto' meaning hybrid when there is a sun."""
    choice = scene.settings.integrator
    if choice == "auto":
        return "hybrid" if scene.sun is not None else "path"
    return choice



def optical_depth_scale(scene: Scene) -> float:
    """The largest attenuation depth c * D over the water bodies and bands (D: bottom depth,
    mesh height; infinite for a bottomless ocean)."""
    tau = 0.0
    for w in scene.water:
        if w.type == "ocean":
            depth = np.inf if w.bottom_depth is None else float(w.bottom_depth)
            top = float(w.surface.z)
        else:
            z = np.asarray(w.mesh.vertices)[:, 2]
            depth = float(z.max() - z.min())
            top = float(z.max())
        if isinstance(w.iops, IOPGrid):  # 3-D: bounded by the densest voxel everywhere
            g = w.iops
            unit = 0.0
            for rho, u in zip(g.densities(), g.units()):
                rmax = float(np.max(rho)) if np.size(rho) else 0.0
                unit = unit + rmax * (np.asarray(u.absorption) + np.asarray(u.total_scattering))
            for b in (g.iops.layers if isinstance(g.iops, IOPProfile) else [g.iops]):
                c = float(np.max(np.asarray(b.absorption) + np.asarray(b.total_scattering) + unit))
                tau = max(tau, c * depth if c > 0 else 0.0)
            continue
        if isinstance(w.iops, IOPProfile):  # stratified: the vertical column's optical depth
            tau = max(tau, _profile_optical_depth(w.iops, top, top - depth))
            continue
        c = float(np.max(np.asarray(w.iops.absorption) + np.asarray(w.iops.total_scattering)))
        tau = max(tau, c * depth if c > 0 else 0.0)
    return tau


def _profile_optical_depth(profile: IOPProfile, z_hi: float, z_lo: float) -> float:
    """Largest over bands of int (a + b) dz from z_lo to z_hi (m) through the layers."""
    tops = np.asarray(profile.z_top, dtype=np.float64)
    total = 0.0
    for i, layer in enumerate(profile.layers):
        hi = z_hi if i == 0 else min(z_hi, tops[i])
        lo = max(z_lo, tops[i + 1]) if i + 1 < len(tops) else z_lo
        if hi > lo:
            c = np.asarray(layer.absorption) + np.asarray(layer.total_scattering)
            total = total + np.array([ck * (hi - lo) if ck > 0 else 0.0 for ck in c])
    return float(np.max(total))


AUTO_CONE_TAU = 10.0       # optically deeper than this: use a forward cone
AUTO_CONE_DEG = 3.0        # its half-angle


def resolve_forward_cone(scene: Scene) -> float:
    """Forward-scattering cone half-angle (degrees) for the hybrid integrator.

    The rule ('auto'): shallow or clear water (c * depth <= 10) keeps the full phase function,
    which is exact and cheap there; optically deeper water keeps the light scattered within
    3 degrees of the beam in the beam (c_beam = a + b (1 - f)), which removes the rare, very
    bright paths that head straight at the refracted sun. The error of each choice on the
    canonical problems is measured by `photic bench --error` (docs/benchmarks.md).
    """
    value = scene.settings.forward_cone_deg
    if value != "auto":
        return float(value)
    return AUTO_CONE_DEG if optical_depth_scale(scene) > AUTO_CONE_TAU else 0.0


GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def sun_direction_in_disk(scene: Scene, i: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """Direction ``i`` of ``n`` stratified over the sun's disk (equal solid angles, a
    Fibonacci spiral randomly rotated and jittered by ``rng``): the beams of n passes together
    sample the whole disk evenly, so soft caustic edges converge with the passes."""
    s = np.asarray(scene.sun.direction, float)
    alpha = np.radians(scene.sun.angular_diameter_deg) / 2
    u0, phi0 = rng.random(), 2 * np.pi * rng.random()
    cos_t = 1.0 - ((i % n) + u0) / n * (1.0 - np.cos(alpha))
    phi = phi0 + GOLDEN_ANGLE * i
    a = np.array([1.0, 0.0, 0.0]) if abs(s[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(s, a); u /= np.linalg.norm(u)
    v = np.cross(s, u)
    sin_t = np.sqrt(max(0.0, 1 - cos_t * cos_t))
    d = cos_t * s + sin_t * (np.cos(phi) * u + np.sin(phi) * v)
    return d / np.linalg.norm(d)


def _bin_counts(total: int, nbins: int) -> np.ndarray:
    """Samples per bin when sample i goes to bin i % nbins."""
    counts = np.full(nbins, total // nbins, dtype=np.int64)
    counts[: total % nbins] += 1
    return counts


def _mean_stderr(s: np.ndarray, s2: np.ndarray, n) -> tuple[np.ndarray, np.ndarray]:
    n = np.asarray(n, dtype=np.float64)
    nn = np.maximum(n, 1.0)
    mean = s / nn
    var = np.maximum(s2 / nn - mean * mean, 0.0) * nn / np.maximum(nn - 1.0, 1.0)
    return mean, np.sqrt(var / nn)


# --- pieces shared with photic.distributed, whose work units must reproduce these passes -----

def camera_passes(samples: int) -> list[tuple[int, int]]:
    """(first sample, count) of each camera pass: 1, 2, 4, 8, then 16 samples per pixel."""
    passes, start, size = [], 0, 1
    while start < samples:
        n = min(size, samples - start)
        passes.append((start, n))
        start += n
        size = min(size * 2, 16)
    return passes


def radiometer_passes(samples: int, hybrid: bool) -> list[tuple[int, int]]:
    """(first sample, count) of each radiometer pass.

    The hybrid integrator draws a sun direction per pass: at least 64 passes (of 4,096 to
    65,536 samples) so the disk is sampled evenly and its spread stays well inside the
    reported standard error."""
    size = RADIOMETER_PASS
    if hybrid:
        size = int(np.clip(-(-samples // 64) // 1024 * 1024, 4096, RADIOMETER_PASS))
    return [(s, min(size, samples - s)) for s in range(0, samples, size)]


def build_pass_beams(core, scene: Scene, seed: int, gi: int, key: tuple, i: int, n: int,
                     threads: int) -> None:
    """Before pass ``i`` of ``n`` of the hybrid integrator: beams for direction i of n drawn in
    the sun's disk (deterministic per seed, band group ``gi`` and sensor ``key``)."""
    rng = np.random.default_rng([seed, gi, *key])
    direction = tuple(sun_direction_in_disk(scene, i, n, rng))
    if core.ocean_rough:
        # The sub-pixel facet(s) of the rough surface for this build, stratified over
        # the passes like the sun's disk.
        r = rng.random(2)
        core.build_beams(direction, threads,
                         ((i + r[0]) / n, (r[1] + i * 0.6180339887498949) % 1.0))
    else:
        core.build_beams(direction, threads)


def image_result(name: str, s: np.ndarray, s2: np.ndarray, n: int) -> ImageResult:
    """A camera's result from its sums (H, W, components + 1, nbands) over ``n`` samples."""
    mean, err = _mean_stderr(s, s2, n)
    comps = {c: mean[:, :, i + 1, :] for i, c in enumerate(COMPONENTS[:3])}
    return ImageResult(name, mean[:, :, 0, :], err[:, :, 0, :] ** 2, n, comps)


def radiometer_result(r, medium: str, s: np.ndarray, s2: np.ndarray, done: int,
                      batch=None) -> RadiometerResult:
    """A radiometer's result from its sums (nbins, components + 1, nbands) over ``done``
    samples; ``batch``: [sum, sum of squares, count] of the hybrid integrator's pass means."""
    nbins = s.shape[0]
    counts = _bin_counts(done, nbins)[:, None, None]
    mean, err = _mean_stderr(s, s2, counts)
    if batch is not None:
        bs, bs2, bn = batch
        k = np.maximum(bn, 2.0)
        var = np.maximum(0.0, bs2 - bs * bs / k) / (k - 1.0)
        err = np.where(bn >= 4, np.maximum(err, np.sqrt(var / k)), err)
    bins = (r.polar_bins, r.azimuth_bins) if r.quantity == "radiance_distribution" else None
    comps = {c: (mean[:, i + 1, :], err[:, i + 1, :]) for i, c in enumerate(COMPONENTS)}
    return RadiometerResult(r.name, r.quantity, np.asarray(r.position, float), medium,
                            mean[:, 0, :], err[:, 0, :], done, bins, comps)


def add_pass(sums, batch, g, s, s2, n: int) -> None:
    """Adds one pass of n samples (sums s, s2) to a sensor's [sum, sum of squares] in band
    group g and, when ``batch`` ([sum, sum of squares, count] of the pass means) is given, its
    mean to the batch means. Renderer.run and the distributed merge both add passes here, in
    the same order, so that their results agree bit for bit."""
    if batch is not None:
        pm = s / (n / s.shape[0])
        batch[0][..., g] += pm
        batch[1][..., g] += pm * pm
        batch[2][g] += 1
    sums[0][..., g] += s
    sums[1][..., g] += s2


class Renderer:
    """Renders a validated scene progressively.

    Parameters override the scene's settings: ``samples`` per pixel, ``radiometer_samples`` per
    radiometer, ``seed``, ``threads`` (0 = all cores).
    """

    def __init__(self, scene: Scene, samples: int | None = None, radiometer_samples: int | None = None,
                 seed: int | None = None, threads: int | None = None):
        scene.validate()
        st = scene.settings
        self.integrator = resolve_integrator(scene)
        self.forward_cone_deg = resolve_forward_cone(scene) if self.integrator == "hybrid" else 0.0
        self.scene = scene
        self.samples = int(st.samples if samples is None else samples)
        self.radiometer_samples = int(st.radiometer_samples if radiometer_samples is None else radiometer_samples)
        self.seed = int(st.seed if seed is None else seed)
        self.threads = int(st.threads if threads is None else threads)
        for what, value, hi in (("samples", self.samples, 10**6),
                                ("radiometer_samples", self.radiometer_samples, 10**10)):
            if not 1 <= value <= hi:
                raise SceneError("settings", what, f"must be in 1..{hi}, got {value}")
        if not 0 <= self.threads <= 1024:
            raise SceneError("settings", "threads", f"must be in 0..1024, got {self.threads}")
        self._cancel = threading.Event()
        self._core = None
        # Running sums of the cameras, readable while rendering (snapshot) under the lock.
        self._lock = threading.Lock()
        self._cam_sums: dict = {}
        self._cam_done: dict = {}
        self.progress = 0.0
        self.counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
        self.t_start = None

    def cancel(self) -> None:
        """Stop as soon as possible (safe to call from another thread)."""
        self._cancel.set()
        core = self._core
        if core is not None:
            core.cancel()

    def snapshot(self, camera: str) -> ImageResult | None:
        """The current estimate of a camera while it renders (None before its first pass).

        Safe to call from another thread: passes are added under a lock, so the sums and the
        sample count always belong together."""
        with self._lock:
            if camera not in self._cam_sums or not self._cam_done.get(camera):
                return None
            n = self._cam_done[camera]
            s, s2 = (a.copy() for a in self._cam_sums[camera])
        return image_result(camera, s, s2, n)

    def _camera_passes(self) -> list[tuple[int, int]]:
        return camera_passes(self.samples)

    def run(self, progress=None) -> RenderResult:
        """Render everything; ``progress(fraction, message)`` is called after every pass."""
        scene = self.scene
        radiometers = scene.all_radiometers()
        nb = len(scene.bands)
        nc = len(COMPONENTS) + 1  # the core's layout: total, then the components
        groups = band_groups(nb)
        threads = self.threads or (os.cpu_count() or 1)
        hybrid = self.integrator == "hybrid"
        result = RenderResult(scene.name, list(scene.bands))
        cam_sums = self._cam_sums = {c.name: [np.zeros((c.resolution[1], c.resolution[0], nc, nb))
                                              for _ in range(2)] for c in scene.cameras}
        cam_done = self._cam_done = {c.name: 0 for c in scene.cameras}
        rad_sums, rad_done, rad_batch = [], [0] * len(radiometers), []
        cam_passes = self._camera_passes()
        rad_passes = radiometer_passes(self.radiometer_samples, hybrid)
        total_work = len(groups) * (sum(c.resolution[0] * c.resolution[1] * self.samples for c in scene.cameras)
                                    + len(radiometers) * self.radiometer_samples)
        done_work = 0
        counters = self.counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
        media = [None] * len(radiometers)
        beam_stats = {"passes": 0, "prisms": 0, "build_s": 0.0}
        t0 = self.t_start = time.perf_counter()
        buffers: dict = {}  # per shape, the passes' output arrays (reused: fresh ones fault per page)

        def out(shape):
            if shape not in buffers:
                buffers[shape] = (np.empty(shape), np.empty(shape))
            return buffers[shape]

        def add_counts(c):
            for k in counters:
                counters[k] += int(c[k])

        def new_pass(core, gi, key, i, n):
            """Before every pass of the hybrid integrator: beams for direction i of n drawn in
            the sun's disk (deterministic per seed, band group and sensor)."""
            if not hybrid:
                return
            tb = time.perf_counter()
            build_pass_beams(core, scene, self.seed, gi, key, i, n, self.threads)
            beam_stats["build_s"] += time.perf_counter() - tb
            beam_stats["passes"] += 1
            beam_stats["prisms"] = max(beam_stats["prisms"], core.beam_count)

        def run_passes(core, gi, g, key, passes, render_pass, sums, done, done_key, work_per_sample,
                       label, total, batch=None):
            """Render one sensor's passes into its sums; False when cancelled (the cancelled
            pass is dropped). ``batch``: [sum, sum of squares, count] of the pass means."""
            nonlocal done_work
            for pi, (start, n) in enumerate(passes):
                new_pass(core, gi, key, pi, len(passes))
                s, s2, c = render_pass(start, n)
                if core.cancelled:
                    return False
                with self._lock:
                    add_pass(sums, batch, g, s, s2, n)
                    if gi == 0:
                        done[done_key] = start + n
                    add_counts(c)
                    done_work += work_per_sample * n
                    self.progress = done_work / total_work
                if progress:
                    progress(done_work / total_work, f"{label}: {start + n}/{total} samples")
            return True

        cancelled = False
        for gi, g in enumerate(groups):
            core = compile_scene(scene, g, seed=self.seed, hybrid=hybrid,
                                 forward_cone_deg=self.forward_cone_deg, threads=self.threads)
            self._core = core
            if self._cancel.is_set():
                core.cancel()
            for ri in range(len(radiometers)):
                m = core.radiometer_medium(ri)
                media[ri] = "air" if m < 0 else scene.water[m].name
                if gi == 0:
                    nbins = core.radiometer_bins(ri)
                    rad_sums.append([np.zeros((nbins, nc, nb)), np.zeros((nbins, nc, nb))])
            for ci, cam in enumerate(scene.cameras):
                ok = run_passes(core, gi, g, (0, ci), cam_passes, lambda st, n, ci=ci, cam=cam: core.render_camera(
                                    ci, st, n, self.threads, out((cam.resolution[1], cam.resolution[0], nc, g.stop - g.start))),
                                cam_sums[cam.name], cam_done, cam.name,
                                cam.resolution[0] * cam.resolution[1], f"camera {cam.name}", self.samples)
                if not ok:
                    cancelled = True
                    break
            # The hybrid integrator builds its beams once per pass (a sun direction in the disk,
            # and with a rough ocean other sub-pixel facets): that variation between passes is
            # not in the per-sample variance, so the standard error also comes from the spread
            # of the pass means (batch means), the larger one kept.
            batch_means = hybrid
            for ri, r in enumerate(radiometers):
                if cancelled:
                    break
                if batch_means and len(rad_batch) <= ri:
                    shape = rad_sums[ri][0].shape
                    rad_batch.append([np.zeros(shape), np.zeros(shape), np.zeros(nb)])
                ok = run_passes(core, gi, g, (1, ri), rad_passes, lambda st, n, ri=ri: core.render_radiometer(
                                    ri, st, n, self.threads, out(rad_sums[ri][0].shape[:-1] + (g.stop - g.start,))),
                                rad_sums[ri], rad_done, ri, 1, f"radiometer {r.name}", self.radiometer_samples,
                                rad_batch[ri] if batch_means else None)
                if not ok:
                    cancelled = True
                    break
            if cancelled:
                break
        self._core = None
        elapsed = time.perf_counter() - t0

        for cam in scene.cameras:
            result.images[cam.name] = image_result(cam.name, *cam_sums[cam.name], cam_done[cam.name])
        for ri, r in enumerate(radiometers):
            if ri >= len(rad_sums):
                break
            result.radiometers.append(radiometer_result(
                r, media[ri] or "air", *rad_sums[ri], rad_done[ri],
                rad_batch[ri] if ri < len(rad_batch) else None))
        result.cancelled = cancelled
        result.stats = dict(counters, time_s=elapsed, threads=threads, seed=self.seed,
                            samples=self.samples, radiometer_samples=self.radiometer_samples,
                            segments_per_s=counters["segments"] / elapsed if elapsed > 0 else 0.0,
                            band_groups=len(groups), integrator=self.integrator,
                            forward_cone_deg=self.forward_cone_deg,
                            beam_passes=beam_stats["passes"], beam_prisms=beam_stats["prisms"],
                            beam_build_s=beam_stats["build_s"])
        return result


def render(scene: Scene, progress=None, **overrides) -> RenderResult:
    """Render a scene (see Renderer for the overrides)."""
    return Renderer(scene, **overrides).run(progress)
