"""A forward cone against the exact mode below waves, point by point.

Ed at 64 points over one period of the calibration patch (20 m, JONSWAP 6 m/s, 64 x 64, its mesh
refined ``--refinement`` times; a 0.1,
b 0.2 Petzold, sand 6 m down, the real 0.53 deg sun, black sky), 1 and 5 m down, rendered with
each forward cone given (the first is the reference): per depth the ratio of the means over
the 64 points, the range of the per-point ratios and the z-scores' spread (1 where the two
agree point by point). ``--path N``: also pure path tracing at the points where the second
cone is farthest from the first (N samples per radiometer: a referee, slow: about 450 s for
2 x 2e8 samples on 2 cores).

    .venv/bin/python scripts/forward_cone_points.py --sun 30 --samples 8192 --cones 0,3
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from photic.render import render
from photic.scene import Scene

WAVES = {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0, "fetch_m": 50000.0,
         "patch_size_m": [20.0, 20.0], "resolution": [64, 64], "seed": 0}
DEPTHS = (1.0, 5.0)


def points_scene(zenith: float, cone: float, seed: int, per_side: int = 8, refinement: int = 1) -> Scene:
    g = (np.arange(per_side) + 0.5) * 20.0 / per_side
    rads = [{"name": f"Ed_{z:g}_{i}", "quantity": "Ed", "position": [float(x), float(y), -z]}
            for z in DEPTHS for i, (x, y) in enumerate((x, y) for x in g for y in g)]
    return Scene.from_dict({
        "photic_scene": 1, "name": "cone_points",
        "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]}},
        "water": [{"name": "sea", "type": "ocean", "surface": dict(WAVES, mesh_refinement=refinement), "bottom": {"depth": 6.0, "material": "sand"},
                   "iops": {"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": zenith, "azimuth_deg": 30.0, "irradiance": [1.0], "angular_diameter_deg": 0.53},
        "sky": {"type": "black"}, "radiometers": rads,
        "settings": {"integrator": "hybrid", "seed": seed, "forward_cone_deg": cone}})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sun", type=float, default=30.0, help="sun zenith angle (deg)")
    ap.add_argument("--samples", type=int, default=8192, help="samples per radiometer")
    ap.add_argument("--cones", default="0,3", help="forward cones (deg), the first the reference")
    ap.add_argument("--path", type=int, default=0, help="path-tracing samples at the two farthest points")
    ap.add_argument("--refinement", type=int, default=1, help="the patch's mesh_refinement")
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args(argv)
    cones = [float(c) for c in a.cones.split(",")]
    out = {}
    for cone in cones:
        t = time.time()
        res = render(points_scene(a.sun, cone, 1, refinement=a.refinement), radiometer_samples=a.samples, threads=a.threads)
        out[cone] = {r.name: (float(r.mean[0, 0]), float(r.stderr[0, 0])) for r in res.radiometers}
        print(f"cone {cone:g} deg: {time.time() - t:.1f} s", flush=True)
    ref = out[cones[0]]
    far = []
    for cone in cones[1:]:
        for z in DEPTHS:
            names = [k for k in ref if k.startswith(f"Ed_{z:g}_")]
            a_, sa = (np.array([out[cone][k][i] for k in names]) for i in (0, 1))
            b_, sb = (np.array([ref[k][i] for k in names]) for i in (0, 1))
            zz = (a_ - b_) / np.hypot(sa, sb)
            r = a_ / b_
            print(f"sun {a.sun:g} deg, Ed {z:g} m down, cone {cone:g} / {cones[0]:g}: mean {a_.mean() / b_.mean():.4f}, "
                  f"per point {r.min():.3f}-{r.max():.3f}, z rms {np.sqrt(np.mean(zz ** 2)):.2f}, "
                  f"largest |z| {np.abs(zz).max():.1f} (median relative error {np.median(sb / b_):.4f})")
            if z == DEPTHS[-1] and cone == cones[1]:
                far = [names[int(np.argmin(r))], names[int(np.argmax(r))]]
    if a.path and far:
        sc = points_scene(a.sun, 0.0, 7, refinement=a.refinement)
        sc.radiometers = [r for r in sc.radiometers if r.name in far]
        sc.settings.integrator = "path"
        t = time.time()
        res = render(sc, radiometer_samples=a.path, threads=a.threads)
        for r in res.radiometers:
            line = ", ".join(f"cone {c:g}: {out[c][r.name][0]:.4f} +- {out[c][r.name][1]:.4f}" for c in cones)
            print(f"{r.name}: path tracing {r.mean[0, 0]:.4f} +- {r.stderr[0, 0]:.4f} ({time.time() - t:.0f} s); {line}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
