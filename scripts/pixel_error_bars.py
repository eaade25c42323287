"""Are pixels' error bars honest over a whole image? The spread of several seeds' pixel means
against the mean of their reported variances, summed over the image (1 is honest), and per
pixel the share above the chi-square 99 % point (1 % for normal samples; heavy tails and a
variance that is too low raise it).

    .venv/bin/python scripts/pixel_error_bars.py                   # every case below
    .venv/bin/python scripts/pixel_error_bars.py --cases main,rough

Cases: ``main`` (example_blends/underwater_objects.blend, through bpy), ``pool``
(examples/stepped_pool.json), both 120 pixels across, 12 seeds at 8 spp; ``waves-blur``,
``waves-noblur`` (sun_disk_blur off: beams per pass), ``rough`` (a rough flat sea, wind 8 m/s)
and ``wide-sun`` (a 10 deg sun) from scripts/se_calibration.py's camera scene (sun 30 deg, cone
3 deg, 48 x 32), 16 seeds at 16 spp.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from photic.render import render
from photic.scene import Scene

ROOT = Path(__file__).resolve().parents[1]
CASES = ("main", "pool", "waves-blur", "waves-noblur", "rough", "wide-sun")


def case_scene(name: str):
    """(scene dict maker by seed, base_dir, samples per pixel, seeds)."""
    if name in ("main", "pool"):
        from photic.bench_examples import example_scenes
        want = "underwater_objects.blend" if name == "main" else "stepped_pool.json"
        ex = next(e for e in example_scenes(120, blends=name == "main") if e.name == want)
        d = ex.scene.to_dict()
        return (lambda seed: d), ROOT / Path(ex.source).parent, 8, 12
    sys.path.insert(0, str(ROOT / "scripts"))
    from se_calibration import scene
    surface = "flat" if name == "rough" else "waves"
    d = scene(surface, 30.0, 3.0, 1, True).to_dict()
    d["cameras"][0]["resolution"] = [48, 32]
    if name == "waves-noblur":
        d["settings"]["sun_disk_blur"] = False
    if name == "rough":
        d["water"][0]["surface"] = {"kind": "flat", "z": 0.0, "roughness": {"wind_speed": 8.0}}
    if name == "wide-sun":
        d["sun"]["angular_diameter_deg"] = 10.0
    return (lambda seed: d), None, 16, 16


def measure(name: str, threads: int = 2) -> dict:
    make, base, spp, nseeds = case_scene(name)
    xs, vs = [], []
    for s in range(nseeds):
        res = render(Scene.from_dict(make(s), base_dir=base), samples=spp, seed=900 + s, threads=threads)
        img = next(iter(res.images.values()))
        xs.append(img.mean)
        vs.append(img.variance)
    xs, vs = np.array(xs), np.array(vs)
    spread, rep = xs.var(0, ddof=1), vs.mean(0)
    ok = rep > 0
    hi = stats.chi2.ppf(0.99, nseeds - 1) / (nseeds - 1)
    return {"case": name, "spp": spp, "seeds": nseeds, "image_ratio": float(spread.mean() / rep.mean()),
            "median_pixel": float(np.median(spread[ok] / rep[ok])),
            "chi2_median": float(stats.chi2.ppf(0.5, nseeds - 1) / (nseeds - 1)),
            "above_99": float(np.mean(spread[ok] / rep[ok] > hi))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    print("case           spp seeds  image variance ratio  per-pixel median (chi2 median)  above 99 % point")
    for name in args.cases.split(","):
        r = measure(name, args.threads)
        print(f"{name:<14} {r['spp']:>3} {r['seeds']:>5}  {r['image_ratio']:>20.3f}  "
              f"{r['median_pixel']:>16.3f} ({r['chi2_median']:.3f})  {100 * r['above_99']:>14.2f} %", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
