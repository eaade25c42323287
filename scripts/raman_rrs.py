"""Rrs of clear and of greener water with and without Raman scattering (docs/verification.md,
"Raman scattering"): pure water (Pope and Fry 1997) with a little CDOM and particles (the
particles' b at 550 nm the --particles values), 16 bands of 20 nm from 400 to 700 nm, a flat deep sea, the
sun at 30 degrees, a black sky; Rrs = Lu(0+) / Ed(0+) from a radiometer 1 m above the water
looking straight down (a 2 degree cap: no glint, no sky to reflect, so Lu(0+) is the
water-leaving radiance) and the sun's irradiance on the horizontal. Hybrid integrator; the
Raman component of Lu gives the Raman share of Rrs in the same render.

    .venv/bin/python scripts/raman_rrs.py [--particles 0.02 0.3] [--samples 400000] [--plot docs/images/raman_rrs.png]
"""
from __future__ import annotations

import argparse
import math
import time

import numpy as np

from photic.plots import linear_panels, save_figure
from photic.render import render
from photic.scene import Scene, scene_warnings

CENTERS = np.arange(400.0, 701.0, 20.0)  # 16 bands: one group (Raman light crosses no group)
ZENITH = 30.0


def scene(bp: float, raman: bool) -> Scene:
    """Pure water, CDOM a_g(440) = 0.01 m^-1 (slope 0.014 per nm) and particles of b(550) =
    bp m^-1 (lambda^-1, backscatter fraction 0.01, absorbing a(440) = 0.1 bp, slope 0.011)."""
    model = {"model": "mixture", "components": [
        {"model": "cdom", "a_ref": 0.01, "wavelength_ref_nm": 440.0, "slope": 0.014},
        {"model": "particles", "b_ref": bp, "wavelength_ref_nm": 550.0, "exponent": 1.0,
         "backscatter_fraction": 0.01, "a_ref": 0.1 * bp, "absorption_ref_nm": 440.0,
         "absorption_slope": 0.011}]}
    return Scene.from_dict({
        "photic_scene": 1, "name": f"raman_rrs_bp{bp:g}",
        "bands": [{"name": f"{c:.0f}", "center_nm": float(c), "width_nm": 20.0} for c in CENTERS],
        "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0},
                   "iop_model": model}],
        "sun": {"zenith_deg": ZENITH, "azimuth_deg": 0.0, "irradiance": [1.0] * len(CENTERS)},
        "radiometers": [{"name": "Lu", "quantity": "radiance", "position": [0.0, 0.0, 1.0],
                         "direction": [0.0, 0.0, -1.0], "half_angle_deg": 2.0}],
        "settings": {"integrator": "hybrid", "raman": raman, "seed": 11}})


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--particles", type=float, nargs="+", default=[0.02, 0.3],
                   help="the particles' scattering coefficient at 550 nm (m^-1), one water per value")
    p.add_argument("--samples", type=int, default=400_000)
    p.add_argument("--plot", default="docs/images/raman_rrs.png")
    args = p.parse_args(argv)
    ed = math.cos(math.radians(ZENITH))  # the sun's irradiance on the horizontal (1 normal to it)
    series = []
    for chl in args.particles:
        c0 = time.process_time()
        on = render(scene(chl, True), radiometer_samples=args.samples, threads=2).radiometers[0]
        c1 = time.process_time()
        off = render(scene(chl, False), radiometer_samples=args.samples, threads=2).radiometers[0]
        c2 = time.process_time()
        for w in scene_warnings(scene(chl, True)):
            print(f"  warning: {w}")
        rrs_on, rrs_off = on.mean[0] / ed, off.mean[0] / ed
        se_on, se_off = on.stderr[0] / ed, off.stderr[0] / ed
        raman, raman_se = on.components["raman"][0][0] / ed, on.components["raman"][1][0] / ed
        print(f"particles b(550) = {chl:g} m^-1: Rrs (sr^-1) with / without Raman, Raman share of Rrs; "
              f"CPU {c1 - c0:.1f} s with Raman, {c2 - c1:.1f} s without ({(c1 - c0) / (c2 - c1):.2f}x)")
        print(f"{'band':>6} {'with':>12} {'+-':>9} {'without':>12} {'+-':>9} {'Raman':>12} {'share':>7}")
        for k, c in enumerate(CENTERS):
            share = raman[k] / rrs_on[k] if rrs_on[k] > 0 else float("nan")
            print(f"{c:>6.0f} {rrs_on[k]:>12.4e} {se_on[k]:>9.1e} {rrs_off[k]:>12.4e} {se_off[k]:>9.1e} "
                  f"{raman[k]:>12.4e} {100 * share:>6.1f}%")
        series.append((chl, rrs_on, rrs_off, raman))
    if args.plot:
        colours = [(40, 90, 200), (40, 150, 60), (200, 40, 40)]
        top = max(float(np.max(on)) for _, on, _, _ in series) * 1.1
        step = 10 ** math.floor(math.log10(top / 4))
        rrs = {"title": "Rrs with Raman (dark) and without (light)", "xlabel": "wavelength (nm)",
               "ylabel": "Rrs (1/sr)", "legend": True, "series": [], "ylim": (0.0, top),
               "yticks": np.arange(0.0, top, 2 * step), "xticks": np.arange(400, 701, 50)}
        share = {"title": "Raman share of Rrs", "xlabel": "wavelength (nm)", "ylabel": "%",
                 "legend": True, "series": [], "ylim": (0.0, 20.0), "yticks": np.arange(0, 21, 5),
                 "xticks": np.arange(400, 701, 50)}
        for (chl, on, off, raman), col in zip(series, colours):
            rrs["series"] += [(f"b_p {chl:g}/m, with Raman", CENTERS, on, col),
                              (f"b_p {chl:g}/m, without", CENTERS, off, tuple(min(255, x + 110) for x in col))]
            share["series"].append((f"b_p {chl:g}/m", CENTERS, 100 * raman / np.maximum(on, 1e-30), col))
        save_figure(linear_panels([rrs, share]), args.plot)
        print(f"plot: {args.plot}")


if __name__ == "__main__":
    main()
