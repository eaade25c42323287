"""tests/test_floor_reflection.py's cameras-against-radiometers comparison over many seeds:
each comparison's z-score (camera minus radiometer over their combined standard error) per
seed, and per comparison the mean z over the seeds with its standard error (1 / sqrt(seeds)
for honest error bars). A bias smaller than one render's error shows as a mean z many of its
standard errors from 0; honest error bars as z's spread near 1.

    .venv/bin/python scripts/camera_radiometer_seeds.py [--surface waves] [--b 0.15] [--seeds 8] [--first-seed 100]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import test_floor_reflection as tfr  # noqa: E402

from photic.render import render  # noqa: E402


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--surface", default="waves", choices=["flat", "waves"])
    p.add_argument("--b", type=float, default=0.15)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--first-seed", type=int, default=100)
    args = p.parse_args(argv)
    zs: dict[str, list[float]] = {}
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        def record(label, value, reference, stderr):
            zs.setdefault(label, []).append((value - reference) / stderr if stderr > 0 else 0.0)
            return 0.0  # (the test's own bound is not applied here)
        tfr.render = lambda sc, **kw: render(sc, seed=seed, **kw)
        tfr.test_cameras_and_radiometers_agree_on_every_quantity(record, args.surface, args.b)
        print(f"seed {seed}: largest |z| {max(abs(v[-1]) for v in zs.values()):.2f}", flush=True)
    n = args.seeds
    allz = np.array([z for v in zs.values() for z in v])
    print(f"\n{len(zs)} comparisons x {n} seeds: z spread {allz.std():.2f}, |z| > 3: {np.sum(np.abs(allz) > 3)} "
          f"(normal: {0.0027 * allz.size:.1f})")
    print(f"{'comparison':<42} {'mean z':>7} {'+-':>5} {'mean/se':>8}")
    for label, v in sorted(zs.items(), key=lambda kv: -abs(np.mean(kv[1]))):
        m = float(np.mean(v))
        print(f"{label:<42} {m:>7.2f} {1 / np.sqrt(n):>5.2f} {m * np.sqrt(n):>8.2f}")


if __name__ == "__main__":
    main()
