"""Rrs of clear and of chlorophyll-rich water with and without inelastic light (Raman
scattering, chlorophyll and CDOM fluorescence): the example examples/chlorophyll_bloom.json
(new Case-1 water of Bricaud et al. 1998 with its co-varying CDOM, 15 bands of 20 nm from 410
to 690 nm, a flat deep sea, the sun at 30 degrees, a black sky) at two chlorophyll
concentrations, each rendered as the file says (all three processes) and purely elastic (Raman
off, no fluorescence). Rrs = Lu(0+) / Ed(0+) from the example's radiometers 1 m above the water
(no glint or sky to reflect, so Lu(0+) is the water-leaving radiance); each process's share of
Rrs from its component of Lu(0+) in the same render. Also what the inelastic light costs
(with --seeds N): CPU time x the variance of Rrs over N seeds' renders (their spread, not the
reported errors, which are themselves noisy), with against without, per band; "elastic bands"
are those whose inelastic share is under 1 %.

    .venv/bin/python scripts/inelastic_rrs.py [--chlorophyll 0.05 5] [--samples 400000] [--seeds 8 --seed-samples 100000] [--plot docs/images/inelastic_rrs.png]
"""
from __future__ import annotations

import argparse
import copy
import json
import math
import time
from pathlib import Path

import numpy as np

from photic.plots import linear_panels, save_figure
from photic.render import render
from photic.scene import Scene, scene_warnings

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "chlorophyll_bloom.json"
PROCESSES = ("raman", "chlorophyll", "cdom")


def scene(chlorophyll: float, inelastic: bool) -> Scene:
    d = json.loads(EXAMPLE.read_text())
    water = d["water"][0]
    water["iop_model"]["chlorophyll"] = chlorophyll
    d["name"] = f"chlorophyll_{chlorophyll:g}_{'inelastic' if inelastic else 'elastic'}"
    if not inelastic:
        d["settings"]["raman"] = False
        water.pop("chlorophyll_fluorescence")
        water.pop("cdom_fluorescence")
    return Scene.from_dict(copy.deepcopy(d), base_dir=EXAMPLE.parent)


def rrs(result) -> tuple[np.ndarray, np.ndarray, dict]:
    """Rrs and its SE per band, and each process's component of Rrs."""
    lu = next(r for r in result.radiometers if r.name == "Lu(0+)")
    ed = next(r for r in result.radiometers if r.name == "Ed(0+)")
    e = ed.mean[0]
    value = lu.mean[0] / e
    se = np.hypot(lu.stderr[0] / e, value * ed.stderr[0] / e)
    parts = {c: lu.components[c][0][0] / e for c in PROCESSES if c in lu.components}
    return value, se, parts


def seeds_cost(on_scene: Scene, off_scene: Scene, seeds: int, samples: int) -> np.ndarray:
    """Per band: (CPU time x variance of Rrs over ``seeds`` renders) with over without."""
    out = []
    for sc in (on_scene, off_scene):
        values, cpu = [], 0.0
        for seed in range(seeds):
            c0 = time.process_time()
            values.append(rrs(render(sc, radiometer_samples=samples, threads=2, seed=100 + seed))[0])
            cpu += time.process_time() - c0
        out.append(cpu * np.var(values, axis=0, ddof=1))
    return out[0] / out[1]


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--chlorophyll", type=float, nargs="+", default=[0.05, 5.0],
                   help="chlorophyll concentrations (mg m^-3), one water per value")
    p.add_argument("--samples", type=int, default=400_000)
    p.add_argument("--seeds", type=int, default=0, help="seeds per render for the cost table (0: none)")
    p.add_argument("--seed-samples", type=int, default=100_000)
    p.add_argument("--plot", default="docs/images/inelastic_rrs.png")
    args = p.parse_args(argv)
    series = []
    centers = None
    for chl in args.chlorophyll:
        on_scene, off_scene = scene(chl, True), scene(chl, False)
        centers = np.array([b.center_nm for b in on_scene.bands])
        c0 = time.process_time()
        on = rrs(render(on_scene, radiometer_samples=args.samples, threads=2))
        c1 = time.process_time()
        off = rrs(render(off_scene, radiometer_samples=args.samples, threads=2))
        c2 = time.process_time()
        for w in scene_warnings(on_scene):
            print(f"  warning: {w}")
        print(f"chlorophyll {chl:g} mg m^-3: Rrs (sr^-1) with / without inelastic light, each process's "
              f"share of Rrs; CPU {c1 - c0:.1f} s with, {c2 - c1:.1f} s without ({(c1 - c0) / (c2 - c1):.2f}x)")
        cost = seeds_cost(on_scene, off_scene, args.seeds, args.seed_samples) if args.seeds > 1 else None
        print(f"{'band':>6} {'with':>11} {'+-':>8} {'without':>11} {'+-':>8} {'Raman':>7} {'chl':>7} "
              f"{'CDOM':>7}" + (f" {'cost':>6}" if cost is not None else ""))
        inelastic_share = sum(on[2][x] for x in PROCESSES) / on[0]
        for k, c in enumerate(centers):
            shares = [100 * on[2][x][k] / on[0][k] for x in PROCESSES]
            print(f"{c:>6.0f} {on[0][k]:>11.4e} {on[1][k]:>8.1e} {off[0][k]:>11.4e} {off[1][k]:>8.1e} "
                  + " ".join(f"{s:>6.1f}%" for s in shares) + (f" {cost[k]:>5.2f}x" if cost is not None else ""))
        if cost is not None:
            elastic = inelastic_share < 0.01
            print(f"cost for the same error (CPU x variance over {args.seeds} seeds of {args.seed_samples} samples, "
                  f"with / without): elastic bands median {np.median(cost[elastic]):.2f}x (largest "
                  f"{cost[elastic].max():.2f}x), all bands median {np.median(cost):.2f}x (largest {cost.max():.2f}x)")
        series.append((chl, on, off))
    if args.plot:
        colours = [(40, 90, 200), (40, 150, 60), (200, 40, 40)]
        top = max(float(np.max(on[0])) for _, on, _ in series) * 1.1
        step = 10 ** math.floor(math.log10(top / 4))
        panel_rrs = {"title": "Rrs with inelastic light (dark) and without (light)", "xlabel": "wavelength (nm)",
                     "ylabel": "Rrs (1/sr)", "legend": True, "series": [], "ylim": (0.0, top),
                     "yticks": np.arange(0.0, top, 2 * step), "xticks": np.arange(400, 701, 50)}
        panel_share = {"title": "Each process's share of Rrs", "xlabel": "wavelength (nm)",
                       "ylabel": "%", "legend": True, "series": [], "ylim": (0.0, 50.0),
                       "yticks": np.arange(0, 51, 10), "xticks": np.arange(400, 701, 50)}
        shades = {"raman": 0, "chlorophyll": 70, "cdom": 140}
        for (chl, on, off), col in zip(series, colours):
            light = tuple(min(255, x + 110) for x in col)
            panel_rrs["series"] += [(f"Chl {chl:g}, with", centers, on[0], col),
                                    (f"Chl {chl:g}, without", centers, off[0], light)]
            for x in PROCESSES:
                panel_share["series"].append((f"Chl {chl:g}: {x}", centers, 100 * on[2][x] / np.maximum(on[0], 1e-30),
                                              tuple(min(255, v + shades[x]) for v in col)))
        save_figure(linear_panels([panel_rrs, panel_share]), args.plot)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
