"""``photic bench``: the engine's path segments per second against raw Embree ray throughput.

Two scenes are measured: a ~300k-triangle opaque mesh inside a closed water box, and a flat
ocean with a bottom and a few small objects. For each scene and thread count, in the same run:

- engine: radiometers rendered through the compiled core (``render_radiometer``), path
  segments (one ``rtcIntersect1`` each, plus volume sampling and scattering) per second;
- embreex: ``EmbreeScene.run`` on the same triangles, random rays with origins in the water
  and isotropic directions; several threads are used when embreex releases the GIL;
- native: the core's own ``trace_rays`` (scalar ``rtcIntersect1`` on its Embree scene) on the
  same rays.

Measurements are interleaved and repeated (3 times, once in quick mode); medians are reported.

``photic bench --error`` (:func:`run_error_bench`) measures speed against error instead: pure
path tracing and the hybrid integrator (forward cone 0 and "auto") at doubling budgets on
canonical problem 2 (omega0 = 0.9) and on the stepped pool's underwater camera, against a
reference rendered with hybrid cone 0 at a large budget; time to 5 % error and a log-log plot.
"""
from __future__ import annotations

import math
import statistics
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _core
from .compile import compile_scene
from .scene import (Band, IOPs, Material, MeshObject, OceanSurface, PhaseFunction, Radiometer,
                    ScatteringComponent, Scene, Sky, Sun, TriangleMesh, WaterBody)

TARGET_RATIO = 0.5  # goal: engine segments/s >= this fraction of raw embreex rays/s at 2 threads
_CHUNK = 1024       # the core's radiometer chunk: sample counts are multiples of it


@dataclass
class BenchScene:
    """A benchmark scene and the region where raw rays start (water, outside the objects)."""

    name: str
    scene: Scene
    region: tuple[np.ndarray, np.ndarray]   # (lo, hi) corners of the origin box
    note: str = ""
    excluded: list[tuple[np.ndarray, float]] = field(default_factory=list)  # (centre, radius)


def _mesh(tm) -> TriangleMesh:
    return TriangleMesh(np.asarray(tm.vertices, np.float64), np.asarray(tm.faces, np.int64))


def _bands() -> list[Band]:
    return [Band(str(c), float(c), 10.0) for c in (450, 550, 650)]


def mesh_in_water(quick: bool = False) -> BenchScene:
    """A 20 x 20 x 10 m water box (a=0.1, b=0.5 Petzold at 550 nm) holding an icosphere of
    327,680 triangles (20,480 if quick), uniform sky, four Eo radiometers in the water."""
    import trimesh

    box = trimesh.creation.box(extents=(20.0, 20.0, 10.0))
    box.apply_translation((0.0, 0.0, -5.0))
    sphere = trimesh.creation.icosphere(subdivisions=5 if quick else 7, radius=3.0)
    sphere.apply_translation((0.0, 0.0, -5.0))
    iops = IOPs([0.05, 0.1, 0.35], [ScatteringComponent([0.6, 0.5, 0.4], PhaseFunction("petzold"))])
    scene = Scene(
        name="mesh_in_water", bands=_bands(),
        materials={"grey": Material("grey", [0.2, 0.2, 0.2])},
        meshes=[MeshObject("sphere", _mesh(sphere), "grey")],
        water=[WaterBody("tank", "mesh", iops, mesh=_mesh(box))],
        sky=Sky("uniform", np.full(3, 1.0 / math.pi)),
        radiometers=[Radiometer(f"Eo{i}", "Eo", p) for i, p in enumerate(
            [(6.0, 0.0, -5.0), (0.0, -6.0, -3.0), (-6.0, 6.0, -7.0), (0.0, 0.0, -1.0)])])
    scene.validate()
    return BenchScene("mesh_in_water", scene, (np.array([-10.0, -10.0, -10.0]), np.zeros(3)),
                      excluded=[(np.array([0.0, 0.0, -5.0]), 3.0)])


def flat_ocean_objects(quick: bool = False) -> BenchScene:
    """A flat ocean with a sand bottom at 10 m, four objects (12 to 576 triangles), a
    cardioidal sky and the sun at 30 degrees; Ed, Eu and Eo radiometers at 1, 5 and 9 m."""
    import trimesh

    objects = [
        ("rock", trimesh.creation.icosphere(subdivisions=2, radius=1.2), (4.0, -3.0, -8.7)),
        ("crate", trimesh.creation.box(extents=(2.0, 2.0, 1.5)), (-4.0, -2.0, -9.2)),
        ("pillar", trimesh.creation.cylinder(radius=0.4, height=6.0, sections=64), (-3.0, 4.0, -6.9)),
        ("ring", trimesh.creation.torus(major_radius=1.0, minor_radius=0.25, major_sections=24,
                                        minor_sections=12), (3.0, 4.0, -5.0)),
    ]
    meshes, excluded = [], []
    for name, tm, pos in objects:
        tm.apply_translation(pos)
        meshes.append(MeshObject(name, _mesh(tm), "grey"))
        centre = tm.vertices.mean(axis=0)
        excluded.append((centre, float(np.linalg.norm(tm.vertices - centre, axis=1).max())))
    iops = IOPs([0.05, 0.1, 0.35], [ScatteringComponent([0.3, 0.25, 0.2], PhaseFunction("petzold"))])
    scene = Scene(
        name="flat_ocean_objects", bands=_bands(),
        materials={"grey": Material("grey", [0.2, 0.2, 0.2]),
                   "sand": Material("sand", [0.3, 0.35, 0.4])},
        meshes=meshes,
        water=[WaterBody("sea", "ocean", iops, surface=OceanSurface("flat", 0.0),
                         bottom_depth=10.0, bottom_material="sand")],
        sun=Sun(30.0, 0.0, [1.5, 1.8, 1.6]),
        sky=Sky("cardioidal", np.full(3, 3.0 * 0.3 / (7.0 * math.pi))),
        radiometers=[Radiometer(f"{q}@{z:g}m", q, (0.0, 0.0, -z))
                     for z in (1.0, 5.0, 9.0) for q in ("Ed", "Eu", "Eo")])
    scene.validate()
    return BenchScene("flat_ocean_objects", scene,
                      (np.array([-15.0, -15.0, -10.0]), np.array([15.0, 15.0, 0.0])),
                      note="raw rays meet the objects plus the surface and bottom as two "
                           "large quads (the engine intersects those planes analytically)",
                      excluded=excluded)


def embree_triangles(scene: Scene) -> np.ndarray:
    """float32 (M, 3, 3): every surface the engine's rays can meet, as triangles: opaque
    meshes, closed water meshes and, for an ocean, its surface and bottom as two large quads
    (the engine intersects those analytically). Raw rays are cast against exactly this."""
    tris = [f.mesh.vertices[f.mesh.triangles] for f in (m.flattened() for m in scene.meshes)]
    tris += [w.mesh.vertices[w.mesh.triangles] for w in scene.water if w.type == "mesh"]
    for w in scene.water:
        if w.type != "ocean":
            continue
        planes = [w.surface.z] + ([w.surface.z - w.bottom_depth] if w.bottom_depth else [])
        r = 1.0e4  # metres: far beyond the bench regions
        for z in planes:
            q = np.array([[-r, -r, z], [r, -r, z], [r, r, z], [-r, r, z]])
            tris.append(q[[[0, 1, 2], [0, 2, 3]]])
    return np.concatenate(tris).astype(np.float32)


def native_raw_scene(tris: np.ndarray):
    """A core scene holding only the raw triangles, for native ray casting."""
    raw = _core.Scene()
    n = len(tris)
    raw.add_mesh(tris.reshape(-1, 3), np.arange(3 * n, dtype=np.uint32).reshape(n, 3), 0, 0)
    raw.add_material(np.zeros(1))
    raw.commit()
    return raw


def random_rays(bs: BenchScene, n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``n`` rays with origins uniform in the water region outside the objects' bounding
    spheres, and isotropic directions (float32 (n, 3) each)."""
    rng = np.random.default_rng(seed)
    lo, hi = bs.region
    origins = np.empty((0, 3))
    while len(origins) < n:
        p = rng.uniform(lo, hi, size=(2 * n, 3))
        ok = np.ones(len(p), bool)
        for centre, radius in bs.excluded:
            ok &= np.linalg.norm(p - centre, axis=1) > radius
        origins = np.concatenate([origins, p[ok]])
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.ascontiguousarray(origins[:n], np.float32), np.ascontiguousarray(d, np.float32)


class EmbreexCaster:
    """Casts rays with embreex (closest-hit distance), split over ``threads`` Python threads."""

    def __init__(self, triangles: np.ndarray):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh as EmbreexMesh

        self.scene = rtcore_scene.EmbreeScene()
        EmbreexMesh(self.scene, np.ascontiguousarray(triangles, np.float32))
        self._pools: dict[int, ThreadPoolExecutor] = {}

    def distances(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Closest-hit distances; misses are -1 (as the core's trace_rays)."""
        t = self.scene.run(o, d, query="DISTANCE")
        return np.where(t >= 1e36, -1.0, t).astype(np.float32)

    def cast(self, o: np.ndarray, d: np.ndarray, threads: int = 1) -> None:
        if threads <= 1:
            self.scene.run(o, d, query="DISTANCE")
            return
        pool = self._pools.setdefault(threads, ThreadPoolExecutor(threads))
        bounds = np.linspace(0, len(o), threads + 1).astype(int)
        jobs = [pool.submit(self.scene.run, o[a:b], d[a:b], query="DISTANCE")
                for a, b in zip(bounds[:-1], bounds[1:])]
        for j in jobs:
            j.result()

    def releases_gil(self, o: np.ndarray, d: np.ndarray) -> bool:
        """True if a Python loop keeps running while ``run`` works in another thread."""
        def count(duration):
            n, end = 0, time.perf_counter() + duration
            while time.perf_counter() < end:
                n += 1
            return n

        t0 = time.perf_counter()
        self.cast(o, d)
        busy = time.perf_counter() - t0
        alone = count(busy)
        done = threading.Event()
        worker = threading.Thread(target=lambda: (self.cast(o, d), done.set()))
        n = 0
        worker.start()
        while not done.is_set():
            n += 1
            time.perf_counter()
        worker.join()
        return n > 0.2 * alone

    def close(self) -> None:
        for pool in self._pools.values():
            pool.shutdown()


def _rate(work, amount: float, seconds: float):
    """Calibrate ``work(k)`` (k repetitions of ``amount`` units) to take about ``seconds``;
    return a function that runs it once more and returns units per second."""
    k = 1
    while True:
        t0 = time.perf_counter()
        work(k)
        dt = time.perf_counter() - t0
        if dt >= 0.2 * seconds or k >= 1 << 20:
            break
        k *= 4
    k = max(1, round(k * seconds / max(dt, 1e-9)))

    def measure() -> float:
        t0 = time.perf_counter()
        work(k)
        return k * amount / (time.perf_counter() - t0)
    return measure


class EngineRunner:
    """Renders every radiometer of a compiled scene; counts path segments."""

    def __init__(self, core, nradiometers: int, threads: int, seconds: float):
        self.core, self.nrad, self.threads = core, nradiometers, threads
        self.start = 0
        n = _CHUNK
        while True:  # calibrate the samples per radiometer
            dt, _ = self._run(n)
            if dt >= 0.2 * seconds or n >= 1 << 30:
                break
            n *= 4
        chunks = math.ceil(n * seconds / max(dt, 1e-9) / _CHUNK)
        self.samples = max(4 * threads, chunks) * _CHUNK

    def _run(self, n: int) -> tuple[float, int]:
        segments = 0
        t0 = time.perf_counter()
        for i in range(self.nrad):
            _, _, c = self.core.render_radiometer(i, self.start, n, self.threads)
            segments += int(c["segments"])
        dt = time.perf_counter() - t0
        self.start += n  # fresh random numbers on every run
        return dt, segments

    def measure(self) -> float:
        dt, segments = self._run(self.samples)
        return segments / dt


def _bench_scene(bs: BenchScene, threads, seconds: float, repeats: int, nrays: int,
                 gil_free: list) -> list[dict]:
    core = compile_scene(bs.scene)
    tris = embree_triangles(bs.scene)
    raw = native_raw_scene(tris)
    o, d = random_rays(bs, nrays)
    # Rays cut where the engine's path segments are: at free paths of the water's scattering
    # majorant (path tracing casts a segment only that far), for the clipped comparison.
    majorant = max(float(np.max(w.iops.total_scattering)) for w in bs.scene.water)
    tclip = np.random.default_rng(7).exponential(1.0 / majorant, len(o)).astype(np.float32)
    ex = EmbreexCaster(tris)
    try:
        # Same geometry check: embreex and the core's Embree scene must agree on the hits.
        t_ex, t_nat = ex.distances(o[:4096], d[:4096]), raw.trace_rays(o[:4096], d[:4096], 1)
        agree = np.mean(np.isclose(t_ex, t_nat, rtol=1e-3, atol=1e-3))
        hits = 100.0 * np.mean(t_nat > 0)
        if any(t > 1 for t in threads) and not gil_free:
            gil_free.append(ex.releases_gil(o, d))
        records = []
        for nt in threads:
            ex_threads = nt if (nt == 1 or gil_free[0]) else 1
            measures = {
                "engine": EngineRunner(core, len(bs.scene.radiometers), nt, seconds).measure,
                "embreex": _rate(lambda k: [ex.cast(o, d, ex_threads) for _ in range(k)],
                                 len(o), seconds),
                "native": _rate(lambda k: [raw.trace_rays(o, d, nt) for _ in range(k)],
                                len(o), seconds),
                "clipped": _rate(lambda k: [raw.trace_rays(o, d, nt, tclip) for _ in range(k)],
                                 len(o), seconds),
            }
            samples = {key: [] for key in measures}
            for _ in range(repeats):  # interleaved, so drifts in machine load hit all three
                for key, fn in measures.items():
                    samples[key].append(fn())
            eng, emb, nat, clp = (statistics.median(samples[k]) for k in ("engine", "embreex", "native", "clipped"))
            notes = [f"{len(bs.scene.bands)} bands, {len(bs.scene.radiometers)} radiometers, "
                     f"{hits:.0f}% of raw rays hit, median of {repeats}"]
            if bs.note:
                notes.append(bs.note)
            if nt > 1 and not gil_free[0]:
                notes.append("embreex holds the GIL: its figure is single-threaded")
            elif nt > 1:
                notes.append(f"embreex in {nt} Python threads (it releases the GIL)")
            if agree < 0.99:
                notes.append(f"WARNING: embreex and native hit distances agree on only "
                             f"{100 * agree:.1f}% of rays")
            records.append({
                "scene": bs.name, "triangles": int(len(tris)), "threads": int(nt),
                "engine_segments_per_s": eng, "embreex_rays_per_s": emb, "native_rays_per_s": nat,
                "native_clipped_rays_per_s": clp,
                "ratio": eng / emb, "ratio_native": eng / nat, "ratio_clipped": eng / clp,
                "note": "; ".join(notes)})
        return records
    finally:
        ex.close()


def format_table(records: list[dict]) -> str:
    """The records as a table, the notes, and what limits the engine."""
    head = (f"{'scene':<20} {'triangles':>9} {'threads':>7} {'engine Mseg/s':>13} "
            f"{'embreex Mray/s':>14} {'native Mray/s':>13} {'ratio':>6} {'ratio_native':>12} "
            f"{'ratio_clipped':>13}  note")
    lines = [head, "-" * len(head)]
    notes: list[str] = []
    for r in records:
        if r["note"] not in notes:
            notes.append(r["note"])
        lines.append(f"{r['scene']:<20} {r['triangles']:>9} {r['threads']:>7} "
                     f"{r['engine_segments_per_s'] / 1e6:>13.3f} {r['embreex_rays_per_s'] / 1e6:>14.3f} "
                     f"{r['native_rays_per_s'] / 1e6:>13.3f} {r['ratio']:>6.3f} "
                     f"{r['ratio_native']:>12.3f} {r['ratio_clipped']:>13.3f}  [{notes.index(r['note']) + 1}]")
    lines.append("")
    lines += [f"[{i + 1}] {n}" for i, n in enumerate(notes)]
    lines.append("")
    lines.append("ratio: engine path segments per second over raw embreex rays; ratio_native: over the "
                 "core's own rtcIntersect1 on the same triangles and Embree flags, rays to infinity; "
                 "ratio_clipped: over the same native rays cut at free paths of the water's "
                 "scattering majorant, as the engine's path segments are.")
    # (A core built before it loaded embreex's library linked the system's Embree 3.)
    lines.append(f"The core's Embree: {getattr(_core, 'EMBREE', 'the system Embree 3, linked')}.")
    lines.append("What limits the engine: each path segment is one scalar rtcIntersect1 plus the "
                 "physics (free-path sampling, phase-function or Fresnel sampling, the RNG, path "
                 "bookkeeping). In water the ray is traced only up to the sampled collision "
                 "distance, so it is cheaper than a raw ray cast to infinity; absorption is "
                 "applied once per band when a path leaves the water. Raw rays only traverse the "
                 "BVH. Wall time per segment / ray:")
    for r in records:
        seg_ns, ray_ns = 1e9 / r["engine_segments_per_s"], 1e9 / r["native_rays_per_s"]
        lines.append(f"  {r['scene']} ({r['threads']} thr): {seg_ns:.0f} ns per segment vs "
                     f"{ray_ns:.0f} ns per native ray -> {max(seg_ns - ray_ns, 0.0):.0f} ns "
                     f"({100 * max(1 - ray_ns / seg_ns, 0.0):.0f}%) outside the ray cast")
    at2 = [r for r in records if r["threads"] == 2]
    if at2:
        worst = min(r["ratio"] for r in at2)
        lines.append(f"Target: engine >= {TARGET_RATIO} x raw embreex at 2 threads: "
                     f"{'met' if worst >= TARGET_RATIO else 'NOT met'} (lowest ratio {worst:.3f}).")
    return "\n".join(lines)


def run_bench(quick: bool = False, threads=(1, 2), seconds: float = 2.0,
              print_table: bool = True) -> list[dict]:
    """Run the benchmark; return one record per (scene, thread count) and print a table.

    Parameters
    ----------
    quick : bool
        Smaller mesh (20k triangles), fewer rays and one repetition instead of three.
    threads : sequence of int
        Thread counts to measure.
    seconds : float
        Approximate duration of each single measurement.
    print_table : bool
        Print the table to stdout (off for ``--json``).
    """
    threads = [int(t) for t in threads]
    if not threads or min(threads) < 1:
        raise ValueError(f"thread counts must be >= 1, got {threads}")
    repeats, nrays = (1, 1 << 16) if quick else (3, 1 << 20)
    gil_free: list[bool] = []
    records = []
    for make in (mesh_in_water, flat_ocean_objects):
        records += _bench_scene(make(quick), threads, seconds, repeats, nrays, gil_free)
    if print_table:
        print(format_table(records))
    return records


# ----------------------------------------------------------------------------------------
# ``photic bench --error``: speed against error
# ----------------------------------------------------------------------------------------

ERROR_TARGET = 0.05
# (label, integrator, forward_cone_deg)
ERROR_METHODS = (("path", "path", 0.0), ("hybrid cone 0", "hybrid", 0.0), ("hybrid auto", "hybrid", "auto"))
METHOD_COLORS = {"path": (215, 50, 40), "hybrid cone 0": (40, 90, 215), "hybrid auto": (30, 150, 60)}
DEFAULT_ERROR_PLOT = Path("docs") / "images" / "bench_error.png"


@dataclass
class ErrorCase:
    """One scene of the error benchmark.

    ``make(integrator, cone)`` builds the scene; ``kind`` is "radiometers" (budgets are
    samples per radiometer) or "image" (samples per pixel of the one camera); ``budgets`` maps
    a method label to its doubling budgets; the reference is hybrid cone 0 at ``ref_budget``.
    ``pick(result)``, for radiometers: the (values, variances) whose errors count (default: every
    radiometer's first band).
    """

    name: str
    title: str
    kind: str
    make: object
    budgets: dict
    ref_budget: int
    unit: str
    pick: object = None


def _doubling(first: int, count: int) -> list[int]:
    return [first << i for i in range(count)]


def _problem_case(quick: bool) -> ErrorCase:
    from .problems import problem_scene

    def make(integrator, cone):
        d = problem_scene(2, 0.9)
        d["settings"]["integrator"] = integrator
        d["settings"]["forward_cone_deg"] = cone
        return Scene.from_dict(d)

    if quick:
        budgets = {"path": _doubling(4096, 2), "hybrid cone 0": _doubling(1024, 2),
                   "hybrid auto": _doubling(1024, 2)}
        ref = 1 << 14
    else:
        # Path samples are ~5x cheaper: larger budgets so every method spans similar times.
        budgets = {"path": _doubling(1 << 16, 5), "hybrid cone 0": _doubling(1 << 13, 6),
                   "hybrid auto": _doubling(1 << 12, 6)}
        ref = 1 << 19
    return ErrorCase("problem2_omega0.9", r"Problem 2, $\omega_0$ = 0.9 (9 radiometers)", "radiometers",
                     make, budgets, ref, "samples")


def _pool_case(quick: bool, size: tuple[int, int] | None = None) -> ErrorCase:
    """The stepped pool seen by its underwater camera; ``size``: (32, 24) by default, (256,
    256) for the view of the speed targets (issue 26: time to 5 % image error)."""
    from .scenes import stepped_pool

    res = (16, 12) if quick else (size or (32, 24))

    def make(integrator, cone):
        s = stepped_pool(resolution=res, integrator=integrator)
        s.cameras = [c for c in s.cameras if c.name == "under"]
        s.settings.forward_cone_deg = cone
        s.validate()
        return s

    if quick:
        budgets = {"path": _doubling(8, 2), "hybrid cone 0": _doubling(1, 2), "hybrid auto": _doubling(1, 2)}
        ref = 16
    elif res[0] * res[1] > 10000:
        # Path tracing hardly finds the 0.53 deg sun through the refracting surface: two
        # budgets show it; the hybrid's span the 5 % crossing.
        budgets = {"path": _doubling(64, 2), "hybrid cone 0": _doubling(16, 5),
                   "hybrid auto": _doubling(16, 5)}
        ref = 1024
    else:
        # Path samples are ~7x cheaper (no beams): larger budgets, to span similar times.
        budgets = {"path": _doubling(128, 6), "hybrid cone 0": _doubling(16, 6),
                   "hybrid auto": _doubling(16, 6)}
        ref = 512
    return ErrorCase(f"stepped_pool_under_{res[0]}x{res[1]}",
                     f"Stepped pool, under camera {res[0]} x {res[1]}", "image", make, budgets, ref, "spp")


def _render_estimate(case: ErrorCase, scene: Scene, budget: int, seed: int, threads: int):
    """(seconds, values, variances): radiometer means or the image, and their variances."""
    from .render import render

    c0 = time.process_time()
    if case.kind == "radiometers":
        res = render(scene, radiometer_samples=budget, seed=seed, threads=threads)
        if case.pick is not None:
            values, var = case.pick(res)
        else:
            values = np.array([r.mean[0, 0] for r in res.radiometers])
            var = np.array([r.stderr[0, 0] ** 2 for r in res.radiometers])
    else:
        res = render(scene, samples=budget, seed=seed, threads=threads)
        img = next(iter(res.images.values()))
        values, var = img.mean, img.variance
    stats = dict(res.stats, cpu_s=time.process_time() - c0)
    if case.kind == "image":
        stats["image"] = values
    return float(res.stats["time_s"]), values, var, stats


def _relative_errors(case: ErrorCase, values, ref, ref_var) -> tuple[float, float, float]:
    """(error, raw error, reference noise), all relative.

    Radiometers: RMS over radiometers of (x - ref) / ref. Image: sqrt(mean((x - ref)^2)) /
    mean(ref). The reference's own Monte Carlo variance is removed: for independent renders
    E|x - ref|^2 = E|x - truth|^2 + Var(ref), so error^2 = raw^2 - noise^2 (floored at 0; see
    :func:`_resolved` for errors below the reference's noise).
    """
    if case.kind != "radiometers":
        return image_relative_error(values, ref, ref_var)
    raw2 = float(np.mean(((values - ref) / ref) ** 2))
    noise2 = float(np.mean(ref_var / ref ** 2))
    return math.sqrt(max(raw2 - noise2, 0.0)), math.sqrt(raw2), math.sqrt(noise2)


def image_relative_error(values, ref, ref_var) -> tuple[float, float, float]:
    """An image's (error, raw error, reference noise) as _relative_errors gives them: RMS over
    pixels relative to the reference's mean, the reference's own variance removed."""
    m = float(np.mean(ref))
    raw2 = float(np.mean((values - ref) ** 2)) / m ** 2
    noise2 = float(np.mean(ref_var)) / m ** 2
    return math.sqrt(max(raw2 - noise2, 0.0)), math.sqrt(raw2), math.sqrt(noise2)


def _resolved(err: float, noise: float) -> tuple[float, bool]:
    """An error below the reference's own noise is not resolved: it is reported as that noise
    (an upper bound) and flagged."""
    return (noise, True) if err < noise else (err, False)


def time_to_error(records: list[dict], target: float = ERROR_TARGET) -> dict:
    """When one method's error reaches ``target`` for good: interpolated in log-log between
    the budgets around the last crossing (every larger budget stays at or below ``target``;
    single renders are noisy, so an early dip does not count).

    Returns {"seconds": float or None, "text": str, "bound": bool (already below at the first
    budget: seconds is an upper bound), "extrapolated": float or None (not reached: the time
    if the error fell as t^-1/2 from the largest budget on)}.
    """
    rs = sorted(records, key=lambda r: r["budget"])
    if not rs:
        return {"seconds": None, "text": "no data", "bound": False, "extrapolated": None}
    above = [i for i, r in enumerate(rs) if r["rel_error"] > target]
    if not above:
        return {"seconds": rs[0]["seconds"], "text": f"<= {rs[0]['seconds']:.3g} s (first budget)",
                "bound": True, "extrapolated": None}
    i = above[-1]
    if i == len(rs) - 1:
        last = rs[-1]
        ext = last["seconds"] * (last["rel_error"] / target) ** 2
        return {"seconds": None, "bound": False, "extrapolated": ext,
                "text": f"not reached ({100 * last['rel_error']:.3g} % after {last['seconds']:.3g} s)"}
    a, b = rs[i], rs[i + 1]
    la, lb = math.log(a["rel_error"]), math.log(max(b["rel_error"], 1e-12))
    f = (math.log(target) - la) / (lb - la)
    t = math.exp(math.log(a["seconds"]) + f * (math.log(b["seconds"]) - math.log(a["seconds"])))
    return {"seconds": t, "text": f"{t:.3g} s", "bound": False, "extrapolated": None}


def format_error_table(records: list[dict], refs: dict) -> str:
    lines = []
    for scene in dict.fromkeys(r["scene"] for r in records):
        ref = refs[scene]
        lines.append(f"scene {scene}: reference = hybrid cone 0 at {ref['budget']} {ref['unit']} "
                     f"(seed {ref['seed']}, {ref['seconds']:.1f} s), its own RMS relative noise "
                     f"{100 * ref['noise']:.2f} %, removed from the errors (error^2 = raw^2 - noise^2); "
                     f"errors below it are not resolved and shown as '< noise'")
        head = f"  {'method':<26} {'budget':>9} {'seconds':>9} {'rel. error':>10} {'raw':>8}"
        lines += [head, "  " + "-" * (len(head) - 2)]
        for r in (r for r in records if r["scene"] == scene):
            label = r["method"] + (f" ({r['forward_cone_deg']:g} deg)" if r["method"] == "hybrid auto" else "")
            err = (f"< {100 * r['rel_error']:.2f}%" if r["below_ref_noise"] else f"{100 * r['rel_error']:.2f}%")
            lines.append(f"  {label:<26} {r['budget']:>9} {r['seconds']:>9.3f} "
                         f"{err:>10} {100 * r['rel_error_raw']:>7.2f}%"
                         + ("  (= cone 0 settings: measured once)" if r.get("shared") else ""))
        lines.append(f"  time to {100 * ERROR_TARGET:g} % error (log-log interpolation at the last crossing):")
        times = {}
        for m in dict.fromkeys(r["method"] for r in records if r["scene"] == scene):
            tt = time_to_error([r for r in records if r["scene"] == scene and r["method"] == m])
            times[m] = tt
            lines.append(f"    {m:<16} {tt['text']}")
        path = times.get("path")
        for m, tt in times.items():
            if m == "path" or path is None or tt["seconds"] is None:
                continue
            if path["seconds"] is not None:
                ratio = f"{path['seconds'] / tt['seconds']:.3g}"
            else:
                longest = max(r["seconds"] for r in records if r["scene"] == scene and r["method"] == "path")
                bound = (f"> {longest / tt['seconds']:.3g} measured" if longest > tt["seconds"]
                         else f"no measured bound (path ran {longest:.3g} s at most)")
                ratio = (f"{bound}; ~{path['extrapolated'] / tt['seconds']:.3g} if path's error fell as "
                         f"t^-1/2 from its largest budget on")
            lines.append(f"    path / {m}: {ratio}" + (" (hybrid time is an upper bound)" if tt["bound"] else ""))
        lines.append("")
    lines.append("seconds: the render's own time (compile, beams, tracing); errors of single renders "
                 "(independent seeds) are themselves noisy by ~1/sqrt(2 x pixels or radiometers).")
    return "\n".join(lines)


def plot_error_records(records: list[dict], refs: dict, path: str | Path) -> Path:
    """Write the log-log plot of error against time, one panel per scene (see run_error_bench)."""
    from .plots import loglog_panels, save_figure

    panels = []
    for scene in dict.fromkeys(r["scene"] for r in records):
        series = []
        for m in dict.fromkeys(r["method"] for r in records if r["scene"] == scene):
            rs = sorted((r for r in records if r["scene"] == scene and r["method"] == m),
                        key=lambda r: r["budget"])
            label = m + (" (= cone 0 here)" if rs and rs[0].get("shared") else "")
            series.append((label, [r["seconds"] for r in rs], [max(r["rel_error"], 1e-4) for r in rs],
                           METHOD_COLORS.get(m, (0, 0, 0))))
        panels.append({"title": refs[scene].get("title", scene.replace("_", " ")),
                       "xlabel": "time (s)", "ylabel": "relative error", "percent": True, "legend": True,
                       "series": series,
                       "hlines": [(ERROR_TARGET, (110, 110, 110), "5%"),
                                  (refs[scene]["noise"], (170, 170, 170), "reference noise")]})
    return save_figure(loglog_panels(panels), path)


def run_error_bench(quick: bool = False, threads: int = 2, plot: str | Path | None = DEFAULT_ERROR_PLOT,
                    print_table: bool = True, progress=None, cases: list | None = None) -> list[dict]:
    """Speed against error: pure path tracing, hybrid with cone 0 and hybrid with 'auto', at
    doubling budgets, on canonical problem 2 (omega0 = 0.9; the 9 radiometers) and on the
    stepped pool seen by its underwater camera, or on ``cases`` (``ErrorCase``s). Errors are
    relative to a reference rendered once per scene with hybrid cone 0 at a large budget (its
    own variance removed).

    Returns one record per (scene, method, budget): ``scene, method, budget, seconds,
    rel_error`` and ``rel_error_raw, ref_noise, below_ref_noise`` (rel_error is then the
    reference's noise, an upper bound), ``unit, integrator, forward_cone_deg, shared`` (True:
    the same settings as another method, measured once and listed for both). Prints the
    table and the time to 5 % error unless ``print_table`` is False; writes a log-log plot of
    error against time to ``plot`` unless it is None. ``progress(message)`` is called after
    every render.
    """
    from .render import resolve_forward_cone

    say = progress or (lambda msg: None)
    records, refs = [], {}
    for ci, case in enumerate(cases or (_problem_case(quick), _pool_case(quick))):
        ref_scene = case.make("hybrid", 0.0)
        seed = 900_001 + ci
        t, ref, ref_var, _ = _render_estimate(case, ref_scene, case.ref_budget, seed, threads)
        _, _, noise = _relative_errors(case, ref, ref, ref_var)
        refs[case.name] = {"budget": case.ref_budget, "unit": case.unit, "seconds": t, "seed": seed,
                           "noise": noise, "title": case.title}
        say(f"{case.name}: reference {case.ref_budget} {case.unit} in {t:.1f} s, noise {100 * noise:.2f} %")
        done = {}  # (integrator, resolved cone) -> records, so identical settings run once
        for mi, (label, integrator, cone) in enumerate(ERROR_METHODS):
            scene = case.make(integrator, cone)
            resolved = resolve_forward_cone(scene) if integrator == "hybrid" else 0.0
            key = (integrator, resolved, tuple(case.budgets[label]))
            if key in done:
                for r in done[key]:
                    records.append(dict(r, method=label, shared=True))
                continue
            mine = []
            for bi, budget in enumerate(case.budgets[label]):
                t, values, _, stats = _render_estimate(case, scene, budget, 1000 * (ci + 1) + 100 * mi + bi, threads)
                err, raw, _ = _relative_errors(case, values, ref, ref_var)
                err, below = _resolved(err, noise)
                rec = {"scene": case.name, "method": label, "budget": int(budget), "seconds": t,
                       "cpu_s": float(stats["cpu_s"]),
                       "rel_error": err, "rel_error_raw": raw, "ref_noise": noise,
                       "below_ref_noise": below, "unit": case.unit, "integrator": stats["integrator"],
                       "forward_cone_deg": float(stats["forward_cone_deg"]), "shared": False}
                mine.append(rec)
                say(f"{case.name}: {label} {budget} {case.unit}: {t:.2f} s, error {100 * err:.2f} %")
            done[key] = mine
            records += mine
    if print_table:
        print(format_error_table(records, refs))
    if plot:
        plot_error_records(records, refs, plot)
        if print_table:
            print(f"plot: {plot}")
    return records


# ----------------------------------------------------------------------------------------
# ``photic bench --error``: the speed targets (issue 26), around run_error_bench
# ----------------------------------------------------------------------------------------

SPEED_CASES = ("problem2", "pool", "pool256", "waves", "cycles", "examples")
DEFAULT_SIDE_BY_SIDE = Path("docs") / "images" / "bench_pool_photic_cycles.png"


def run_wave_radiometers(threads: int = 2, repeats: int = 5, samples: int = 1000, samples_hi: int = 4000,
                         progress=None) -> dict:
    """The radiometers under the family of wave patches (photic.bench_waves), each against the
    same over a flat sea: per member the CPU-time ratios waves / flat at ``samples`` per
    radiometer ("total", beam builds included) and at the margin (from ``samples`` to
    ``samples_hi``), medians of paired, interleaved runs. ``ratio_waves_over_flat`` and
    ``ratio_waves_over_flat_margin`` are the largest over the family."""
    from .bench_waves import WAVE_FAMILY, run_wave_family

    family = run_wave_family(WAVE_FAMILY, threads, repeats, samples, samples_hi, progress)
    return {"samples": samples, "samples_hi": samples_hi, "radiometers": 64, "threads": threads,
            "repeats": repeats, "family": family,
            # (the first member's CPU seconds: the configuration of issue 46)
            "median": {s: {"cpu_s": family[0]["cpu_s"][f"{s}_{samples}"]} for s in ("waves", "flat")},
            "ratio_waves_over_flat": max(r["ratio_total"] for r in family),
            "ratio_waves_over_flat_margin": max(r["ratio_margin"] for r in family)}


def bpy_available() -> bool:
    import importlib.util
    return importlib.util.find_spec("bpy") is not None


def run_cycles_pool(resolution=(256, 256), samples=(16, 64), threads: int = 2, workdir=None,
                    full_bounces: bool = False) -> dict | None:
    """Cycles on the stepped pool's underwater view, in a separate process through the add-on
    (``blender_addon/cycles_compare.py``): CPU seconds per sample (the marginal cost between
    the two sample counts) and the linear image at the larger one. ``full_bounces``: Cycles'
    bounce limits raised to the scene's max_depth (its defaults stop after 4 diffuse bounces,
    which in the pool leaves out about a tenth of the light). None without ``bpy``."""
    import json
    import subprocess
    import sys
    import tempfile

    from .addon import find_addon
    from .scene import save_scene
    from .scenes import stepped_pool

    if not bpy_available():
        return None
    work = Path(workdir or tempfile.mkdtemp(prefix="photic_cycles_"))
    work.mkdir(parents=True, exist_ok=True)
    scene = stepped_pool(resolution=resolution)
    save_scene(scene, work / "pool.json")
    exr = work / "cycles.exr"
    cmd = [sys.executable, str(find_addon() / "cycles_compare.py"), str(work / "pool.json"),
           "--camera", "under", "--resolution", *map(str, resolution), "--samples", *map(str, samples),
           "--threads", str(threads)] + (["--full-bounces"] if full_bounces else ["--exr", str(exr)])
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=3600)
    lines = [ln for ln in run.stdout.splitlines() if ln.startswith("{")]
    if run.returncode != 0 or not lines:
        raise RuntimeError(f"the Cycles comparison failed ({run.returncode}): {run.stderr[-2000:]}")
    out = json.loads(lines[-1])
    if out.get("exr"):
        import OpenEXR
        with OpenEXR.File(out["exr"]) as f:
            ch = f.parts[0].channels
            rgba = np.asarray(ch["RGBA"].pixels) if "RGBA" in ch else np.stack(
                [np.asarray(ch[c].pixels) for c in "RGB"], -1)
        out["image_rgb"] = np.asarray(rgba)[..., :3].astype(np.float64)
    return out


def side_by_side_png(photic_rgb: np.ndarray, cycles_rgb: np.ndarray, path, labels=("Photic", "Cycles")) -> Path:
    """Two linear RGB images side by side in sRGB with one exposure (the 99th percentile of
    the first maps to white)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .images import srgb_encode

    scale = 1.0 / max(float(np.percentile(photic_rgb, 99)), 1e-30)
    fig, axes = plt.subplots(1, 2, figsize=(8, 4.3), dpi=100)
    for ax, img, label in zip(axes, (photic_rgb, cycles_rgb), labels):
        ax.imshow(srgb_encode(img * scale))
        ax.set_title(label, fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def speed_summary(records: list[dict], waves: dict | None, cycles: dict | None) -> dict:
    """time_to_5pct_s per case and method, cpu_s_per_spp of the 256 x 256 pool view (Photic's
    hybrid and path tracing, Cycles') and the ratios the speed targets ask for."""
    out = {"time_to_5pct_s": {}, "cpu_s_per_spp": {}, "ratios": {}}
    for scene in dict.fromkeys(r["scene"] for r in records):
        out["time_to_5pct_s"][scene] = {}
        for m in dict.fromkeys(r["method"] for r in records if r["scene"] == scene):
            tt = time_to_error([r for r in records if r["scene"] == scene and r["method"] == m])
            out["time_to_5pct_s"][scene][m] = tt["seconds"]
    pool = [r for r in records if r["scene"].startswith("stepped_pool_under_256") and not r.get("shared")]
    for label, method in (("photic_hybrid", "hybrid cone 0"), ("photic_path", "path")):
        rs = sorted((r for r in pool if r["method"] == method), key=lambda r: r["budget"])
        if len(rs) >= 2:  # marginal cost between the smallest and the largest budget
            a, b = rs[0], rs[-1]
            out["cpu_s_per_spp"][label] = (b["cpu_s"] - a["cpu_s"]) / (b["budget"] - a["budget"])
    if cycles is not None:
        out["cpu_s_per_spp"]["cycles"] = cycles["cpu_s_per_spp"]
        out["cycles_version"] = cycles.get("version")
        if "photic_hybrid" in out["cpu_s_per_spp"]:
            out["ratios"]["hybrid_over_cycles_cpu_s_per_spp"] = (out["cpu_s_per_spp"]["photic_hybrid"]
                                                                 / cycles["cpu_s_per_spp"])
        full = cycles.get("full_bounces")
        if full is not None:
            out["cpu_s_per_spp"]["cycles_full_bounces"] = full["cpu_s_per_spp"]
            if "photic_hybrid" in out["cpu_s_per_spp"]:
                out["ratios"]["hybrid_over_cycles_full_bounces_cpu_s_per_spp"] = (
                    out["cpu_s_per_spp"]["photic_hybrid"] / full["cpu_s_per_spp"])
    if "photic_hybrid" in out["cpu_s_per_spp"] and "photic_path" in out["cpu_s_per_spp"]:
        out["ratios"]["hybrid_over_path_cpu_s_per_spp"] = (out["cpu_s_per_spp"]["photic_hybrid"]
                                                           / out["cpu_s_per_spp"]["photic_path"])
    if waves is not None:
        out["wave_radiometers"] = {"median": waves["median"], "samples": waves["samples"],
                                   "samples_hi": waves["samples_hi"], "family": waves["family"]}
        out["ratios"]["radiometers_waves_over_flat"] = waves["ratio_waves_over_flat"]
        out["ratios"]["radiometers_waves_over_flat_margin"] = waves["ratio_waves_over_flat_margin"]
    return out


def format_speed_summary(summary: dict) -> str:
    lines = ["SPEED TARGETS (issue 26)"]
    for scene, ms in summary["time_to_5pct_s"].items():
        for m, t in ms.items():
            lines.append(f"  time to 5 % error, {scene}, {m}: " + ("not reached" if t is None else f"{t:.1f} s wall"))
    for k, v in summary["cpu_s_per_spp"].items():
        lines.append(f"  CPU-s per sample per pixel, stepped pool 256x256, {k}: {v:.3f}")
    if "cycles" in summary["cpu_s_per_spp"]:
        lines.append("  (cycles: its default light paths, at most 4 diffuse bounces; cycles_full_bounces: "
                     "its limits raised to Photic's max_depth, the same light transport)")
    w = summary.get("wave_radiometers")
    if w:
        from .bench_waves import format_wave_family
        lines += ["  " + line for line in format_wave_family(w["family"]).splitlines()]
    for k, v in summary["ratios"].items():
        lines.append(f"  {k}: {v:.3g}")
    return "\n".join(lines)


def run_speed_bench(cases=SPEED_CASES, quick: bool = False, threads: int = 2, plot=DEFAULT_ERROR_PLOT,
                    side_by_side=DEFAULT_SIDE_BY_SIDE, print_table: bool = True, progress=None) -> dict:
    """``photic bench --error``: error against time (run_error_bench) on the chosen ``cases``
    ("problem2", "pool": the pool at 32 x 24, "pool256": at 256 x 256), the radiometers under
    a family of wave patches against a flat sea ("waves"), and Cycles' CPU seconds per sample on the 256 x 256
    pool view with the two images side by side ("cycles", when bpy is present). Returns
    {"records", "waves", "cycles", "summary"}. (The "examples" case is
    photic.bench_examples.run_examples_bench, which the command line runs beside it.)"""
    say = progress or (lambda msg: None)
    chosen = []
    if "problem2" in cases:
        chosen.append(_problem_case(quick))
    if "pool" in cases:
        chosen.append(_pool_case(quick))
    if "pool256" in cases:
        chosen.append(_pool_case(quick, (256, 256)))
    records = run_error_bench(quick=quick, threads=threads, plot=plot, print_table=print_table,
                              progress=progress, cases=chosen) if chosen else []
    waves = None
    if "waves" in cases:
        waves = run_wave_radiometers(threads, repeats=1 if quick else 5, samples=256 if quick else 1000,
                                     samples_hi=1024 if quick else 4000, progress=progress)
    cycles = None
    if "cycles" in cases and not quick:
        if bpy_available():
            say("Cycles on the pool view (a separate process)")
            cycles = run_cycles_pool(threads=threads)
            say("Cycles with Photic's bounce limits")
            cycles["full_bounces"] = run_cycles_pool(threads=threads, full_bounces=True)
        else:
            say("no bpy: Cycles is not measured")
    if cycles is not None and cycles.get("image_rgb") is not None and side_by_side:
        from .render import render
        from .scenes import stepped_pool
        s = stepped_pool(resolution=(256, 256))
        s.cameras = [c for c in s.cameras if c.name == "under"]
        n = max(r["samples"] for r in cycles["runs"])
        img = render(s, samples=n, seed=5, threads=threads).images["under"].mean
        rgb = img[..., [2, 1, 0]]  # bands 450, 550, 650 nm -> R, G, B as 650, 550, 450
        side_by_side_png(rgb, cycles["image_rgb"], side_by_side,
                         (f"Photic hybrid, {n} spp", f"Cycles {cycles.get('version', '')}, {n} spp"))
        cycles["side_by_side"] = str(side_by_side)
    summary = speed_summary(records, waves, cycles)
    if print_table:
        print(format_speed_summary(summary))
        if cycles is not None and cycles.get("side_by_side"):
            print(f"side by side: {cycles['side_by_side']}")
    if cycles is not None:
        cycles.pop("image_rgb", None)
    return {"records": records, "waves": waves, "cycles": cycles, "summary": summary}
