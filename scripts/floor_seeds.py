"""The floor case of tests/test_floor_reflection.py (a Lambertian floor under a flat sea, no
scattering, a uniform sky, no sun) over many seeds: each radiometer's mean of the seeds against
the closed form (tests/analytic.py, FloorCase) with the seeds' own standard error, and the
seeds' spread over the median reported error. For biases smaller than one render's error.

    .venv/bin/python scripts/floor_seeds.py [--reflectance 0.7] [--absorption 0.15] [--seeds 32] [--samples 400000] [--first-seed 1000]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from analytic import FloorCase  # noqa: E402
from test_floor_reflection import floor_scene, sensors  # noqa: E402

from photic.render import render  # noqa: E402


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--reflectance", type=float, default=0.7)
    p.add_argument("--absorption", type=float, default=0.15)
    p.add_argument("--seeds", type=int, default=32)
    p.add_argument("--samples", type=int, default=400_000)
    p.add_argument("--first-seed", type=int, default=1000)
    args = p.parse_args(argv)
    R, a, H, h = args.reflectance, args.absorption, 1.5, 0.02
    scene = floor_scene(R, a, H, sensors(-(H - h), 1.0), l_sky=1.0, integrator="path")
    fc = FloorCase(R, a, H, h, 0.0, e_sun=0.0, l_sky=1.0)
    refs = {q: fc.irradiance(q) for q in ("Ed", "Eu", "Eo", "Eod", "Eou")}
    refs.update(Ldown=fc.radiance_cap(False, 10.0), Lup=fc.radiance_cap(True, 15.0), Lair=fc.air_radiance_down(5.0))
    values = {k: [] for k in refs}
    ses = {k: [] for k in refs}
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        res = render(scene, radiometer_samples=args.samples, seed=seed, threads=2)
        for k in refs:
            r = res.radiometer(k)
            values[k].append(float(r.mean[0, 0]))
            ses[k].append(float(r.stderr[0, 0]))
    print(f"floor R {R:g}, a {a:g} m^-1, {args.seeds} seeds of {args.samples:,} samples")
    for k, ref in refs.items():
        v, s = np.array(values[k]), np.array(ses[k])
        mean, sem = v.mean(), v.std(ddof=1) / np.sqrt(len(v))
        print(f"  {k:6s} closed form {ref:.6f}  mean {mean:.6f}  {100 * (mean / ref - 1):+.3f} % "
              f"+- {100 * sem / ref:.3f} % (z {(mean - ref) / sem:+.2f}); spread / median SE "
              f"{v.std(ddof=1) / np.median(s):.2f}")


if __name__ == "__main__":
    main()
