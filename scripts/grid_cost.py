"""Cost of 3-D IOP grids against homogeneous water at equal samples (a benchmark, not a test).

A sunlit sea below a flat surface, a 64 x 48 camera looking down at 16 samples per pixel and
9 radiometers (Ed, Eu, Eo at 1, 3 and 6 m) at 1e5 samples, rendered

- with homogeneous water (the grid's base IOPs),
- with a 256^3 grid over 100 x 100 x 40 m holding a sparse plume (a sheared Gaussian jet, about
  1 % of the voxels non-zero) and
- with a 256^3 grid of random densities in every voxel,

for the hybrid and the path integrator. Each case is rendered ``--repeat`` times, alternating
with the others, and the median is quoted with the ratio to the homogeneous render measured in
the same run (the machine is shared: ratios are what to compare; every other repeat renders
the fields in reverse order). Times include the scene's
setup (reading the .npz, validation, building the bricks); the "render" columns are the
renderer's own time (building the grid and rendering, not reading and validating the scene).
``--mixed`` also renders each grid's water mixed evenly (homogeneous water of the grid's mean
IOPs, base + mean(rho) x unit, with the grid's components) and compares the grid with it: the
homogeneous render that differs from the grid's in the grid alone (the plume's extra
scattering and phase functions are in both).
``--cdom`` also renders each grid with a second density field on its voxels (a CDOM-like
absorber spread wider than the first field: a box blur over n/16 voxels across; for the
example its own river-water field, with the sediment alone in the first: the example as
``sediment_plume.blend`` holds it) and compares it with the one-field grid: the cost of a
further field.
``--bands N`` renders N bands with the same IOPs in each (one geometric path serves them all,
as in spectral scenes). ``--what example`` renders the sediment-plume example's scene instead
(``example_blends/make_examples.py``: shore, 10 bands, Case-2 IOP models, a camera above the sea
at 160 x 90 and 16 spp, 5 radiometers above the water at 1e5 samples) with its plume resampled
to a 256^3 grid, against the same scene with the clear water alone; with ``--full`` at the
``.blend``'s own settings (480 x 270 at 96 spp, radiometers at 1e6 samples), as users render it.

    .venv/bin/python scripts/grid_cost.py [--n 256] [--repeat 3] [--what both|image|example] [--bands 1]
                                          [--threads 0] [--mixed] [--cdom] [--full] [--json out.json]
"""
from __future__ import annotations

import argparse
import functools
import importlib.util
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from photic.render import render
from photic.scene import IOPGrid, IOPProfile, IOPs, ScatteringComponent, Scene

HG = {"type": "henyey_greenstein", "g": 0.9}
MIXED = ", mixed"  # the name of a grid's water mixed evenly (--mixed)
CDOM = " + cdom"  # the name of a grid with a second field (--cdom)
WATER = {"type": "pure_water"}


def iops(a, b_particles, b_water=0.002):
    return {"absorption": [a], "scattering": [{"b": [b_particles], "phase": HG},
                                              {"b": [b_water], "phase": WATER}]}


BASE = iops(0.05, 0.1)
UNIT = iops(0.2, 1.5, 0.0)
ORIGIN, SIZE = [-50.0, -50.0, -40.0], [100.0, 100.0, 40.0]


def plume(n: int, seed: int = 5) -> np.ndarray:
    """A sediment jet: a Gaussian tube along x that widens and sinks offshore; ~1 % non-zero."""
    x = (np.arange(n) + 0.5) / n
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    centre_y = 0.5 + 0.08 * np.sin(6.0 * X)
    centre_z = 0.93 - 0.1 * X
    width = 0.02 + 0.03 * X
    r2 = ((Y - centre_y) ** 2 + (Z - centre_z) ** 2) / width ** 2
    rho = (3.0 * np.exp(-r2) * np.exp(-1.5 * X)).astype(np.float32)
    rho *= (1.0 + 0.3 * np.random.default_rng(seed).standard_normal(rho.shape)).astype(np.float32)
    rho[rho < 0.05] = 0.0
    return np.maximum(rho, 0.0, dtype=np.float32)


def dense(n: int, seed: int = 6) -> np.ndarray:
    return np.random.default_rng(seed).random((n, n, n), dtype=np.float32)


def companion(rho: np.ndarray) -> np.ndarray:
    """A second field for --cdom: the first spread wider across (a box blur over about n/16
    voxels along x and y, by cumulative sums), as dissolved matter spreads beyond the
    sediment that settles."""
    out = rho.astype(np.float64)
    for axis in (0, 1):
        r = max(1, rho.shape[axis] // 32)
        c = np.cumsum(np.pad(out, [(r + 1, r) if a == axis else (0, 0) for a in range(3)]), axis=axis)
        hi = np.take(c, np.arange(2 * r + 1, c.shape[axis]), axis=axis)
        lo = np.take(c, np.arange(0, c.shape[axis] - 2 * r - 1), axis=axis)
        out = (hi - lo) / (2 * r + 1)
    return np.maximum(out, 0.0).astype(np.float32)


CDOM_UNIT = {"absorption": [0.3], "scattering": [{"b": [0.0], "phase": HG}, {"b": [0.0], "phase": WATER}]}


@functools.lru_cache(maxsize=1)
def _examples():
    """example_blends/make_examples.py as a module (it imports bpy only to write .blend files),
    loaded once."""
    path = Path(__file__).resolve().parents[1] / "example_blends" / "make_examples.py"
    spec = importlib.util.spec_from_file_location("make_examples", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _with_cdom(grid: dict, density_file: Path, unit: dict) -> dict:
    """The grid dict with the .npz's 'cdom' array as a second field, if it holds one."""
    with np.load(density_file) as z:
        if "cdom" in z.files:
            grid["fields"] = [{"name": "cdom", "unit": unit, "key": "cdom"}]
    return grid


def example_scene(integrator: str, density_file: Path | None, full: bool = False) -> Scene:
    """The sediment-plume example's scene at 160 x 90, 16 spp, radiometers at 1e5 samples, or
    (full) at the .blend's own 480 x 270, 96 spp and 1e6 radiometer samples."""
    ex = _examples()
    d = ex.plume_scene_dict() if full else ex.plume_scene_dict(resolution=(160, 90), samples=16)
    water = d["water"][0]
    del water["iops"]
    if density_file is None:  # the clear water the plume enters
        water["iop_model"] = ex.clear_water_model()
    else:  # one field (CDOM following the sediment), or two as in the example's .blend
        grid = _with_cdom({"base": {"iop_model": ex.clear_water_model()},
                           "unit": {"iop_model": ex.plume_unit_model()},
                           "origin": list(ex.PLUME_BOX_ORIGIN), "size": list(ex.PLUME_BOX_SIZE),
                           "file": density_file.name}, density_file, {"iop_model": ex.river_cdom_model()})
        if "fields" in grid:
            grid["unit"] = {"iop_model": ex.sediment_unit_model()}
        water["iop_grid"] = grid
    d["settings"].update(integrator=integrator)
    if not full:
        d["settings"].update(radiometer_samples=100_000)
    return Scene.from_dict(d, base_dir=density_file.parent if density_file else None)


def scene(integrator: str, density_file: Path | None, what: str = "both", bands: int = 1,
          full: bool = False) -> Scene:
    if what == "example":
        return example_scene(integrator, density_file, full)
    water = {"name": "sea", "type": "ocean", "ior": 1.34, "surface": {"kind": "flat", "z": 0.0}}
    if density_file is None:
        water["iops"] = BASE
    else:  # read from an .npz as users give large grids (the reading is part of the cost)
        water["iop_grid"] = _with_cdom({"base": {"iops": BASE}, "unit": {"iops": UNIT},
                                        "origin": ORIGIN, "size": SIZE, "file": density_file.name},
                                       density_file, {"iops": CDOM_UNIT})
    rads = [{"name": f"{q}_{z:g}", "quantity": q, "position": [10.0, 2.0, -z]}
            for z in (1.0, 3.0, 6.0) for q in ("Ed", "Eu", "Eo")]
    cam = {"name": "cam", "type": "perspective", "position": [0.0, -30.0, 20.0], "look_at": [0.0, 0.0, -10.0],
           "fov_deg": 60.0, "resolution": [64, 48]}
    if what == "image":   # an image only, larger: 160 x 120 at 64 spp
        rads, cam["resolution"] = [], [160, 120]
    d = {"photic_scene": 1, "name": "grid cost", "water": [water],
         "sun": {"zenith_deg": 30.0, "azimuth_deg": 60.0, "irradiance": [1.0]},
         "sky": {"type": "uniform", "radiance": [0.3]},
         "cameras": [cam], "radiometers": rads,
         "settings": {"integrator": integrator, "seed": 3, "samples": 16,
                      "radiometer_samples": 100_000, "forward_cone_deg": 0.0}}
    if what == "image":
        d["settings"]["samples"] = 64
    if bands > 1:  # the same IOPs, sun and sky in every band: the geometry serves them all
        d["bands"] = [{"name": f"b{i}", "center_nm": 400.0 + 300.0 * (i + 0.5) / bands,
                       "width_nm": 300.0 / bands} for i in range(bands)]
        d = _per_band(d, bands)
    return Scene.from_dict(d, base_dir=density_file.parent if density_file else None)


def homogenised(sc: Scene) -> Scene:
    """The scene with its gridded water mixed evenly: homogeneous IOPs base + mean(rho_f) x
    unit_f (every field) everywhere, with the grid's components (phase functions). The same
    IOP model and, on average, the same scattering as the grid: the homogeneous render that
    differs from the grid's in the grid alone."""
    def mixed(base: IOPs, units: list, means: list) -> IOPs:
        a, bs = base.absorption, [c.b for c in base.scattering]
        for unit, m in zip(units, means):
            a = a + m * unit.absorption
            bs = [b + m * cu.b for b, cu in zip(bs, unit.scattering)]
        return IOPs(a, [ScatteringComponent(b, cb.phase) for b, cb in zip(bs, base.scattering)])

    for w in sc.water:
        g = w.iops
        if isinstance(g, IOPGrid):
            ms = [float(np.mean(rho, dtype=np.float64)) for rho in g.densities()]
            w.iops = (IOPProfile(g.iops.z_top, [mixed(x, g.units(), ms) for x in g.iops.layers])
                      if isinstance(g.iops, IOPProfile) else mixed(g.iops, g.units(), ms))
    return sc


def _per_band(d, bands: int):
    """The scene with every one-band list of numbers repeated for each band."""
    if isinstance(d, dict):
        return {k: _per_band(v, bands) for k, v in d.items()}
    if isinstance(d, list):
        if len(d) == 1 and isinstance(d[0], float):
            return d * bands
        return [_per_band(x, bands) for x in d]
    return d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=256, help="voxels per axis")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--integrators", default="hybrid,path")
    ap.add_argument("--what", choices=["both", "image", "example"], default="both",
                    help="both: the camera and the 9 radiometers (in and near the plume); "
                         "image: a 160 x 120 camera at 64 spp alone; example: the sediment-plume "
                         "example's scene with its plume on a 256^3 grid")
    ap.add_argument("--bands", type=int, default=1,
                    help="spectral bands (the same IOPs in each): one path serves them all")
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    ap.add_argument("--mixed", action="store_true",
                    help="also render each grid's water mixed evenly (homogeneous water of the "
                         "grid's mean IOPs, the same components) and compare the grid with it")
    ap.add_argument("--cdom", action="store_true",
                    help="also render each grid with a second, CDOM-like density field (the first "
                         "spread wider) and compare it with the one-field grid")
    ap.add_argument("--full", action="store_true",
                    help="with --what example: the .blend's own settings (480 x 270 at 96 spp, "
                         "radiometers at 1e6 samples) instead of the short benchmark's")
    ap.add_argument("--json", help="write the times here")
    args = ap.parse_args(argv)
    if args.full and args.what != "example":
        ap.error("--full is for --what example")
    if args.what == "example":  # the example's own bands
        args.bands = len(_examples().PLUME_BANDS)
    tmp = Path(tempfile.mkdtemp(prefix="photic_grid_cost_"))
    fields, nz = {"homogeneous": None}, {"homogeneous": 0.0}
    makers = (("sparse plume", plume), ("random dense", dense))
    if args.what == "example":
        makers = (("example plume", lambda n: _examples().plume_density((n, n, n))),)
    for name, make in makers:
        rho = make(args.n)
        nz[name] = float(np.count_nonzero(rho)) / rho.size
        fields[name] = tmp / (name.replace(" ", "_") + ".npz")
        np.savez(fields[name], density=rho)
        if args.cdom:  # the same grid with a second field
            two = name + CDOM
            ex = _examples()
            cdom = (ex.plume_density((args.n,) * 3, spread=ex.CDOM_SPREAD, lens=ex.CDOM_LENS)
                    if args.what == "example" else companion(rho))
            nz[two] = float(np.count_nonzero((rho > 0) | (cdom > 0))) / rho.size
            fields[two] = tmp / (two.replace(" ", "_").replace("+", "") + ".npz")
            np.savez(fields[two], density=rho, cdom=cdom)
    if args.mixed:  # each grid's water mixed evenly: homogeneous, the grid's mean IOPs
        for name in list(fields)[1:]:
            fields[name + MIXED], nz[name + MIXED] = fields[name], 0.0
    times: dict = {}
    render_times: dict = {}  # the renderer's own time: without reading the scene and its .npz
    segments: dict = {}  # path segments traced: more where the water scatters more
    for rep in range(args.repeat):
        for integ in args.integrators.split(","):
            # every other repeat in reverse order, so that no field always follows another
            order = list(fields.items()) if rep % 2 == 0 else list(fields.items())[::-1]
            for name, rho in order:
                t0 = time.perf_counter()
                sc = scene(integ, rho, args.what, args.bands, args.full)
                if name.endswith(MIXED):
                    homogenised(sc)
                if args.threads:
                    sc.settings.threads = args.threads
                res = render(sc)
                times.setdefault((integ, name), []).append(time.perf_counter() - t0)
                render_times.setdefault((integ, name), []).append(res.stats["time_s"])
                segments[(integ, name)] = res.stats["segments"]  # the same in every repeat
        print(f"repeat {rep + 1}/{args.repeat} done", flush=True)
    setup = {"both": "64 x 48 camera at 16 spp + 9 radiometers at 1e5 samples",
             "image": "160 x 120 camera at 64 spp",
             "example": "the plume example's scene (160 x 90 camera at 16 spp + 5 radiometers "
                        "at 1e5 samples, 10 bands)"}[args.what]
    if args.full:
        setup = ("the plume example's scene at the .blend's settings (480 x 270 camera at 96 spp + "
                 "5 radiometers at 1e6 samples, 10 bands)")
    print(f"\n{args.n}^3 grid, {setup}" + ("" if args.what == "example" else f", {args.bands} band(s)") + ", "
          f"{args.threads or 'all'} thread(s); median of {args.repeat}")
    print("(x homog.: ratio of the medians; paired: median of each repeat's ratio of renders made"
          " one after the other, which the shared machine's drifts disturb less; segments: path"
          " segments traced, x homog.; per segment: the render's paired ratio over that)")
    print(f"{'integrator':<10} {'water':<27} {'non-zero':>9} {'median s':>9} {'x homog.':>9}"
          f" {'render s':>9} {'x homog.':>9} {'paired':>7} {'segments':>9} {'per seg.':>9}")
    rows = []
    for integ in args.integrators.split(","):
        ref = statistics.median(times[(integ, "homogeneous")])
        ref_r = statistics.median(render_times[(integ, "homogeneous")])
        for name in fields:
            t = statistics.median(times[(integ, name)])
            tr = statistics.median(render_times[(integ, name)])
            paired = statistics.median(a / b for a, b in zip(render_times[(integ, name)],
                                                               render_times[(integ, "homogeneous")]))
            seg = segments[(integ, name)] / segments[(integ, "homogeneous")]
            print(f"{integ:<10} {name:<27} {nz[name]:>8.2%} {t:>9.2f} {t / ref:>9.2f}"
                  f" {tr:>9.2f} {tr / ref_r:>9.2f} {paired:>7.2f} {seg:>9.2f} {paired / seg:>9.2f}")
            rows.append({"integrator": integ, "water": name, "nonzero": nz[name], "median_s": t,
                         "ratio": t / ref, "times_s": times[(integ, name)],
                         "render_median_s": tr, "render_ratio": tr / ref_r,
                         "render_paired_ratio": paired,
                         "segments": segments[(integ, name)], "segments_ratio": seg,
                         "render_times_s": render_times[(integ, name)]})
    if args.cdom:
        print("\ntwo fields against the same grid's first field alone (render, paired, segments,"
              " per segment)")
        for integ in args.integrators.split(","):
            for name in [n for n in fields if n + CDOM in fields]:
                one, two = render_times[(integ, name)], render_times[(integ, name + CDOM)]
                paired = statistics.median(b / a for a, b in zip(one, two))
                seg = segments[(integ, name + CDOM)] / segments[(integ, name)]
                print(f"{integ:<10} {name + CDOM:<27} {statistics.median(two) / statistics.median(one):>9.2f}"
                      f" {paired:>7.2f} {seg:>9.2f} {paired / seg:>9.2f}")
    mixed = []
    if args.mixed:
        print("\nagainst the same water mixed evenly (homogeneous, the grid's mean IOPs: the same IOP"
              " model and components, on average the same scattering)")
        print(f"{'integrator':<10} {'water':<27} {'render x':>9} {'paired':>7} {'segments':>9} {'per seg.':>9}")
        for integ in args.integrators.split(","):
            for name in [n for n in fields if n + MIXED in fields]:
                grid, even = render_times[(integ, name)], render_times[(integ, name + MIXED)]
                ratio = statistics.median(grid) / statistics.median(even)
                paired = statistics.median(a / b for a, b in zip(grid, even))
                seg = segments[(integ, name)] / segments[(integ, name + MIXED)]
                print(f"{integ:<10} {name:<27} {ratio:>9.2f} {paired:>7.2f} {seg:>9.2f} {paired / seg:>9.2f}")
                mixed.append({"integrator": integ, "water": name, "render_ratio": ratio,
                              "render_paired_ratio": paired, "segments_ratio": seg})
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"n": args.n, "repeat": args.repeat, "what": args.what, "full": args.full,
                       "bands": args.bands,
                       "threads": args.threads, "rows": rows, "against_mixed": mixed}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
