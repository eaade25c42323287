"""``photic bench --large``: memory and time against scene size, each size in its own process.

The scene (:func:`seabed_scene`) is the same at every size; only its tessellation changes: a
40 x 40 m seabed height field at about 10 m depth (half of the triangles) with 64 displaced
rocks on it (the other half), under a JONSWAP wave patch tiled over the ocean, a flat sand
bottom at 14 m catching the rays that leave the seabed, the sun at 35 degrees and a
cardioidal sky. An underwater camera (128 x 96) looks across the rocks; four radiometers
(Ed, Eu, Eo and a radiance looking at the seabed) sit among them.

For each size a fresh child process (so its peak resident memory belongs to that size alone)

1. imports photic and records its resident memory (the baseline);
2. generates the geometry (numpy; not the engine's cost, timed apart);
3. builds the scene objects and validates them (``Scene.validate``);
4. compiles it (``compile_scene``: conversions, the core's copy, Embree's BVH build);
5. renders the camera and the radiometers through the compiled core with a fixed seed
   (the path integrator, medians of repetitions), and casts random rays from the water over
   the seabed with the core's ``trace_rays`` (pure Embree ray casting).

The peak resident memory of every phase is measured on Linux by resetting the process's
high-water mark (``/proc/self/clear_refs``) before it; elsewhere only the overall peak
(``ru_maxrss``) is known. Times are wall clock and process CPU time (all threads; steadier on
a shared machine). Two more cases, each in its own process too: the closed-mesh check of a
water body (``check_closed_mesh``) on a sphere of each size, and a tiled ocean (a 512 x 512
wave patch repeated without copies, seen from above the water towards the horizon and looking
down, whose memory does not grow with the visible area; and a 2048 x 2048 patch, 8.4 million
triangles, to the horizon).

    photic bench --large [--sizes 1e4 1e5 1e6 1e7] [--repeats 3] [--no-ocean] [--json]
                         [--out-json docs/images/large_scenes.json] [--plot docs/images/large_scenes.png]

The child process is ``python -m photic.bench_large '<case as JSON>'`` (:func:`measure_case`).
"""
from __future__ import annotations

import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

DEFAULT_SIZES = (10_000, 100_000, 1_000_000, 10_000_000)
DEFAULT_PLOT = Path("docs") / "images" / "large_scenes.png"
DEFAULT_JSON = DEFAULT_PLOT.with_suffix(".json")
SEABED_HALF = 20.0      # m: the seabed covers [-20, 20]^2
SEABED_Z = -10.0        # m: its mean height
N_ROCKS = 64
RESOLUTION = (128, 96)  # camera pixels
RAYS = 200_000          # random rays cast with trace_rays per repetition


# ----------------------------------------------------------------------------------------
# Geometry
# ----------------------------------------------------------------------------------------

def seabed_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The seabed's height (m) at (x, y): a mean of -10 m and four sinusoidal undulations."""
    return (SEABED_Z + 0.5 * np.sin(0.31 * x + 0.2 * y) + 0.3 * np.sin(0.77 * y - 0.4 * x + 1.0)
            + 0.12 * np.sin(2.1 * x + 1.7 * y) + 0.05 * np.sin(5.3 * x - 4.1 * y + 0.3))


def seabed_mesh(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A height field of n x n cells (2 n^2 triangles, normals up) over the seabed's square:
    float64 vertices (n+1)^2 x 3 and int64 triangles."""
    s = np.linspace(-SEABED_HALF, SEABED_HALF, n + 1)
    v = np.empty(((n + 1) ** 2, 3))
    v[:, 0] = np.tile(s, n + 1)           # x fastest
    v[:, 1] = np.repeat(s, n + 1)
    v[:, 2] = seabed_height(v[:, 0], v[:, 1])
    i = np.arange(n, dtype=np.int64)
    a = (i[None, :] + (n + 1) * i[:, None]).ravel()  # lower-left corner of every cell
    t = np.empty((2 * n * n, 3), np.int64)
    t[0::2, 0], t[0::2, 1], t[0::2, 2] = a, a + 1, a + n + 2
    t[1::2, 0], t[1::2, 1], t[1::2, 2] = a, a + n + 2, a + n + 1
    return v, t


def _uv_sphere(n_lat: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions and outward-wound triangles of a sphere with n_lat bands of latitude
    and 2 n_lat meridians: 4 n_lat (n_lat - 1) triangles."""
    n_lon = 2 * n_lat
    theta = np.pi * np.arange(1, n_lat) / n_lat
    phi = 2.0 * np.pi * np.arange(n_lon) / n_lon
    st = np.sin(theta)[:, None]
    d = np.empty(((n_lat - 1) * n_lon + 2, 3))
    d[:-2, 0] = (st * np.cos(phi)[None, :]).ravel()
    d[:-2, 1] = (st * np.sin(phi)[None, :]).ravel()
    d[:-2, 2] = np.repeat(np.cos(theta), n_lon)
    d[-2] = (0.0, 0.0, 1.0)
    d[-1] = (0.0, 0.0, -1.0)
    north, south = len(d) - 2, len(d) - 1
    j = np.arange(n_lon, dtype=np.int64)
    jn = (j + 1) % n_lon
    tris = [np.stack([np.full(n_lon, north), j, jn], axis=1)]
    if n_lat > 2:
        r = np.arange(n_lat - 2, dtype=np.int64)[:, None] * n_lon
        a, b = (r + j).ravel(), (r + n_lon + j).ravel()
        c, e = (r + n_lon + jn).ravel(), (r + jn).ravel()
        tris += [np.stack([a, b, c], axis=1), np.stack([a, c, e], axis=1)]
    last = (n_lat - 2) * n_lon
    tris.append(np.stack([np.full(n_lon, south), last + jn, last + j], axis=1))
    return d, np.concatenate(tris)


def rock_layout(seed: int = 11) -> list[tuple[np.ndarray, float, np.ndarray, np.ndarray]]:
    """(centre, radius, displacement axes (3, 3), phases (3,)) of the N_ROCKS rocks."""
    rng = np.random.default_rng(seed)
    rocks = []
    for _ in range(N_ROCKS):
        x, y = rng.uniform(-16.0, 16.0, 2)
        r = float(rng.uniform(0.5, 1.6))
        centre = np.array([x, y, float(seabed_height(x, y)) + 0.2 * r])
        axes = rng.normal(size=(3, 3))
        axes /= np.linalg.norm(axes, axis=1, keepdims=True)
        rocks.append((centre, r, axes, rng.uniform(0.0, 2.0 * np.pi, 3)))
    return rocks


def rock_vertices(directions: np.ndarray, centre, radius, axes, phases) -> np.ndarray:
    """A rock: the sphere's directions displaced radially by three sinusoids and flattened."""
    k = np.array([3.0, 7.0, 13.0])
    amp = np.array([0.18, 0.08, 0.04])
    f = 1.0 + np.sin(directions @ axes.T * k + phases) @ amp
    v = directions * (radius * f)[:, None]
    v[:, 2] *= 0.7
    return v + centre


def split_triangles(n_triangles: int) -> tuple[int, int]:
    """(seabed cells per side n, rock latitude bands n_lat) for about n_triangles in all:
    half in the seabed (2 n^2), half in the rocks (N_ROCKS x 4 n_lat (n_lat - 1))."""
    n = max(4, int(round(math.sqrt(n_triangles / 4.0))))
    per_rock = max(16.0, (n_triangles - 2 * n * n) / N_ROCKS)
    n_lat = max(3, int(round(0.5 * (1.0 + math.sqrt(1.0 + per_rock)))))
    return n, n_lat


def seabed_geometry(n_triangles: int) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(name, material, vertices, triangles) of the seabed and the rocks for ~n_triangles."""
    n, n_lat = split_triangles(n_triangles)
    v, t = seabed_mesh(n)
    parts = [("seabed", "sand", v, t)]
    d, tr = _uv_sphere(n_lat)
    for i, (c, r, axes, ph) in enumerate(rock_layout()):
        parts.append((f"rock{i:02d}", "rock", rock_vertices(d, c, r, axes, ph), tr))
    return parts


INSTANCED_SIZES = (10_000, 1_000_000, 10_000_000, 100_000_000)
DEFAULT_INSTANCED_PLOT = Path("docs") / "images" / "large_instanced.png"
BLADE_TRIANGLES = 1000  # a seagrass blade: a curved ribbon of 500 quads
ROCK_COPIES = 100
MEADOW_SEABED_CELLS = 50  # the seabed itself: 2 x 50^2 = 5,000 triangles, not instanced


def blade_mesh(n_triangles: int = BLADE_TRIANGLES) -> tuple[np.ndarray, np.ndarray]:
    """A seagrass blade in its own frame: a ribbon 1 m long and 8 mm wide rising from the
    origin along z and bending over along x, twisted a quarter turn; n_triangles (even)."""
    n = max(1, n_triangles // 2)
    s = np.linspace(0.0, 1.0, n + 1)
    twist = 0.5 * np.pi * s
    spine = np.stack([0.35 * s ** 2, np.zeros_like(s), 0.9 * s], axis=1)
    side = np.stack([-np.sin(twist) * 0.0, np.cos(twist), np.sin(twist) * 0.2], axis=1) * 0.004
    v = np.concatenate([spine - side, spine + side])  # left edge 0..n, right edge n+1..2n+1
    i = np.arange(n, dtype=np.int64)
    t = np.empty((2 * n, 3), np.int64)
    t[0::2] = np.stack([i, i + 1, n + 1 + i], axis=1)
    t[1::2] = np.stack([i + 1, n + 2 + i, n + 1 + i], axis=1)
    return v, t


def meadow_layout(n_blades: int, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Transforms (N, 3, 4) of the blades and of the ROCK_COPIES rocks over the seabed: blades
    in patches around 40 centres (a meadow's clumps), turned about z, leaning, 0.4-1.2 m tall;
    the rocks of :func:`rock_layout`'s kind, rotated and scaled 0.5-1.6 m."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-17.0, 17.0, (40, 2))
    xy = centres[rng.integers(0, 40, n_blades)] + rng.normal(0.0, 1.8, (n_blades, 2))
    xy = np.clip(xy, -SEABED_HALF + 0.5, SEABED_HALF - 0.5)
    turn = rng.uniform(0.0, 2.0 * np.pi, n_blades)
    lean = rng.normal(0.0, 0.15, n_blades)
    size = rng.uniform(0.4, 1.2, n_blades)
    c, s_, cl, sl = np.cos(turn), np.sin(turn), np.cos(lean), np.sin(lean)
    blades = np.zeros((n_blades, 3, 4))
    # R = Rz(turn) Ry(lean) * size
    blades[:, 0, 0], blades[:, 0, 1], blades[:, 0, 2] = c * cl, -s_, c * sl
    blades[:, 1, 0], blades[:, 1, 1], blades[:, 1, 2] = s_ * cl, c, s_ * sl
    blades[:, 2, 0], blades[:, 2, 1], blades[:, 2, 2] = -sl, 0.0, cl
    blades[:, :, :3] *= size[:, None, None]
    blades[:, :, 3] = np.stack([xy[:, 0], xy[:, 1], seabed_height(xy[:, 0], xy[:, 1]) - 0.02], axis=1)
    rocks = np.zeros((ROCK_COPIES, 3, 4))
    for k in range(ROCK_COPIES):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        r = rng.uniform(0.5, 1.6)
        x, y = rng.uniform(-16.0, 16.0, 2)
        rocks[k, :, :3] = q * np.array([r, r, 0.7 * r])
        rocks[k, :, 3] = (x, y, float(seabed_height(x, y)) + 0.2 * r)
    return blades, rocks


def meadow_geometry(n_triangles: int) -> dict:
    """The instanced meadow of about n_triangles rendered triangles: the seabed (5,000
    triangles, flattened), half of the rest in copies of a 1,000-triangle blade and half in
    ROCK_COPIES copies of one rock mesh. Returns the parts and their counts."""
    rest = max(0, n_triangles - 2 * MEADOW_SEABED_CELLS ** 2)
    n_blades = max(1, int(round(rest / 2 / BLADE_TRIANGLES)))
    per_rock = max(24.0, rest / 2 / ROCK_COPIES)
    n_lat = max(3, int(round(0.5 * (1.0 + math.sqrt(1.0 + per_rock)))))
    d, rock_t = _uv_sphere(n_lat)
    k = np.array([3.0, 7.0, 13.0])
    rock_v = d * (1.0 + np.sin(d * k + np.array([0.3, 1.1, 2.0])) @ np.array([0.18, 0.08, 0.04]))[:, None]
    blade_v, blade_t = blade_mesh()
    blades, rocks = meadow_layout(n_blades)
    sv, st = seabed_mesh(MEADOW_SEABED_CELLS)
    return {"seabed": (sv, st), "blade": (blade_v, blade_t, blades), "rock": (rock_v, rock_t, rocks)}


# ----------------------------------------------------------------------------------------
# Scenes
# ----------------------------------------------------------------------------------------

_BANDS = [{"name": "650", "center_nm": 650.0, "width_nm": 40.0},
          {"name": "550", "center_nm": 550.0, "width_nm": 40.0},
          {"name": "450", "center_nm": 450.0, "width_nm": 40.0}]


def _waves(resolution: int) -> dict:
    return {"kind": "waves", "spectrum": "jonswap", "wind_speed": 7.0, "fetch_m": 50000.0,
            "wind_direction_deg": 80.0, "patch_size_m": [64.0, 64.0],
            "resolution": [resolution, resolution], "seed": 4}


def seabed_scene_dict() -> dict:
    """The seabed scene without its meshes (added as objects by :func:`seabed_scene`)."""
    return {
        "photic_scene": 1, "name": "large_seabed", "bands": _BANDS,
        "materials": {"sand": {"type": "lambertian", "reflectance": [0.35, 0.3, 0.25]},
                      "rock": {"type": "lambertian", "reflectance": [0.12, 0.1, 0.08]}},
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": _waves(128),
                   "bottom": {"depth": 14.0, "material": "sand"},
                   "iops": {"absorption": [0.35, 0.065, 0.02], "b": [0.1, 0.1, 0.1],
                            "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": 35.0, "azimuth_deg": 30.0, "irradiance": [1.5, 1.8, 1.9]},
        "sky": {"type": "cardioidal", "radiance": [0.05, 0.07, 0.12]},
        "cameras": [{"name": "diver", "type": "perspective", "position": [-19.0, -3.0, -7.0],
                     "direction": [1.0, 0.15, -0.25], "up": [0.0, 0.0, 1.0], "fov_deg": 70.0,
                     "resolution": list(RESOLUTION)}],
        "radiometers": [
            {"name": "Ed", "quantity": "Ed", "position": [0.0, 0.0, -8.0]},
            {"name": "Eu", "quantity": "Eu", "position": [-5.0, 3.0, -8.0]},
            {"name": "Eo", "quantity": "Eo", "position": [5.0, 5.0, -8.5]},
            {"name": "L", "quantity": "radiance", "position": [0.0, -5.0, -7.0],
             "direction": [0.3, 0.6, -1.0]}],
        "settings": {"integrator": "path", "samples": 4, "seed": 7},
    }


def seabed_scene(n_triangles: int, parts=None):
    """The seabed scene with ~n_triangles (validated); ``parts`` from seabed_geometry."""
    from .scene import MeshObject, Scene, TriangleMesh

    scene = Scene.from_dict(seabed_scene_dict())
    for name, mat, v, t in parts if parts is not None else seabed_geometry(n_triangles):
        scene.meshes.append(MeshObject(name, TriangleMesh(v, t), mat))
    scene.validate()
    return scene


def meadow_scene(parts: dict):
    """The seabed scene's sea, sun, sky, camera and radiometers over the instanced meadow."""
    from .scene import MeshObject, Scene, TriangleMesh

    d = seabed_scene_dict()
    d["name"] = "large_meadow"
    d["materials"]["blade"] = {"type": "lambertian", "reflectance": [0.05, 0.15, 0.04]}
    scene = Scene.from_dict(d)
    sv, st = parts["seabed"]
    bv, bt, bx = parts["blade"]
    rv, rt, rx = parts["rock"]
    scene.meshes += [MeshObject("seabed", TriangleMesh(sv, st), "sand"),
                     MeshObject("blades", TriangleMesh(bv, bt), "blade", instances=bx),
                     MeshObject("rocks", TriangleMesh(rv, rt), "rock", instances=rx)]
    scene.validate()
    return scene


def ocean_scene_dict(view: str, patch_resolution: int = 512) -> dict:
    """A tiled wind sea (64 m patch of patch_resolution^2 cells) seen from 10 m above the
    water, towards the horizon or looking steeply down (about 20 m of sea in view)."""
    direction = [0.0, 1.0, -0.06] if view == "horizon" else [0.0, 0.35, -1.0]
    waves = dict(_waves(patch_resolution), roughness={"wind_speed": 7.0})
    return {
        "photic_scene": 1, "name": f"ocean_{view}", "bands": _BANDS,
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": waves,
                   "iops": {"absorption": [0.3, 0.065, 0.02], "b": [0.05, 0.05, 0.05],
                            "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": 70.0, "azimuth_deg": 90.0, "irradiance": [1.5, 1.8, 1.9]},
        "sky": {"type": "cardioidal", "radiance": [0.05, 0.07, 0.12]},
        "cameras": [{"name": "view", "type": "perspective", "position": [0.0, 0.0, 10.0],
                     "direction": direction, "up": [0.0, 0.0, 1.0], "fov_deg": 60.0,
                     "resolution": list(RESOLUTION)}],
        "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [0.0, 0.0, -2.0]}],
        "settings": {"integrator": "path", "samples": 4, "seed": 7},
    }


# ----------------------------------------------------------------------------------------
# Measuring (in the process that runs the case)
# ----------------------------------------------------------------------------------------

def _mb(kib: float) -> float:
    return kib / 1024.0


def rss_mb() -> float:
    """Current resident memory (MiB)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:
        return peak_rss_mb()


def peak_rss_mb() -> float:
    """Peak resident memory of this process (MiB): on Linux the high-water mark VmHWM (since
    the last PhasePeaks reset), as ru_maxrss there survives execve and so would report the
    peak of the process that started this one (a large pytest, say); ru_maxrss elsewhere."""
    hwm = PhasePeaks._hwm()
    if hwm is not None:
        return hwm
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 2**20 if sys.platform == "darwin" else _mb(r)


class PhasePeaks:
    """Peak resident memory per phase: the high-water mark (VmHWM) is reset before each phase
    where Linux allows it (``/proc/self/clear_refs``); otherwise the running ru_maxrss."""

    def __init__(self):
        self.resettable = self._reset()

    @staticmethod
    def _reset() -> bool:
        try:
            with open("/proc/self/clear_refs", "w") as f:
                f.write("5")
            return True
        except OSError:
            return False

    @staticmethod
    def _hwm() -> float | None:
        try:
            with open("/proc/self/status") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        return _mb(float(line.split()[1]))
        except OSError:
            pass
        return None

    def start(self) -> None:
        if self.resettable:
            self._reset()

    def peak(self) -> float:
        h = self._hwm() if self.resettable else None
        return h if h is not None else peak_rss_mb()


def _median_time(fn, repeats: int) -> tuple[float, float, object]:
    """(median wall seconds, median CPU seconds of the whole process, last result)."""
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu), out


def _timing(wall: float, cpu: float, count: int, unit: str) -> dict:
    """Seconds and seconds per ``unit`` (wall clock and CPU time summed over the threads)."""
    return {"seconds": wall, "cpu_seconds": cpu, f"s_per_{unit}": wall / max(1, count),
            f"cpu_s_per_{unit}": cpu / max(1, count)}


def _render_timings(core, scene, samples: int, radiometer_samples: int, threads: int,
                    repeats: int, rays: int) -> dict:
    """Camera, radiometer and raw ray timings on a compiled core (medians of repeats). CPU
    time (all threads) is the steadier measure on a shared machine: waiting for a core does
    not count."""
    res = {}
    cam = scene.cameras[0]
    pixels = cam.resolution[0] * cam.resolution[1]
    t, ct, (s, _, c) = _median_time(lambda: core.render_camera(0, 0, samples, threads), repeats)
    image = np.asarray(s)[:, :, 0, :] / samples  # the total (component 0), per band
    seg = int(c["segments"])
    res["camera"] = {"pixels": pixels, "spp": samples, "segments": seg,
                     "mean_radiance": float(image.mean()), "finite": bool(np.isfinite(image).all()),
                     **_timing(t, ct, pixels * samples, "sample"),
                     "s_per_segment": t / max(1, seg), "cpu_s_per_segment": ct / max(1, seg)}
    nrad = len(scene.all_radiometers())
    if nrad:
        def rads():
            seg = 0
            for ri in range(nrad):
                seg += int(core.render_radiometer(ri, 0, radiometer_samples, threads)[2]["segments"])
            return seg
        t, ct, seg = _median_time(rads, repeats)
        res["radiometers"] = {"count": nrad, "samples": radiometer_samples, "segments": seg,
                              **_timing(t, ct, nrad * radiometer_samples, "sample"),
                              "s_per_segment": t / max(1, seg), "cpu_s_per_segment": ct / max(1, seg)}
    if rays:
        rng = np.random.default_rng(3)
        o = np.empty((rays, 3), np.float32)
        o[:, :2] = rng.uniform(-SEABED_HALF, SEABED_HALF, (rays, 2))
        o[:, 2] = rng.uniform(-7.5, -1.0, rays)
        d = rng.normal(size=(rays, 3))
        d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
        t, ct, dist = _median_time(lambda: core.trace_rays(o, d, threads), repeats)
        res["rays"] = {"count": rays, **_timing(t, ct, rays, "ray"),
                       "hit_fraction": float(np.mean(np.asarray(dist) >= 0))}
    return res


def measure_case(case: dict) -> dict:
    """Run one case in this process (see the module docstring): ``case`` holds ``kind``
    ("seabed" or "ocean"), ``triangles`` (seabed) or ``view`` and ``patch_resolution``
    (ocean), ``samples``, ``radiometer_samples``, ``threads``, ``repeats``, ``rays``."""
    from .compile import compile_scene
    from .scene import Scene

    if case["kind"] == "closed":
        return _measure_closed(int(case["triangles"]))
    # Warm up (imports, the schema, the wave code) so that the baseline holds them.
    Scene.from_dict(seabed_scene_dict())
    phases = PhasePeaks()
    baseline = rss_mb()
    rec = {"kind": case["kind"], "baseline_rss_mb": baseline, "phase_peak_mb": {},
           "phase_s": {}, "phase_cpu_s": {},
           "per_phase_peaks": phases.resettable}

    def phase(name, fn):
        phases.start()
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        rec["phase_s"][name] = time.perf_counter() - t0
        rec["phase_cpu_s"][name] = time.process_time() - c0
        rec["phase_peak_mb"][name] = phases.peak()
        return out

    if case["kind"] == "instanced":
        parts = phase("generate", lambda: meadow_geometry(int(case["triangles"])))
        scene = phase("scene", lambda: meadow_scene(parts))
        del parts
        rec["triangles"] = int(sum(len(m.mesh.triangles) * m.copies for m in scene.meshes))
        rec["stored_triangles"] = int(sum(len(m.mesh.triangles) for m in scene.meshes))
        rec["instances"] = int(sum(m.copies for m in scene.meshes if m.instances is not None))
        rec["vertices"] = int(sum(len(m.mesh.vertices) for m in scene.meshes))
        rec["objects"] = len(scene.meshes)
        rays = int(case.get("rays", RAYS))
    elif case["kind"] == "seabed":
        parts = phase("generate", lambda: seabed_geometry(int(case["triangles"])))
        scene = phase("scene", lambda: seabed_scene(0, parts))
        del parts  # the scene holds its own copies now
        rec["triangles"] = int(sum(len(m.mesh.triangles) for m in scene.meshes))
        rec["vertices"] = int(sum(len(m.mesh.vertices) for m in scene.meshes))
        rec["objects"] = len(scene.meshes)
        rays = int(case.get("rays", RAYS))
    else:
        scene = phase("scene", lambda: Scene.from_dict(ocean_scene_dict(case["view"],
                                                                         int(case["patch_resolution"]))))
        mesh, _, _ = scene.water[0].surface.patch()
        rec["view"] = case["view"]
        rec["triangles"] = 0
        rec["patch_triangles"] = int(len(mesh.triangles))
        del mesh
        rays = 0
    core = phase("compile", lambda: compile_scene(scene))
    rec["rss_after_compile_mb"] = rss_mb()
    threads = int(case.get("threads", 2))
    timings = phase("render", lambda: _render_timings(core, scene, int(case["samples"]),
                                                      int(case["radiometer_samples"]), threads,
                                                      int(case["repeats"]), rays))
    rec.update(timings)
    rec["threads"] = threads
    rec["peak_rss_mb"] = max(peak_rss_mb(), *rec["phase_peak_mb"].values())
    rec["peak_growth_mb"] = rec["peak_rss_mb"] - baseline
    # The geometry's cost: the peak while the scene is built, checked and compiled (the
    # render adds a fixed ~20 MB: thread stacks and image sums, whatever the size).
    rec["build_growth_mb"] = max(rec["phase_peak_mb"]["scene"], rec["phase_peak_mb"]["compile"]) - baseline
    rec["resident_growth_mb"] = rec["rss_after_compile_mb"] - baseline
    if rec["triangles"]:
        rec["bytes_per_triangle"] = rec["build_growth_mb"] * 2**20 / rec["triangles"]
        rec["resident_bytes_per_triangle"] = rec["resident_growth_mb"] * 2**20 / rec["triangles"]
    return rec


def _measure_closed(n_triangles: int) -> dict:
    """The closed-mesh check of a water body (``check_closed_mesh``) on a sphere of about
    n_triangles: seconds and peak memory above the mesh itself."""
    from .scene import TriangleMesh, check_closed_mesh

    n_lat = max(3, int(round(0.5 * (1.0 + math.sqrt(1.0 + n_triangles)))))
    d, t = _uv_sphere(n_lat)
    mesh = TriangleMesh(d * 5.0, t)
    del d, t
    phases = PhasePeaks()
    base = rss_mb()
    phases.start()
    t0, c0 = time.perf_counter(), time.process_time()
    check_closed_mesh("water 'blob'", mesh)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    growth = phases.peak() - base
    m = len(mesh.triangles)
    return {"kind": "closed", "triangles": m, "seconds": seconds, "cpu_seconds": cpu, "peak_growth_mb": growth,
            "bytes_per_triangle": growth * 2**20 / m, "per_phase_peaks": phases.resettable}


# ----------------------------------------------------------------------------------------
# Driving the child processes
# ----------------------------------------------------------------------------------------

def run_case_in_child(case: dict, timeout: float | None = None) -> dict:
    """measure_case(case) in a fresh Python process; its record."""
    env = dict(os.environ)
    src = str(Path(__file__).resolve().parents[1])  # photic importable as in this process
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    proc = subprocess.run([sys.executable, "-m", "photic.bench_large", json.dumps(case)],
                          capture_output=True, text=True, env=env, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"large-scene case {case} failed (exit {proc.returncode}):\n"
                           f"{proc.stderr[-4000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _median_record(records: list[dict], top: bool = True) -> dict:
    """Field-wise median of repeated records (numbers; nested dicts recursively)."""
    out = dict(records[0])
    for k, v in records[0].items():
        if isinstance(v, bool) or not isinstance(v, (int, float, dict)):
            continue
        if isinstance(v, dict):
            out[k] = _median_record([r[k] for r in records], top=False)
        else:
            out[k] = statistics.median(r[k] for r in records)
    if top:
        out["runs"] = len(records)
    return out


def run_large_bench(sizes=DEFAULT_SIZES, samples: int = 4, radiometer_samples: int = 65536,
                    threads: int = 2, repeats: int = 3, builds: int = 3, large_builds: int = 1,
                    ocean: bool = True, closed: bool = True,
                    ocean_cases=(("horizon", 512), ("down", 512), ("horizon", 2048)),
                    progress=None) -> list[dict]:
    """One record per size (the median of ``builds`` child processes up to 2 million
    triangles, ``large_builds`` above; renders repeated ``repeats`` times in each); with
    ``closed``, one per size for the closed-mesh check of a water body; with ``ocean``, one
    per tiled-ocean case: (view, patch resolution) in ``ocean_cases``."""
    say = progress or (lambda msg: None)
    records = []
    common = {"samples": samples, "radiometer_samples": radiometer_samples, "threads": threads,
              "repeats": repeats}
    for n in sizes:
        runs = []
        for _ in range(builds if n <= 2_000_000 else large_builds):
            runs.append(run_case_in_child(dict(common, kind="seabed", triangles=int(n))))
            say(f"{n:,} triangles: peak {runs[-1]['peak_rss_mb']:.0f} MB, "
                f"camera {runs[-1]['camera']['cpu_s_per_sample'] * 1e6:.2f} CPU us/sample")
        records.append(_median_record(runs))
    if closed:
        for n in sizes:
            runs = [run_case_in_child({"kind": "closed", "triangles": int(n)})
                    for _ in range(builds if n <= 2_000_000 else large_builds)]
            say(f"closed check, {n:,} triangles: {runs[-1]['seconds']:.2f} s")
            records.append(_median_record(runs))
    if ocean:
        for view, res in ocean_cases:
            runs = [run_case_in_child(dict(common, kind="ocean", view=view, patch_resolution=res))
                    for _ in range(max(1, min(builds, 2)) if res <= 512 else 1)]
            say(f"ocean {view}, {res} x {res} patch: peak {runs[-1]['peak_rss_mb']:.0f} MB")
            records.append(_median_record(runs))
    return records


def run_instanced_bench(sizes=INSTANCED_SIZES, samples: int = 4, radiometer_samples: int = 65536,
                        threads: int = 2, repeats: int = 3, builds: int = 1, progress=None) -> list[dict]:
    """One record per size of the instanced meadow (the median of ``builds`` child processes),
    and the flattened seabed of 10^4 triangles (same sea, camera and radiometers): the view
    the camera's cost per sample is compared with."""
    say = progress or (lambda msg: None)
    common = {"samples": samples, "radiometer_samples": radiometer_samples, "threads": threads,
              "repeats": repeats}
    records = [_median_record([run_case_in_child(dict(common, kind="seabed", triangles=10_000))
                               for _ in range(builds)])]
    say(f"flattened seabed, {records[0]['triangles']:,} triangles: camera "
        f"{records[0]['camera']['cpu_s_per_sample'] * 1e6:.2f} CPU us/sample")
    for n in sizes:
        runs = [run_case_in_child(dict(common, kind="instanced", triangles=int(n))) for _ in range(builds)]
        say(f"instanced, {runs[-1]['triangles']:,} triangles ({runs[-1]['instances']:,} copies): peak "
            f"{runs[-1]['peak_rss_mb']:.0f} MB, camera {runs[-1]['camera']['cpu_s_per_sample'] * 1e6:.2f} "
            f"CPU us/sample")
        records.append(_median_record(runs))
    return records


def format_instanced_table(records: list[dict]) -> str:
    """The instanced sizes against the flattened 10^4-triangle seabed (the first record)."""
    base = next(r for r in records if r["kind"] == "seabed")
    ref = base["camera"]["cpu_s_per_sample"]
    lines = [f"{'rendered':>12} {'stored':>9} {'copies':>7} {'peak RSS':>9} {'build':>8} "
             f"{'scene+check':>11} {'compile':>8} {'camera CPU':>11} {'camera cost':>12} {'ray CPU':>8}",
             f"{'triangles':>12} {'triangles':>9} {'':>7} {'(MB)':>9} {'(MB)':>8} {'(s)':>11} "
             f"{'(s)':>8} {'(us/spp)':>11} {'vs 10^4 flat':>12} {'(ns)':>8}"]
    for r in records:
        what = "flat" if r["kind"] == "seabed" else ""
        lines.append(
            f"{r['triangles']:>12,} {r.get('stored_triangles', r['triangles']):>9,} "
            f"{r.get('instances', 0):>7,} {r['peak_rss_mb']:>9.0f} {r['build_growth_mb']:>8.0f} "
            f"{r['phase_s']['scene']:>11.2f} {r['phase_s']['compile']:>8.2f} "
            f"{r['camera']['cpu_s_per_sample'] * 1e6:>11.2f} "
            f"{r['camera']['cpu_s_per_sample'] / ref:>11.2f}x {r['rays']['cpu_s_per_ray'] * 1e9:>8.0f} {what}")
    lines.append(f"flat: the seabed scene of 10^4 flattened triangles (seabed and 64 rocks) with the same "
                 f"sea, camera ({RESOLUTION[0]} x {RESOLUTION[1]}) and radiometers; the others: a "
                 f"5,000-triangle seabed, copies of a {BLADE_TRIANGLES}-triangle blade and "
                 f"{ROCK_COPIES} copies of one rock; build: peak above the baseline while the scene "
                 f"is built, checked and compiled; {base['threads']} threads; CPU: process CPU time")
    return "\n".join(lines)


def plot_instanced(records: list[dict], path: str | Path) -> Path:
    """Log-log: the camera's CPU time per sample and the peak memory against rendered
    triangles, instanced, with the flattened 10^4-triangle view as a horizontal line."""
    from .plots import loglog_panels, save_figure

    inst = [r for r in records if r["kind"] == "instanced"]
    base = next(r for r in records if r["kind"] == "seabed")
    n = [r["triangles"] for r in inst]
    time_panel = {"title": "Camera CPU time per sample", "xlabel": "rendered triangles",
                  "ylabel": "microseconds", "legend": True, "series": [
                      ("instanced meadow", n, [r["camera"]["cpu_s_per_sample"] * 1e6 for r in inst], (200, 40, 40)),
                      ("1.5 x the flattened 10^4-triangle view", [min(n), max(n)],
                       [1.5 * base["camera"]["cpu_s_per_sample"] * 1e6] * 2, (170, 170, 170))]}
    mem_panel = {"title": "Peak memory", "xlabel": "rendered triangles", "ylabel": "GB", "legend": True,
                 "series": [("peak RSS of the process", n, [r["peak_rss_mb"] / 1024 for r in inst], (200, 40, 40)),
                            ("4 GB", [min(n), max(n)], [4.0, 4.0], (170, 170, 170))]}
    return save_figure(loglog_panels([time_panel, mem_panel]), path)


def format_table(records: list[dict]) -> str:
    """The records as text tables: seabed sizes, closed-mesh checks, tiled ocean."""
    lines = []
    seabed = [r for r in records if r["kind"] == "seabed"]
    if seabed:
        lines.append(f"{'triangles':>11} {'peak RSS':>9} {'build':>6} {'resident':>9} "
                     f"{'scene+check':>11} {'compile':>8} {'camera':>9} {'camera':>9} "
                     f"{'radiometer':>11} {'segment':>8} {'ray':>6}")
        lines.append(f"{'':>11} {'(MB)':>9} {'B/tri':>6} {'B/tri':>9} "
                     f"{'(s)':>11} {'(s)':>8} {'wall':>9} {'CPU':>9} {'CPU':>11} {'CPU':>8} {'CPU':>6}")
        lines.append(f"{'':>11} {'':>9} {'':>6} {'':>9} {'':>11} {'':>8} {'(us/spp)':>9} "
                     f"{'(us/spp)':>9} {'(us/sample)':>11} {'(ns)':>8} {'(ns)':>6}")
        for r in seabed:
            lines.append(
                f"{r['triangles']:>11,} {r['peak_rss_mb']:>9.0f} "
                f"{r['bytes_per_triangle']:>6.0f} {r['resident_bytes_per_triangle']:>9.0f} "
                f"{r['phase_s']['scene']:>11.2f} {r['phase_s']['compile']:>8.2f} "
                f"{r['camera']['s_per_sample'] * 1e6:>9.2f} "
                f"{r['camera']['cpu_s_per_sample'] * 1e6:>9.2f} "
                f"{r['radiometers']['cpu_s_per_sample'] * 1e6:>11.2f} "
                f"{r['camera']['cpu_s_per_segment'] * 1e9:>8.0f} {r['rays']['cpu_s_per_ray'] * 1e9:>6.0f}")
        lines.append(f"peak RSS: the child process's peak (rendering included; {seabed[0]['baseline_rss_mb']:.0f} MB "
                     "after import); build B/tri: peak while building, checking and compiling the scene, "
                     "above that baseline, per triangle; resident B/tri: held after compiling (scene, core "
                     "copy, Embree's buffers and BVH); scene+check: mesh objects and Scene.validate; "
                     f"compile: compile_scene with Embree's build; {seabed[0]['threads']} threads; CPU: "
                     "process CPU time over all threads (steadier on a shared machine); segment: camera "
                     "CPU time per path segment; ray: trace_rays per random ray")
        lines.append("phase peaks (MB): " + "; ".join(
            f"{r['triangles']:,}: " + ", ".join(f"{k} {v:.0f}" for k, v in r["phase_peak_mb"].items())
            for r in seabed))
    closed = [r for r in records if r["kind"] == "closed"]
    if closed:
        lines.append("")
        lines.append(f"{'closed water mesh check':<24} {'seconds':>8} {'CPU (s)':>8} {'peak growth (MB)':>17} {'B/tri':>6}")
        for r in closed:
            lines.append(f"{r['triangles']:>13,} triangles {r['seconds']:>8.2f} {r['cpu_seconds']:>8.2f} "
                         f"{r['peak_growth_mb']:>17.0f} {r['bytes_per_triangle']:>6.0f}")
    ocean = [r for r in records if r["kind"] == "ocean"]
    if ocean:
        lines.append("")
        lines.append(f"{'tiled ocean':<12} {'patch triangles':>15} {'peak RSS (MB)':>14} "
                     f"{'resident (MB)':>14} {'waves (s)':>10} {'compile (s)':>12} "
                     f"{'camera CPU (us/spp)':>20}")
        for r in ocean:
            lines.append(f"{r['view']:<12} {int(r['patch_triangles']):>15,} {r['peak_rss_mb']:>14.0f} "
                         f"{r['rss_after_compile_mb']:>14.0f} {r['phase_s']['scene']:>10.2f} "
                         f"{r['phase_s']['compile']:>12.2f} "
                         f"{r['camera']['cpu_s_per_sample'] * 1e6:>20.2f}")
        lines.append("resident: after compiling; waves: the scene read and checked, the wave patch "
                     "generated (cached for the compile)")
    return "\n".join(lines)


def plot_records(records: list[dict], path: str | Path) -> Path:
    """Two log-log panels against triangles: time per sample and per ray, with a curve
    growing as log N through the first camera point for comparison; and memory, with a line
    proportional to N through the last build point."""
    from .plots import loglog_panels, save_figure

    seabed = [r for r in records if r["kind"] == "seabed"]
    n = [r["triangles"] for r in seabed]
    cam = [r["camera"]["cpu_s_per_sample"] * 1e6 for r in seabed]
    ref_n = np.geomspace(min(n), max(n), 7)
    # An invisible line (the grid's grey, on the top grid line) a decade above the data
    # keeps the legend clear of the curves.
    room = lambda ys: [(10.0 ** math.ceil(math.log10(max(ys)) + 1.0), (200, 200, 200), "")]
    log_ref = cam[0] * np.log(ref_n) / np.log(n[0])
    build = [r["build_growth_mb"] / 1024 for r in seabed]
    time_panel = {"title": "CPU time per sample (all threads)", "xlabel": "triangles", "ylabel": "microseconds",
                  "legend": True, "series": [
                      ("camera (per pixel sample)", n, cam, (200, 40, 40)),
                      ("radiometer sample", n, [r["radiometers"]["cpu_s_per_sample"] * 1e6 for r in seabed], (40, 90, 200)),
                      ("random ray (trace_rays)", n, [r["rays"]["cpu_s_per_ray"] * 1e6 for r in seabed], (40, 150, 60)),
                      ("camera if growing as log N", ref_n, log_ref, (170, 170, 170))], "hlines": room(cam)}
    mem_panel = {"title": "Memory", "xlabel": "triangles", "ylabel": "GB", "legend": True,
                 "series": [
                     ("peak RSS of the process", n, [r["peak_rss_mb"] / 1024 for r in seabed], (200, 40, 40)),
                     ("build peak above baseline", n, build, (40, 90, 200)),
                     ("resident after compile", n, [max(r["resident_growth_mb"] / 1024, 1e-4) for r in seabed], (40, 150, 60)),
                     ("proportional to N", ref_n[[0, -1]], build[-1] * ref_n[[0, -1]] / n[-1], (170, 170, 170))]}
    return save_figure(loglog_panels([time_panel, mem_panel]), path)


def machine_info() -> dict:
    """CPU model, cores, memory and platform of this machine (for the JSON file)."""
    import platform

    info = {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version(),
            "numpy": np.__version__}
    try:
        with open("/proc/cpuinfo") as f:
            info["cpu"] = next((line.split(":", 1)[1].strip() for line in f
                                if line.startswith("model name")), None)
        with open("/proc/meminfo") as f:
            info["memory_gb"] = round(int(f.readline().split()[1]) / 2**20, 1)
    except OSError:
        pass
    return info


def run_large_cli(args) -> int:
    """``photic bench --large``: the table (or JSON with ``--json``), the JSON file and plot."""
    say = None if args.json else (lambda msg: print(msg, file=sys.stderr, flush=True))
    if getattr(args, "instanced", False):
        return _run_instanced_cli(args, say)
    if args.quick:  # a smoke run: two small sizes, one build, few samples, small ocean patch
        sizes = [int(float(n)) for n in (args.sizes or (10_000, 100_000))]
        kw = dict(samples=1, radiometer_samples=4096, repeats=1, builds=1,
                  ocean_cases=(("horizon", 128), ("down", 128)))
    else:
        sizes = [int(float(n)) for n in (args.sizes or DEFAULT_SIZES)]
        kw = dict(repeats=args.repeats, builds=args.repeats, large_builds=args.repeats)
    records = run_large_bench(sizes, threads=max(args.threads), ocean=not args.no_ocean,
                              progress=say, **kw)
    if args.json:
        print(json.dumps(records, indent=1))
    else:
        print(format_table(records))
    out_json = args.out_json if args.out_json is not None else ("" if args.quick else str(DEFAULT_JSON))
    if out_json:
        Path(out_json).parent.mkdir(parents=True, exist_ok=True)
        Path(out_json).write_text(json.dumps({"machine": machine_info(), "records": records}, indent=1))
        if say:
            print(f"records: {out_json}")
    plot = args.plot if args.plot is not None else ("" if args.quick else str(DEFAULT_PLOT))
    if plot and any(r["kind"] == "seabed" for r in records):
        plot_records(records, plot)
        if say:
            print(f"plot: {plot}")
    return 0


def _run_instanced_cli(args, say) -> int:
    sizes = [int(float(n)) for n in (args.sizes or INSTANCED_SIZES)]
    if args.quick:
        records = run_instanced_bench(sizes, samples=1, radiometer_samples=4096, repeats=1,
                                      threads=max(args.threads), progress=say)
    else:
        # 16 samples per pixel: a camera render of about a second, steadier than the seabed
        # bench's 4 (the cost per sample is the measure here)
        records = run_instanced_bench(sizes, samples=16, repeats=args.repeats, threads=max(args.threads),
                                      progress=say)
    print(json.dumps(records, indent=1) if args.json else format_instanced_table(records))
    out_json = args.out_json if args.out_json is not None else (
        "" if args.quick else str(DEFAULT_INSTANCED_PLOT.with_suffix(".json")))
    if out_json:
        Path(out_json).parent.mkdir(parents=True, exist_ok=True)
        Path(out_json).write_text(json.dumps({"machine": machine_info(), "records": records}, indent=1))
    plot = args.plot if args.plot is not None else ("" if args.quick else str(DEFAULT_INSTANCED_PLOT))
    if plot:
        plot_instanced(records, plot)
        if say:
            print(f"plot: {plot}")
    return 0


def main(argv=None) -> int:
    """Child entry point: ``python -m photic.bench_large '<case as JSON>'``."""
    argv = sys.argv[1:] if argv is None else argv
    print(json.dumps(measure_case(json.loads(argv[0]))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
