"""The sky's (and, with the hybrid, the sun's) Raman Lu at 531 nm against its closed form over
many seeds: the scene of tests/test_raman.py's gridded-water test (a 3-D grid of an absorbing
field, density 0.5 everywhere, over clear water) and the same water made homogeneous (the
field's absorption folded into the base). The mean of the seeds against the closed form with
the seeds' own standard error, and the seeds' spread over the median reported error (honest
error bars: about 1).

    .venv/bin/python scripts/raman_seeds.py [--integrator path hybrid] [--seeds 16] [--samples 4000000]
"""
from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import test_raman as T  # noqa: E402  (the test's scene and closed forms)

from photic import inelastic  # noqa: E402
from photic.render import render  # noqa: E402
from photic.scene import Scene  # noqa: E402

UNIT = {"absorption": [0.01, 0.02], "b": [0.0, 0.0], "phase": {"type": "isotropic"}}


def waters(integrator: str) -> dict[str, dict]:
    d0 = T._sky_sea(integrator).to_dict()
    grid = copy.deepcopy(d0)
    water = grid["water"][0]
    base = water.pop("iops")
    water["iop_grid"] = {"base": {"iops": base}, "unit": {"iops": UNIT}, "origin": [-5000.0, -5000.0, -3000.0],
                         "size": [10000.0, 10000.0, 3001.0], "density": np.full((2, 2, 3), 0.5).tolist()}
    homog = copy.deepcopy(d0)
    homog["water"][0]["iops"]["absorption"] = [a + 0.5 * u for a, u in zip(T.SKY_A, UNIT["absorption"])]
    return {"homogeneous": homog, "gridded": grid}


def closed_form(integrator: str) -> float:
    c = np.asarray(T.SKY_A) + 0.5 * np.asarray(UNIT["absorption"]) + inelastic.raman_b([b.center_nm for b in T.BANDS])
    tau = [lambda z0, z1, k=k: c[k] * (z1 - z0) for k in range(2)]
    expect = T._sky_raman_nadir_radiance(tau[0], tau[1], 1.0, 1.0)
    if integrator == "hybrid":
        expect += T._sun_raman_radiance_in_cap(tau[0], tau[1], 1.0, np.radians(2.0))
    return float(expect)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--integrator", nargs="+", default=["path", "hybrid"])
    p.add_argument("--seeds", type=int, default=16)
    p.add_argument("--samples", type=int, default=4_000_000)
    args = p.parse_args(argv)
    for integrator in args.integrator:
        expect = closed_form(integrator)
        print(f"{integrator}: closed form {expect:.6e}")
        for name, d in waters(integrator).items():
            values, ses = [], []
            for seed in range(100, 100 + args.seeds):
                r = render(Scene.from_dict(d), radiometer_samples=args.samples, seed=seed, threads=2).radiometers[0]
                values.append(float(r.mean[0, 1]))
                ses.append(float(r.stderr[0, 1]))
            v, s = np.array(values), np.array(ses)
            mean, sem = v.mean(), v.std(ddof=1) / np.sqrt(len(v))
            print(f"  {name:12s} mean of {len(v)} seeds {mean:.6e}: {100 * (mean / expect - 1):+.3f} % "
                  f"+- {100 * sem / expect:.3f} % (z {(mean - expect) / sem:+.2f}); seeds' spread / median "
                  f"reported SE {v.std(ddof=1) / np.median(s):.2f}", flush=True)


if __name__ == "__main__":
    main()
