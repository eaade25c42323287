"""Are the standard errors Photic prints honest? Spread of means over seeds / reported SE.

For each setting (sea surface, sun zenith, forward cone, sample count) the same scene is
rendered with several seeds; the ratio

    spread of the seeds' means (sample standard deviation) / median of the reported SEs

is about 1 for an honest standard error (0.7-1.5 is the target; with 16 seeds the spread
itself is uncertain by about +-18 %). Radiometers: Ed and Eo at 1 m and 5 m below the real
0.53 deg sun. Image pixels (--camera): a camera at 1 m looking down at the floor 5 m deep, the
ratio per pixel, summarised by its median over the pixels. Estimates that Photic flags as
unreliable (too few passes, heavy tails) are counted in the 'flagged' column.

    .venv/bin/python scripts/se_calibration.py                       # a quick grid (~10 min)
    .venv/bin/python scripts/se_calibration.py --full --json se.json # 1024 ... 1M samples
    .venv/bin/python scripts/se_calibration.py --markdown se.json    # the table of docs/verification.md
    .venv/bin/python scripts/se_calibration.py --surfaces bottom --zeniths 60 --cones 0 --samples 1048576
                                                     # problem 2's water over a bottom (bottom_scene)
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from photic.render import render
from photic.scene import Scene

WAVES = {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0, "fetch_m": 50000.0,
         "patch_size_m": [20.0, 20.0], "resolution": [64, 64], "seed": 0}
DEPTHS = (1.0, 5.0)


def bottom_scene(seed: int, zenith: float = 60.0, cone="auto") -> Scene:
    """Problem 2 of Mobley et al. (1993) (c = 1 m^-1, single-scattering albedo 0.9, Petzold,
    black sky, flat surface, the sun at 60 deg) over a Lambertian bottom of reflectance 0.5 at
    5 m (optical depth 5), as problem 6 puts a bottom under it: Ed, Eou and Lu (the mu >= 0.9
    cap) at 1, 3 and 4.5 m. The automatic forward cone is 0 here (the exact mode)."""
    rads = []
    for z in (1.0, 3.0, 4.5):
        rads += [{"name": f"Ed_{z:g}", "quantity": "Ed", "position": [0.0, 0.0, -z]},
                 {"name": f"Eou_{z:g}", "quantity": "Eou", "position": [0.0, 0.0, -z]},
                 {"name": f"Lu_{z:g}", "quantity": "radiance", "position": [0.0, 0.0, -z],
                  "direction": [0.0, 0.0, -1.0], "half_angle_deg": float(np.degrees(np.arccos(0.9)))}]
    return Scene.from_dict({
        "photic_scene": 1, "name": "bottom",
        "materials": {"bottom": {"type": "lambertian", "reflectance": [0.5]}},
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": {"kind": "flat", "z": 0.0},
                   "iops": {"absorption": [0.1], "b": [0.9], "phase": {"type": "petzold"}},
                   "bottom": {"depth": 5.0, "material": "bottom"}}],
        "sun": {"zenith_deg": zenith, "azimuth_deg": 0.0, "irradiance": [1.0]},
        "sky": {"type": "black"}, "radiometers": rads,
        "settings": {"integrator": "hybrid", "seed": seed, "forward_cone_deg": cone}})


def scene(surface: str, zenith: float, cone: float, seed: int, camera: bool) -> Scene:
    if surface == "bottom":  # (radiometers only)
        return bottom_scene(seed, zenith, cone)
    rads = [{"name": f"{q}_{z:g}", "quantity": q, "position": [0.3, 0.7, -z]}
            for z in DEPTHS for q in ("Ed", "Eo")]
    cams = [{"name": "floor", "type": "perspective", "position": [0.3, 0.7, -1.0],
             "direction": [0, 0, -1], "up": [0, 1, 0], "fov_deg": 60, "resolution": [24, 16]}]
    d = {"photic_scene": 1, "name": "se_calibration",
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]}},
         "water": [{"name": "sea", "type": "ocean",
                    "surface": {"kind": "flat", "z": 0.0} if surface == "flat" else WAVES,
                    "bottom": {"depth": 6.0, "material": "sand"},
                    "iops": {"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": zenith, "azimuth_deg": 30.0, "irradiance": [1.0],
                 "angular_diameter_deg": 0.53},
         "sky": {"type": "black"},
         "radiometers": [] if camera else rads,
         "cameras": cams if camera else [],
         "settings": {"integrator": "hybrid", "seed": seed, "forward_cone_deg": cone}}
    return Scene.from_dict(d)


def flagged(r) -> bool:
    """Whether Photic marked this estimate's standard error as unreliable for a reason of the
    sampling (not the wave mesh's error alone: photic.render.sampling_untrusted)."""
    from photic.render import sampling_untrusted
    return sampling_untrusted(r)


def radiometer_rows(surface, zenith, cone, n, seeds, threads):
    means, ses, flags = {}, {}, {}
    for s in seeds:
        res = render(scene(surface, zenith, cone, s, False), radiometer_samples=n, threads=threads)
        for r in res.radiometers:
            means.setdefault(r.name, []).append(r.mean[0, 0])
            ses.setdefault(r.name, []).append(r.stderr[0, 0])
            flags.setdefault(r.name, []).append(flagged(r))
    rows = []
    for name in means:
        m, e = np.array(means[name]), np.array(ses[name])
        rows.append({"surface": surface, "zenith": zenith, "cone": cone, "samples": n, "quantity": name,
                     "mean": float(m.mean()), "spread": float(m.std(ddof=1)), "median_se": float(np.median(e)),
                     "ratio": float(m.std(ddof=1) / np.median(e)) if np.median(e) > 0 else float("inf"),
                     "flagged": int(sum(flags[name]))})
    return rows


def camera_rows(surface, zenith, cone, spp, seeds, threads):
    imgs, vars_ = [], []
    for s in seeds:
        res = render(scene(surface, zenith, cone, s, True), samples=spp, threads=threads)
        img = res.images["floor"]
        imgs.append(img.mean[..., 0])
        vars_.append(img.variance[..., 0])
    imgs, vars_ = np.array(imgs), np.array(vars_)
    spread = imgs.std(axis=0, ddof=1)
    se = np.median(np.sqrt(vars_), axis=0)
    ok = (spread > 0) & np.isfinite(se) & (se > 0)
    ratio = spread[ok] / se[ok]
    unknown = int(np.sum(~np.isfinite(vars_)))
    return [{"surface": surface, "zenith": zenith, "cone": cone, "samples": spp, "quantity": "pixels",
             "mean": float(imgs.mean()), "spread": float(np.median(spread)), "median_se": float(np.median(se)),
             "ratio": float(np.median(ratio)) if ratio.size else float("nan"),
             "ratio_p10": float(np.percentile(ratio, 10)) if ratio.size else float("nan"),
             "ratio_p90": float(np.percentile(ratio, 90)) if ratio.size else float("nan"),
             "flagged": unknown}]


def markdown(rows: list[dict]) -> str:
    """The rows as a table: one line per setting and quantity, one column per sample count
    (the ratio, and in brackets how many seeds' errors Photic flagged, when any)."""
    table: dict = {}
    columns: list = []
    for r in rows:
        pixels = r["quantity"] == "pixels"
        col = (pixels, r["samples"])
        if col not in columns:
            columns.append(col)
        key = (r["surface"], r["zenith"], r["cone"], "pixels (median)" if pixels else r["quantity"])
        table.setdefault(key, {})[col] = f"{r['ratio']:.2f}" + (f" ({r['flagged']})" if r["flagged"] else "")
    columns.sort()
    head = [f"{n} spp" if pixels else f"{n:,}" for pixels, n in columns]
    lines = ["| sea | sun zenith | cone | quantity | " + " | ".join(head) + " |",
             "| --- | --- | --- | --- | " + " | ".join("---" for _ in head) + " |"]
    for (surface, zenith, cone, quantity), cells in table.items():
        lines.append(f"| {surface} | {zenith:g} | {cone:g} | {quantity} | " +
                     " | ".join(cells.get(c, "") for c in columns) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=16)
    ap.add_argument("--surfaces", default="flat,waves", help="flat, waves, bottom (bottom_scene)")
    ap.add_argument("--zeniths", default="0,30,80")
    ap.add_argument("--cones", default="0,3")
    ap.add_argument("--samples", default="1024,8192,65536")
    ap.add_argument("--spp", default="4,16,64")
    ap.add_argument("--camera", action="store_true", help="image pixels too")
    ap.add_argument("--full", action="store_true",
                    help="zeniths 0,30,60,80,85 and 1024 ... 1M samples")
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--json", help="write the rows here")
    ap.add_argument("--markdown", nargs="+", metavar="JSON",
                    help="only print the rows of these --json files as a Markdown table")
    a = ap.parse_args(argv)
    if a.markdown:
        rows = [r for f in a.markdown for r in json.load(open(f))["rows"]]
        print(markdown(rows))
        return 0
    if a.full:
        a.zeniths, a.samples = "0,30,60,80,85", "1024,4096,16384,65536,262144,1048576"
    seeds = list(range(1, a.seeds + 1))
    rows = []
    print(f"{'surface':7} {'zen':>4} {'cone':>4} {'samples':>8} {'quantity':8} {'mean':>10} {'spread':>10} "
          f"{'median SE':>10} {'ratio':>6} {'flagged':>7}", flush=True)
    t0 = time.time()
    for surface in a.surfaces.split(","):
        for zenith in map(float, a.zeniths.split(",")):
            for cone in map(float, a.cones.split(",")):
                batches = [radiometer_rows(surface, zenith, cone, n, seeds, a.threads)
                           for n in map(int, a.samples.split(","))]
                if a.camera:
                    batches += [camera_rows(surface, zenith, cone, n, seeds, a.threads)
                                for n in map(int, a.spp.split(","))]
                for batch in batches:
                    for r in batch:
                        rows.append(r)
                        print(f"{r['surface']:7} {r['zenith']:4g} {r['cone']:4g} {r['samples']:8d} {r['quantity']:8} "
                              f"{r['mean']:10.4g} {r['spread']:10.3g} {r['median_se']:10.3g} {r['ratio']:6.2f} "
                              f"{r['flagged']:7d}", flush=True)
    ratios = np.array([r["ratio"] for r in rows if np.isfinite(r["ratio"]) and not r["flagged"]])
    print(f"\n{len(rows)} rows in {time.time() - t0:.0f} s; unflagged ratios: "
          f"{np.sum((ratios >= 0.7) & (ratios <= 1.5))}/{ratios.size} within 0.7-1.5, "
          f"range {ratios.min():.2f}-{ratios.max():.2f}" if ratios.size else "")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"seeds": a.seeds, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
