"""What Raman scattering (settings.raman "auto", the default) costs on every example scene with
a camera: CPU time per render with and without it (median of --repeats paired renders, the
two alternating) and the Raman pass's share of the image's mean per band (docs/verification.md,
"Raman scattering").

    .venv/bin/python scripts/raman_cost.py [--width 240] [--spp 16] [--repeats 3]
"""
from __future__ import annotations

import argparse
import copy
import statistics
import time

import numpy as np

from photic.bench_examples import example_scenes
from photic.inelastic import raman_active
from photic.render import render


def _cpu(scene, spp: int, seed: int):
    c0 = time.process_time()
    res = render(scene, samples=spp, seed=seed, threads=2)
    return time.process_time() - c0, next(iter(res.images.values()))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--width", type=int, default=240)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    print(f"{'example':<28} {'raman':>6} {'CPU on (s)':>10} {'CPU off (s)':>11} {'ratio':>6} "
          f"{'Raman share of the mean, per band':>34}")
    for ex in example_scenes(args.width):
        on = ex.scene
        off = copy.deepcopy(on)
        off.settings.raman = False
        if not raman_active(on):
            print(f"{ex.name:<28} {'off':>6} (its bands receive no Raman light)")
            continue
        t_on, t_off = [], []
        for r in range(args.repeats):
            t, img = _cpu(on, args.spp, r + 1)
            t_on.append(t)
            t_off.append(_cpu(off, args.spp, r + 1)[0])
        raman = img.components["raman"]
        share = raman.mean(axis=(0, 1)) / np.maximum(img.mean.mean(axis=(0, 1)), 1e-300)
        ratio = statistics.median(t_on) / statistics.median(t_off)
        print(f"{ex.name:<28} {'on':>6} {statistics.median(t_on):>10.2f} {statistics.median(t_off):>11.2f} "
              f"{ratio:>5.2f}x {' / '.join(f'{100 * s:.2f}%' for s in share):>34}")


if __name__ == "__main__":
    main()
