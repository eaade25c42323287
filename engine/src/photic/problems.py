"""Canonical problems 1 and 2 of Mobley et al. 1993 (Appl. Opt. 32:7484).

Homogeneous, infinitely deep water under a level surface (n = 1.34), black sky, sun at 60 deg
zenith with unit irradiance normal to it; c = 1 m^-1 so that optical depth equals depth in
metres; single-scattering albedo 0.2 or 0.9; phase function: pure water shape (problem 1) or
Petzold's average particle (problem 2). Ed, Eou and Lu (averaged over the nadir-viewing polar
cap mu >= 0.9, as the published numbers are) at optical depths 1, 5 and 10. The scene files are
kept in ``examples/problems`` of the repository and written by :func:`problem_scene`.

A value passes when ``|ours - ref| <= (2 CV + 0.005) ref + 3 SE``: CV is the spread between
the published models, 0.005 the rounding of the published values, SE our standard error. By
default each radiometer stops when its SE is a third of that band (``band_targets``), the
files' sample counts being the most it may take.
"""
from __future__ import annotations

import csv
import math
import time
from importlib import resources

from .render import render
from .scene import Scene

TAUS = (1.0, 5.0, 10.0)
QUANTITIES = ("Ed", "Eou", "Lu")
CONFIGS = [(1, 0.2), (1, 0.9), (2, 0.2), (2, 0.9)]
LU_CAP_DEG = math.degrees(math.acos(0.9))  # polar cap mu >= 0.9


def reference_table() -> dict:
    """{(problem, omega0, tau, quantity): (mean of models, CV)}."""
    text = resources.files("photic.data").joinpath("mobley1993_problems_1_2_reference.csv").read_text()
    rows = csv.DictReader(line for line in text.splitlines() if line and not line.startswith("#"))
    return {(int(r["problem"]), float(r["omega0"]), float(r["tau"]), r["quantity"]):
            (float(r["mean_of_models"]), float(r["cv_std_over_mean"])) for r in rows}


def problem_scene(problem: int, omega0: float, samples: int = 600_000, seed: int = 1993) -> dict:
    """The scene description (a dict, as in the JSON files) of one configuration."""
    phase = {"type": "pure_water"} if problem == 1 else {"type": "petzold"}
    rads = []
    for tau in TAUS:
        z = -tau  # c = 1 per metre
        rads += [{"name": f"Ed_tau{tau:g}", "quantity": "Ed", "position": [0.0, 0.0, z]},
                 {"name": f"Eou_tau{tau:g}", "quantity": "Eou", "position": [0.0, 0.0, z]},
                 {"name": f"Lu_tau{tau:g}", "quantity": "radiance", "position": [0.0, 0.0, z],
                  "direction": [0.0, 0.0, -1.0], "half_angle_deg": LU_CAP_DEG}]
    return {
        "photic_scene": 1,
        "name": f"mobley1993_problem{problem}_omega{omega0:g}",
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": {"kind": "flat", "z": 0.0},
                   "iops": {"absorption": [1.0 - omega0], "b": [omega0], "phase": phase}}],
        "sun": {"zenith_deg": 60.0, "azimuth_deg": 0.0, "irradiance": [1.0]},
        "sky": {"type": "black"},
        "radiometers": rads,
        "settings": {"integrator": "hybrid", "radiometer_samples": samples, "seed": seed,
                     "forward_cone_deg": "auto"},
    }


def band_targets(problem: int, omega0: float, refs: dict, fraction: float = 1 / 3) -> dict:
    """Radiometer name -> target relative error: ``fraction`` of its pass band (2 CV + 0.005)."""
    return {f"{q}_tau{tau:g}": fraction * (2 * refs[(problem, omega0, tau, q)][1] + 0.005)
            for tau in TAUS for q in QUANTITIES}


def run_problem(scene: Scene, problem: int, omega0: float, refs: dict, samples: int | None = None,
                threads: int | None = None, forward_cone_deg=None, adaptive: bool = True) -> list[dict]:
    """Render one configuration; one record per reference value. ``adaptive``: each radiometer
    stops at a third of its pass band (``band_targets``); else all take ``samples``."""
    if forward_cone_deg is not None:
        scene.settings.forward_cone_deg = forward_cone_deg
    t0 = time.perf_counter()
    res = render(scene, radiometer_samples=samples, threads=threads,
                 radiometer_targets=band_targets(problem, omega0, refs) if adaptive else None)
    seconds = time.perf_counter() - t0
    records = []
    for tau in TAUS:
        for q in QUANTITIES:
            r = res.radiometer(f"{q}_tau{tau:g}")
            ref, cv = refs[(problem, omega0, tau, q)]
            value, se = float(r.mean[0, 0]), float(r.stderr[0, 0])
            passed = abs(value - ref) <= (2 * cv + 0.005) * ref + 3 * se
            records.append({"problem": problem, "omega0": omega0, "tau": tau, "quantity": q,
                            "value": value, "stderr": se, "reference": ref, "cv": cv,
                            "seconds": seconds, "passed": bool(passed), "samples": r.samples,
                            "target_error": r.target_error,
                            "integrator": res.stats["integrator"],
                            "forward_cone_deg": res.stats["forward_cone_deg"]})
    return records


def format_records(records: list[dict]) -> str:
    lines = [f"{'problem':>7} {'omega0':>6} {'tau':>4} {'qty':<4} {'ours +- stderr':<26} "
             f"{'reference':>10} {'CV':>6} {'dev':>8} {'samples':>8} {'time':>7}  result"]
    for r in records:
        dev = 100 * (r["value"] - r["reference"]) / r["reference"]
        lines.append(f"{r['problem']:>7} {r['omega0']:>6g} {r['tau']:>4g} {r['quantity']:<4} "
                     f"{r['value']:.5g} +- {r['stderr']:.2g}".ljust(26 + 25) +
                     f"{r['reference']:>10.4g} {r['cv']:>6.3f} {dev:>+7.2f}% "
                     f"{r.get('samples', 0):>8} {r['seconds']:>6.1f}s  "
                     f"{'pass' if r['passed'] else 'FAIL'}")
    n_ok = sum(r["passed"] for r in records)
    lines.append(f"{n_ok}/{len(records)} values pass |ours - ref| <= (2 CV + 0.005) ref + 3 SE")
    return "\n".join(lines)
