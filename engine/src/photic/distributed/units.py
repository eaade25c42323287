"""Work units of a render and their exact merge.

A render (``photic.render.Renderer``) is a list of passes per band group and sensor whose
random numbers depend only on the seed, the sample indices, the band group and the sensor
(and, for the hybrid integrator, the pass index i of n that picks the sun direction). A unit
is a run of consecutive passes of one sensor in one band group (cameras optionally cut into
tiles); it computes exactly what the renderer's loop computes for those passes, so the units
are independent and may run anywhere, in any order, any number of times.

Merging is exact and its order is fixed by the plan, never by the scheduling: the merger adds
the units of each sensor in pass order. Radiometer units keep the sums of every pass
(they are small), so the merged radiometers equal ``photic render`` bit for bit whatever
the unit size; a camera unit keeps the sum over its passes, so with one pass per unit (the
default) the merged images equal ``photic render`` bit for bit too, and with more they differ
from it by float rounding only (and are still the same on any cluster). Tiled cameras use a
seed per tile (another, equally valid random stream than the untiled render).

Rounds (for a target standard error) repeat the radiometer passes with a seed derived from
the item's seed and the round number; they are merged after round 0 in round order.
"""
from __future__ import annotations

import collections
import os
import socket
import threading
import time
from dataclasses import dataclass, replace

import numpy as np

from ..compile import compile_scene, scene_band_groups
from ..estimates import CameraSums, RadiometerSums
from ..render import (COMPONENTS, ImageResult, RenderResult, _mean_stderr, build_pass_beams,
                      camera_passes, flag_beam_modes, image_components, image_result,
                      radiometer_passes,
                      radiometer_result, round_seed, uses_beams)
from .job import Item, Job

NC = len(COMPONENTS) + 1      # the core's layout: total, then the components
CAMERA_COMPONENTS = NC        # (beam_direct is always zero for cameras; raman, chlorophyll, cdom where rendered)


@dataclass(frozen=True, order=True)
class Unit:
    """Passes [first, last) of one sensor in one band group (and round, and tile)."""

    item: str
    round: int
    group: int
    kind: str                 # "camera" or "radiometer"
    sensor: int               # index among the scene's cameras / all_radiometers()
    tile: int                 # camera tile index, -1 for a whole image or a radiometer
    first: int
    last: int

    @property
    def id(self) -> str:
        tile = f"_t{self.tile}" if self.tile >= 0 else ""
        return (f"r{self.round}_g{self.group}_{self.kind[:3]}{self.sensor}{tile}"
                f"_p{self.first:04d}-{self.last - 1:04d}")


def tile_rects(width: int, height: int, tile: int) -> list[tuple[int, int, int, int]]:
    """(x0, y0, w, h) of the tiles, row by row; one rect for the whole image when tile = 0."""
    if tile <= 0 or (tile >= width and tile >= height):
        return [(0, 0, width, height)]
    return [(x, y, min(tile, width - x), min(tile, height - y))
            for y in range(0, height, tile) for x in range(0, width, tile)]


def plan_round(item: Item, job: Job, rnd: int) -> list[Unit]:
    """The units of one round of an item, in merge order. Round 0 renders everything; later
    rounds only the radiometers (the target standard error is a radiometer target)."""
    units = []
    scene = item.scene
    hybrid = item.integrator == "hybrid"
    ngroups = len(scene_band_groups(scene))
    rad_np = len(radiometer_passes(item.radiometer_samples, uses_beams(scene, hybrid)))
    cam_np = len(camera_passes(item.samples))
    for g in range(ngroups):
        if rnd == 0:
            for ci, cam in enumerate(scene.cameras):
                rects = tile_rects(*cam.resolution, job.tile)
                for t in range(len(rects)):
                    for p in range(0, cam_np, job.camera_passes):
                        units.append(Unit(item.name, rnd, g, "camera", ci, t if len(rects) > 1 else -1,
                                          p, min(p + job.camera_passes, cam_np)))
        for ri in range(len(scene.all_radiometers())):
            for p in range(0, rad_np, job.radiometer_passes):
                units.append(Unit(item.name, rnd, g, "radiometer", ri, -1, p,
                                  min(p + job.radiometer_passes, rad_np)))
    return units


def unit_spec(item: Item, job: Job, unit: Unit, threads: int) -> dict:
    """Everything a worker needs besides the scene (plain values: cheap to ship)."""
    hybrid = item.integrator == "hybrid"
    beams = uses_beams(item.scene, hybrid)
    if unit.kind == "camera":
        passes = camera_passes(item.samples)
        cam = item.scene.cameras[unit.sensor]
        rect = tile_rects(*cam.resolution, job.tile)[unit.tile] if unit.tile >= 0 else None
    else:
        passes = radiometer_passes(item.radiometer_samples, beams)
        rect = None
    return {"unit": unit.id, "fingerprint": item.fingerprint, "kind": unit.kind,
            "sensor": unit.sensor, "group": unit.group, "round": unit.round,
            "seed": round_seed(item.seed, unit.round), "rect": rect, "tile": unit.tile,
            "first": unit.first, "passes": passes[unit.first:unit.last], "npasses": len(passes),
            "hybrid": hybrid, "beams": beams, "cone": item.forward_cone_deg, "threads": int(threads)}


# --- on the worker -------------------------------------------------------------------------

_CORES: collections.OrderedDict = collections.OrderedDict()  # compiled scenes of this process
_CORES_MAX = 3
_CORES_LOCK = threading.Lock()


def _tile_scene(scene, ci: int, rect, seed: int, tile: int):
    """The scene with camera ``ci`` replaced by the camera of one tile, whose rays are those
    of the tile's pixels in the whole image (same pixel grid, narrower field of view, shifted
    window), and the seed of that tile."""
    cam = scene.cameras[ci]
    W, H = cam.resolution
    x0, y0, w, h = rect
    sx, sy = cam.shift
    # Derived from the core's camera model: the tile's pixel (p, r) sees the direction of the
    # image's pixel (x0 + p, y0 + r) when tan(fov/2) scales by w / W and the window shifts.
    half = np.radians(cam.fov_deg) / 2
    fov = float(np.degrees(2 * np.arctan(np.tan(half) * w / W)))
    shift = ((2 * x0 + w - W) / (2 * w) + sx * W / w, (H - 2 * y0 - h) / (2 * w) + sy * W / w)
    tcam = replace(cam, fov_deg=fov, ortho_width=cam.ortho_width * w / W, resolution=(w, h), shift=shift)
    tscene = replace(scene, cameras=[tcam], radiometers=[], radiometer_arrays=[])
    tseed = int(np.random.SeedSequence([seed, 0x711E, ci, tile]).generate_state(1, np.uint64)[0]) >> 1
    return tscene, tseed


def _take_core(spec: dict, scene):
    """(key, compiled scene) of a unit. Compiled scenes are kept for later units of the same
    item, band group, seed and tile (compiling is deterministic, and every pass rebuilds its
    beams); a unit holds its core alone (beams are per core), so units running at once in one
    worker process (more than one thread per worker) never share one."""
    tiled = spec["kind"] == "camera" and spec["rect"] is not None
    key = (spec["fingerprint"], spec["group"], spec["seed"], (spec["sensor"], spec["tile"]) if tiled else None)
    with _CORES_LOCK:
        core = _CORES.pop(key, None)
    if core is None:
        g = scene_band_groups(scene)[spec["group"]]
        target, seed = scene, spec["seed"]
        if tiled:
            target, seed = _tile_scene(scene, spec["sensor"], spec["rect"], seed, spec["tile"])
        core = compile_scene(target, g, seed=seed, hybrid=spec["hybrid"], forward_cone_deg=spec["cone"])
    return key, core


def clear_core_cache() -> None:
    """Forget this process's compiled scenes (the in-process runner's, after a job)."""
    with _CORES_LOCK:
        _CORES.clear()


def _keep_core(key, core) -> None:
    with _CORES_LOCK:
        _CORES[key] = core
        _CORES.move_to_end(key)
        while len(_CORES) > _CORES_MAX:
            _CORES.popitem(last=False)


def compute_unit(spec: dict, scene) -> dict:
    """Render one unit: {"meta": {...}, "arrays": {...}}. Pure: the same spec and scene give
    the same arrays bit for bit on any machine and thread count."""
    t0, c0 = time.perf_counter(), time.process_time()
    key, core = _take_core(spec, scene)
    try:
        return _render_unit(spec, scene, core, t0, c0)
    finally:
        _keep_core(key, core)


def _render_unit(spec: dict, scene, core, t0: float, c0: float) -> dict:
    threads = spec["threads"]
    counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
    camera = spec["kind"] == "camera"
    ci = 0 if camera and spec["rect"] is not None else spec["sensor"]  # a tile scene has one camera
    # The beams of a pass are those Renderer.run builds: per camera, and one set shared by all
    # the radiometers (paired strata of the sun's disk).
    sensor_key = (0, spec["sensor"]) if camera else (1,)
    sums = per_pass = None
    for k, (start, n) in enumerate(spec["passes"]):
        if spec.get("beams", spec["hybrid"]):
            build_pass_beams(core, scene, spec["seed"], sensor_key, spec["first"] + k, spec["npasses"],
                             threads, paired=not camera, keep=k > 0)
        if camera:
            s, s2, c = core.render_camera(ci, start, n, threads)
            if sums is None:
                sums = [np.zeros(s.shape[:2] + (CAMERA_COMPONENTS,) + s.shape[3:]),
                        np.zeros(s.shape[:2] + (1,) + s.shape[3:]),
                        np.zeros(s.shape[:2] + s.shape[3:])]
            sums[0] += s[:, :, :CAMERA_COMPONENTS]
            sums[1] += s2[:, :, :1]   # the variance is of the total only
            sums[2] += s[:, :, 0] ** 2 / n   # its spread between passes (photic.estimates)
        else:
            mom = np.empty((core.radiometer_bins(spec["sensor"]), 3, core.nbands))
            s, s2, c = core.render_radiometer(spec["sensor"], start, n, threads, None, mom)
            if per_pass is None:
                per_pass = [np.zeros((len(spec["passes"]),) + a.shape) for a in (s, s2, mom)]
            per_pass[0][k], per_pass[1][k], per_pass[2][k] = s, s2, mom
        for name in counters:
            counters[name] += int(c[name])
    meta = {"unit": spec["unit"], "fingerprint": spec["fingerprint"], "kind": spec["kind"],
            "passes": [list(p) for p in spec["passes"]], "counters": counters,
            "time_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
            "host": socket.gethostname(), "pid": os.getpid()}
    if camera:
        arrays = {"s": sums[0], "s2": sums[1], "b": sums[2]}
    else:
        meta["medium"] = int(core.radiometer_medium(spec["sensor"]))
        arrays = {"s": per_pass[0], "s2": per_pass[1], "m": per_pass[2]}
    return {"meta": meta, "arrays": arrays}


# --- merging -----------------------------------------------------------------------------

class ItemMerger:
    """Adds unit results into an item's sums exactly as ``Renderer.run`` adds its passes.

    ``add`` must see each sensor's units of a band group in (round, pass) order; ``merge_units``
    sorts them so. Then every sum gets its terms in one fixed order, whatever the scheduling.
    """

    def __init__(self, item: Item):
        self.item = item
        scene = item.scene
        self.groups = scene_band_groups(scene)
        nb = len(scene.bands)
        self.nb = nb
        beams = uses_beams(scene, item.integrator == "hybrid")
        self.beams = beams
        self.cams = {ci: CameraSums((c.resolution[1], c.resolution[0], NC, nb), False)  # (as Renderer.run)
                     for ci, c in enumerate(scene.cameras)}
        self.cam_samples = {ci: 0 for ci in self.cams}
        self.strata = len(radiometer_passes(item.radiometer_samples, beams)) // 2
        self.rads: dict[int, list[RadiometerSums]] = {}   # per radiometer, one per round
        self.media: dict[int, int] = {}
        self.counters = {"segments": 0, "shadow_rays": 0, "paths": 0}
        self.unit_time_s = 0.0
        self.units = 0
        self.beam_passes = 0
        self.rounds = 0

    def add(self, unit: Unit, result: dict, job: Job) -> None:
        meta, arrays = result["meta"], result["arrays"]
        g = self.groups[unit.group]
        if unit.kind == "camera":
            cam = self.item.scene.cameras[unit.sensor]
            x0, y0, w, h = (tile_rects(*cam.resolution, job.tile)[unit.tile] if unit.tile >= 0
                            else (0, 0, *cam.resolution))
            sums = self.cams[unit.sensor]
            sums.s[y0:y0 + h, x0:x0 + w, :CAMERA_COMPONENTS, g] += arrays["s"]
            sums.s2[y0:y0 + h, x0:x0 + w, :1, g] += arrays["s2"]
            if sums.b is not None and "b" in arrays:
                sums.b[y0:y0 + h, x0:x0 + w, g] += arrays["b"]
            if unit.group == 0 and unit.tile <= 0:
                self.cam_samples[unit.sensor] += sum(n for _, n in meta["passes"])
                sums.sizes.extend(int(n) for _, n in meta["passes"])
        else:
            ri = unit.sensor
            ps, ps2, pm = arrays["s"], arrays["s2"], arrays.get("m")
            rounds = self.rads.setdefault(ri, [])
            while len(rounds) <= unit.round:
                rounds.append(RadiometerSums(ps.shape[1:2] + (NC, self.nb), self.beams, self.strata))
            sums = rounds[unit.round]
            for k, (start, n) in enumerate(meta["passes"]):
                # in pass order, as Renderer.run adds them
                sums.add_pass(g, unit.first + k, start, n, ps[k], ps2[k], None if pm is None else pm[k])
            self.media[ri] = int(meta["medium"])
        if self.beams:
            self.beam_passes += len(meta["passes"])
        for name in self.counters:
            self.counters[name] += int(meta["counters"][name])
        self.unit_time_s += float(meta["time_s"])
        self.units += 1
        self.rounds = max(self.rounds, unit.round + 1)

    def result(self) -> RenderResult:
        item, scene = self.item, self.item.scene
        res = RenderResult(scene.name, list(scene.bands))
        for ci, cam in enumerate(scene.cameras):
            res.images[cam.name] = image_result(cam.name, self.cams[ci], self.cam_samples[ci],
                                                components=image_components(self.item.scene))
        rehits: dict[int, float] = {}
        meshes: dict[int, dict | None] = {}
        for ri, r in enumerate(scene.all_radiometers()):
            if ri not in self.rads:
                continue
            m = self.media.get(ri, -1)
            medium = "air" if m < 0 else scene.water[m].name
            rr = radiometer_result(r, medium, [x for x in self.rads[ri] if x.samples.max() > 0])
            flag_beam_modes(rr, scene, item.integrator == "hybrid", item.forward_cone_deg, m, rehits, meshes)
            res.radiometers.append(rr)
        t = self.unit_time_s
        res.stats = dict(self.counters, time_s=t, threads=0, seed=item.seed, samples=item.samples,
                         radiometer_samples=item.radiometer_samples * max(1, self.rounds),
                         segments_per_s=self.counters["segments"] / t if t > 0 else 0.0,
                         band_groups=len(self.groups), integrator=item.integrator,
                         forward_cone_deg=item.forward_cone_deg, beam_passes=self.beam_passes,
                         rounds=max(1, self.rounds), units=self.units, distributed=True)
        return res


class CameraPreview:
    """A running estimate of one camera from its units in whatever order they arrive, for
    display while a render runs (per-pixel sample counts: tiles and band groups fill in at
    their own pace). Final images come from ItemMerger's fixed order, never from here."""

    def __init__(self, item: Item, job: Job, camera: int = 0):
        cam = item.scene.cameras[camera]
        self.name, self.camera, self.job = cam.name, camera, job
        self.components = image_components(item.scene)
        self.groups = scene_band_groups(item.scene)
        shape = (cam.resolution[1], cam.resolution[0], NC, len(item.scene.bands))
        self.s, self.s2 = np.zeros(shape), np.zeros(shape)
        self.n = np.zeros(shape[:2] + (1, shape[3]))
        self.resolution = cam.resolution
        self.version = 0
        self._lock = threading.Lock()

    def add(self, unit: Unit, result: dict | None) -> None:
        if result is None or unit.kind != "camera" or unit.sensor != self.camera:
            return
        x0, y0, w, h = (tile_rects(*self.resolution, self.job.tile)[unit.tile] if unit.tile >= 0
                        else (0, 0, *self.resolution))
        g = self.groups[unit.group]
        with self._lock:
            self.s[y0:y0 + h, x0:x0 + w, :CAMERA_COMPONENTS, g] += result["arrays"]["s"]
            self.s2[y0:y0 + h, x0:x0 + w, :1, g] += result["arrays"]["s2"]
            self.n[y0:y0 + h, x0:x0 + w, :, g] += sum(n for _, n in result["meta"]["passes"])
            self.version += 1

    def image(self) -> ImageResult | None:
        """The current estimate (None before the first unit)."""
        with self._lock:
            if not self.version:
                return None
            s, s2, n = self.s.copy(), self.s2.copy(), self.n.copy()
        mean, err = _mean_stderr(s, s2, n)
        comps = {c: mean[:, :, COMPONENTS.index(c) + 1, :] for c in self.components}
        return ImageResult(self.name, mean[:, :, 0, :], err[:, :, 0, :] ** 2, int(n.min()), comps)


def merge_order(units) -> list[Unit]:
    """The fixed merge order: round, band group, sensor, tile, passes."""
    kind = {"camera": 0, "radiometer": 1}
    return sorted(units, key=lambda u: (u.round, u.group, kind[u.kind], u.sensor, u.tile, u.first))


def worst_rel_stderr(result: RenderResult) -> float:
    """The largest standard error / |mean| over the radiometers' non-zero values."""
    worst = 0.0
    for r in result.radiometers:
        m = np.abs(r.mean)
        ok = m > 0
        if np.any(ok):
            worst = max(worst, float(np.max(r.stderr[ok] / m[ok])))
    return worst
