"""How point irradiances below waves depend on the patch's mesh refinement.

The calibration patch (20 m, JONSWAP 6 m/s, 64 x 64), no scattering (a 0.1: the refracted sun's
direct light alone, which the beams give without noise), the real 0.53 deg sun: Ed at 64 points
over one period, 1 and 5 m down, for mesh_refinement 1, 2, 4, 8, 16 (the same waves sampled
finer). Per depth and refinement: the mean over the points, the root-mean-square and largest
relative difference from the finest, and the brightest point over the mean. ``--path N``: also
pure path tracing (N samples per radiometer) at two points, coarse and refined 4x, against the
beams (slow: about 150 s per 4e7 samples on 1 thread).

    .venv/bin/python scripts/caustic_resolution.py --sun 30
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from photic.render import render
from photic.scene import Scene

WAVES = {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0, "fetch_m": 50000.0,
         "patch_size_m": [20.0, 20.0], "resolution": [64, 64], "seed": 0}
REFINEMENTS = (1, 2, 4, 8, 16)


def direct_scene(zenith: float, refinement: int, integrator: str = "hybrid", points=None) -> Scene:
    g = (np.arange(8) + 0.5) * 20.0 / 8
    pts = points or [(f"Ed_{z:g}_{i}", x, y, z) for z in (1.0, 5.0) for i, (x, y) in enumerate((x, y) for x in g for y in g)]
    return Scene.from_dict({
        "photic_scene": 1, "name": "caustics",
        "water": [{"name": "sea", "type": "ocean", "surface": dict(WAVES, mesh_refinement=refinement),
                   "iops": {"absorption": [0.1], "b": [0.0], "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": zenith, "azimuth_deg": 30.0, "irradiance": [1.0], "angular_diameter_deg": 0.53},
        "sky": {"type": "black"},
        "radiometers": [{"name": n, "quantity": "Ed", "position": [x, y, -z]} for n, x, y, z in pts],
        "settings": {"integrator": integrator, "seed": 5, "forward_cone_deg": 0}})


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sun", type=float, default=30.0, help="sun zenith angle (deg)")
    ap.add_argument("--path", type=float, default=0, help="path-tracing samples per radiometer (0: none)")
    ap.add_argument("--threads", type=int, default=2)
    a = ap.parse_args(argv)
    vals, names = {}, None
    for r in REFINEMENTS:
        t = time.time()
        res = render(direct_scene(a.sun, r), radiometer_samples=1024, threads=a.threads)
        vals[r] = np.array([x.mean[0, 0] for x in res.radiometers])
        names = [x.name for x in res.radiometers]
        print(f"refinement {r:2d}: {time.time() - t:.1f} s", flush=True)
    print("| depth | refinement | mean Ed | RMS difference from 16x | largest | brightest / mean |")
    print("| --- | --- | --- | --- | --- | --- |")
    for z in ("1", "5"):
        m = np.array([n.startswith(f"Ed_{z}_") for n in names])
        ref = vals[REFINEMENTS[-1]][m]
        for r in REFINEMENTS:
            v = vals[r][m]
            d = v / ref - 1.0
            print(f"| {z} m | {r} | {v.mean():.4f} | {100 * np.sqrt(np.mean(d ** 2)):.1f} % | "
                  f"{100 * np.abs(d).max():.1f} % | {v.max() / v.mean():.2f} |")
    if a.path:
        pts = [("Ed_5_4", 1.25, 11.25, 5.0), ("Ed_5_9", 3.75, 3.75, 5.0)]
        for r in (1, 4):
            hy = render(direct_scene(a.sun, r, points=pts), radiometer_samples=1024, threads=a.threads)
            t = time.time()
            pt = render(direct_scene(a.sun, r, "path", pts), radiometer_samples=int(a.path), threads=a.threads)
            for h, p in zip(hy.radiometers, pt.radiometers):
                z = (h.mean[0, 0] - p.mean[0, 0]) / np.hypot(h.stderr[0, 0], p.stderr[0, 0])
                print(f"refinement {r}, {h.name}: beams {h.mean[0, 0]:.4f}, path tracing {p.mean[0, 0]:.4f} +- "
                      f"{p.stderr[0, 0]:.4f} (z {z:+.1f}; {time.time() - t:.0f} s)", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
