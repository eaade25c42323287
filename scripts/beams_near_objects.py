"""Ed above an object under waves: the scene of issue 25 (an object changed the beams far away).

A JONSWAP sea (20 m period, 64 x 64, wind 6 m/s), water a = 0.1, b = 0.2 Petzold, the real
0.53 deg sun at 30 deg zenith, azimuth 290, sand 5 m down, Blender's default 2 m cube centred
at (0, 0, -4), and a 5 x 5 grid of Ed radiometers at 2 m depth (x -5 ... 11, y -8 ... 8 m),
black sky, hybrid, 4,000 samples each. Printed: the grid's mean Ed without the cube, with it,
and with it while the radiometers are shifted by two periods (40, 40) m; per-point z against
the cube-free values (independent seeds); and hybrid against path tracing with a 5 deg sun at
the same points, where both converge.

    .venv/bin/python scripts/beams_near_objects.py           # about a minute on 2 cores
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from photic.render import render
from photic.scene import Scene


def cube(centre=(0.0, 0.0, -4.0), half=1.0) -> dict:
    c = np.asarray(centre)
    lo, hi = c - half, c + half
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
         [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]]
    t = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
         [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    return {"name": "Cube", "material": "grey", "vertices": v, "triangles": t}


def grid(shift=(0.0, 0.0)) -> list[tuple[float, float, float]]:
    return [(x + shift[0], y + shift[1], -2.0) for x in range(-5, 12, 4) for y in range(-8, 9, 4)]


def scene(with_cube: bool, points, integrator="hybrid", diameter=0.53, seed=1) -> Scene:
    d = {"photic_scene": 1, "name": "cube_under_waves",
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]},
                       "grey": {"type": "lambertian", "reflectance": [0.5]}},
         "meshes": [cube()] if with_cube else [],
         "water": [{"name": "sea", "type": "ocean",
                    "surface": {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0,
                                "fetch_m": 50000.0, "patch_size_m": [20, 20], "resolution": [64, 64],
                                "seed": 0},
                    "bottom": {"depth": 5.0, "material": "sand"},
                    "iops": {"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": 30.0, "azimuth_deg": 290.0, "irradiance": [1.0],
                 "angular_diameter_deg": diameter},
         "sky": {"type": "black"},
         "radiometers": [{"name": f"Ed_{i}", "quantity": "Ed", "position": list(p)}
                         for i, p in enumerate(points)],
         "settings": {"integrator": integrator, "seed": seed}}
    return Scene.from_dict(d)


def values(res):
    return (np.array([r.mean[0, 0] for r in res.radiometers]),
            np.array([r.stderr[0, 0] for r in res.radiometers]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=4000)
    ap.add_argument("--path-samples", type=int, default=400_000)
    a = ap.parse_args(argv)
    runs = {}
    for key, kw in [("without the cube", dict(with_cube=False, points=grid(), seed=1)),
                    ("with the cube", dict(with_cube=True, points=grid(), seed=2)),
                    ("with the cube, shifted (40, 40) m", dict(with_cube=True, points=grid((40, 40)), seed=3))]:
        t = time.perf_counter()
        runs[key] = values(render(scene(**kw), radiometer_samples=a.samples))
        m, s = runs[key]
        print(f"{key:34s} mean Ed {m.mean():.4f} +- {np.sqrt((s ** 2).sum()) / len(s):.4f}"
              f"  ({time.perf_counter() - t:.1f} s)", flush=True)
    m0, s0 = runs["without the cube"]
    for key in list(runs)[1:]:
        m, s = runs[key]
        z = (m - m0) / np.hypot(s, s0)
        print(f"{key:34s} z per point against the cube-free sea: {z.min():+.2f} ... {z.max():+.2f}")
    # both integrators under a 5 deg sun, with the cube
    hy = values(render(scene(True, grid(), "hybrid", 5.0, 4), radiometer_samples=a.samples))
    pt = values(render(scene(True, grid(), "path", 5.0, 5), radiometer_samples=a.path_samples))
    z = (hy[0] - pt[0]) / np.hypot(hy[1], pt[1])
    se = [np.sqrt((x[1] ** 2).sum()) / len(x[1]) for x in (hy, pt)]
    print(f"5 deg sun, with the cube: hybrid {hy[0].mean():.4f} +- {se[0]:.4f}, path tracing "
          f"{pt[0].mean():.4f} +- {se[1]:.4f}; z per point {z.min():+.2f} ... {z.max():+.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
