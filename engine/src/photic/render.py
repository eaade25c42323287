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
from .scene import Scene, SceneError

RADIOMETER_PASS = 1 << 16  # samples per radiometer pass (a multiple of the core's chunk)
UNITS_RADIANCE = "W m^-2 sr^-1 (per unit of the band's source spectrum, e.g. nm^-1)"
UNITS_IRRADIANCE = "W m^-2 (per unit of the band's source spectrum, e.g. nm^-1)"
IRRADIANCE_QUANTITIES = {"Ed", "Eu", "Eo", "Eod", "Eou"}


@dataclass
class ImageResult:
    name: str
    mean: np.ndarray          # (H, W, nbands) radiance
    variance: np.ndarray      # (H, W, nbands) variance of the per-pixel mean (standard error^2)
    samples: int              # samples per pixel

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


class Renderer:
    """Renders a validated scene progressively.

    Parameters override the scene's settings: ``samples`` per pixel, ``radiometer_samples`` per
    radiometer, ``seed``, ``threads`` (0 = all cores).
    """

    def __init__(self, scene: Scene, samples: int | None = None, radiometer_samples: int | None = None,
                 seed: int | None = None, threads: int | None = None):
        scene.validate()
        st = scene.settings
        if st.integrator != "path":
            raise SceneError("settings", "integrator",
                             f"integrator {st.integrator!r} is not available in this version; use 'path'")
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

    def cancel(self) -> None:
        """Stop as soon as possible (safe to call from another thread)."""
        self._cancel.set()
        core = self._core
        if core is not None:
            core.cancel()

    def _camera_passes(self) -> list[tuple[int, int]]:
        passes, start, size = [], 0, 1
        while start < self.samples:
            n = min(size, self.samples - start)
            passes.append((start, n))
            start += n
            size = min(size * 2, 16)
        return passes

    def run(self, progress=None) -> RenderResult:
        """Render everything; ``progress(fraction, message)`` is called after every pass."""
        scene = self.scene
        radiometers = scene.all_radiometers()
        nb = len(scene.bands)
        groups = band_groups(nb)
        threads = self.threads or (os.cpu_count() or 1)
        result = RenderResult(scene.name, list(scene.bands))
        cam_sums = {c.name: [np.zeros((c.resolution[1], c.resolution[0], nb)) for _ in range(2)]
                    for c in scene.cameras}
        cam_done = {c.name: 0 for c in scene.cameras}
        rad_sums, rad_done = [], [0] * len(radiometers)
        cam_passes = self._camera_passes()
        rad_passes = [(s, min(RADIOMETER_PASS, self.radiometer_samples - s))
                      for s in range(0, self.radiometer_samples, RADIOMETER_PASS)]
        total_work = len(groups) * (sum(c.resolution[0] * c.resolution[1] * self.samples for c in scene.cameras)
                                    + len(radiometers) * self.radiometer_samples)
        done_work = 0
        counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
        media = [None] * len(radiometers)
        t0 = time.perf_counter()

        def add_counts(c):
            for k in counters:
                counters[k] += int(c[k])

        cancelled = False
        for gi, g in enumerate(groups):
            core = compile_scene(scene, g, seed=self.seed)
            self._core = core
            if self._cancel.is_set():
                core.cancel()
            for ri in range(len(radiometers)):
                m = core.radiometer_medium(ri)
                media[ri] = "air" if m < 0 else scene.water[m].name
                if gi == 0:
                    nbins = core.radiometer_bins(ri)
                    rad_sums.append([np.zeros((nbins, nb)), np.zeros((nbins, nb))])
            for ci, cam in enumerate(scene.cameras):
                for start, n in cam_passes:
                    s, s2, c = core.render_camera(ci, start, n, self.threads)
                    if core.cancelled:
                        cancelled = True
                        break
                    cam_sums[cam.name][0][..., g] += s
                    cam_sums[cam.name][1][..., g] += s2
                    if gi == 0:
                        cam_done[cam.name] = start + n
                    add_counts(c)
                    done_work += cam.resolution[0] * cam.resolution[1] * n
                    if progress:
                        progress(done_work / total_work, f"camera {cam.name}: {start + n}/{self.samples} samples")
                if cancelled:
                    break
            for ri, r in enumerate(radiometers):
                if cancelled:
                    break
                for start, n in rad_passes:
                    s, s2, c = core.render_radiometer(ri, start, n, self.threads)
                    if core.cancelled:
                        cancelled = True
                        break
                    rad_sums[ri][0][:, g] += s
                    rad_sums[ri][1][:, g] += s2
                    if gi == 0:
                        rad_done[ri] = start + n
                    add_counts(c)
                    done_work += n
                    if progress:
                        progress(done_work / total_work, f"radiometer {r.name}: {start + n}/{self.radiometer_samples} samples")
            if cancelled:
                break
        self._core = None
        elapsed = time.perf_counter() - t0

        for cam in scene.cameras:
            n = cam_done[cam.name]
            mean, err = _mean_stderr(cam_sums[cam.name][0], cam_sums[cam.name][1], n)
            result.images[cam.name] = ImageResult(cam.name, mean, err ** 2, n)
        for ri, r in enumerate(radiometers):
            if ri >= len(rad_sums):
                break
            nbins = rad_sums[ri][0].shape[0]
            counts = _bin_counts(rad_done[ri], nbins)[:, None]
            mean, err = _mean_stderr(rad_sums[ri][0], rad_sums[ri][1], counts)
            bins = (r.polar_bins, r.azimuth_bins) if r.quantity == "radiance_distribution" else None
            result.radiometers.append(RadiometerResult(r.name, r.quantity, np.asarray(r.position, float),
                                                       media[ri] or "air", mean, err, rad_done[ri], bins))
        result.cancelled = cancelled
        result.stats = dict(counters, time_s=elapsed, threads=threads, seed=self.seed,
                            samples=self.samples, radiometer_samples=self.radiometer_samples,
                            segments_per_s=counters["segments"] / elapsed if elapsed > 0 else 0.0,
                            band_groups=len(groups))
        return result


def render(scene: Scene, progress=None, **overrides) -> RenderResult:
    """Render a scene (see Renderer for the overrides)."""
    return Renderer(scene, **overrides).run(progress)
