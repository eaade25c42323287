"""The floor case of docs/verification.md: a flat sea, water that absorbs and does not scatter,
a Lambertian floor, the real sun; Ed 1 cm above the floor and the radiance 1 m above the water
looking straight down, against their closed form (tests/analytic.py, FloorCase).

    .venv/bin/python scripts/floor_case.py [--samples 262144] [--seed 7] [--core OTHER_CORE.so]

Prints one Markdown row per case: reflectance, sun zenith, quantity, value +- standard error,
closed form, and the difference in per cent and in standard errors. ``--core`` loads another
build of the core (``_core*.so``), e.g. one kept from before a change.
"""
from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=262144)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--core", default=None, help="another build of the core (_core*.so)")
    args = ap.parse_args(argv)
    if args.core:
        import photic
        spec = importlib.util.spec_from_file_location("photic._core", args.core)
        core = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(core)
        sys.modules["photic._core"] = core
        photic._core = core
    sys.path.insert(0, str(ROOT / "tests"))
    from analytic import FloorCase
    from test_floor_reflection import floor_scene

    from photic.render import render

    H, h, a = 2.0, 0.01, 0.1
    print("| R | sun zenith | quantity | value +- SE | closed form | difference |")
    print("| --- | --- | --- | --- | --- | --- |")
    for R in (0.0, 0.5, 0.9):
        for zen in (0.0, 30.0, 60.0):
            rads = [{"name": "Ed", "quantity": "Ed", "position": [0, 0, -(H - h)]}]
            if zen == 30.0 and R > 0:  # the glint stays outside the caps
                rads += [{"name": f"L air, {c:g} deg cap", "quantity": "radiance", "direction": [0, 0, -1],
                          "half_angle_deg": c, "position": [0, 0, 1.0]} for c in (1.0, 5.0)]
            res = render(floor_scene(R, a, H, rads, zenith=zen, seed=args.seed), radiometer_samples=args.samples)
            fc = FloorCase(R, a, H, h, zen)
            for r in res.radiometers:
                cap = None if r.name == "Ed" else float(r.name.split()[2])
                ref = fc.irradiance("Ed") if cap is None else fc.air_radiance_down(cap)
                m, se = r.mean[0, 0], r.stderr[0, 0]
                z = (m - ref) / se if se > 0 else 0.0
                print(f"| {R:g} | {zen:g} | {r.name} | {m:.6f} +- {se:.6f} | {ref:.6f} | "
                      f"{100 * (m / ref - 1):+.2f} % ({z:+.1f} SE) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
