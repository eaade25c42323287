"""Denoising against error at equal time: the stepped pool's underwater view (caustics on the
steps and floor), hybrid, rendered at doubling sample counts, each image as it is and
denoised by OpenImageDenoise with its guides, against a converged reference.

    .venv/bin/python scripts/denoise_bench.py                 # 128 x 128, reference 512 spp
    .venv/bin/python scripts/denoise_bench.py --size 256 256 --ref 1024 --json out.json

Errors as `photic bench --error` measures them: RMS(x - ref) / mean(ref) over pixels and bands,
the reference's own noise removed. Times are wall seconds on the threads given (the
denoised image's include its guides and the denoiser). "Equal time" is the noisy image's
error at the denoised image's time, interpolated on the noisy curve (error ~ t^-1/2).

Caustics: the pixels where the reference's surface beams (the refracted sun on the steps and
floor) make at least half the light and vary most between neighbours (the top quarter of
their detail over the local mean: the caustic lines). There the denoiser's bias shows: the caustic contrast
is the standard deviation of the image's detail (the image minus its 5 x 5 box mean) over
the reference's, 1 when the caustic network is kept, below 1 when it is smoothed away;
its mean bias is mean(x - ref) / mean(ref) over those pixels.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np


def box5(img: np.ndarray) -> np.ndarray:
    """Each pixel's 5 x 5 box mean (edges replicated)."""
    p = np.pad(img, ((2, 2), (2, 2), (0, 0)), mode="edge")
    c = np.cumsum(np.cumsum(p, 0), 1)
    c = np.pad(c, ((1, 0), (1, 0), (0, 0)))
    h, w = img.shape[:2]
    return (c[5:5 + h, 5:5 + w] - c[:h, 5:5 + w] - c[5:5 + h, :w] + c[:h, :w]) / 25.0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, nargs=2, default=(128, 128))
    p.add_argument("--ref", type=int, default=512, help="reference samples per pixel")
    p.add_argument("--budgets", type=int, nargs="+", default=[2, 4, 8, 16, 32, 64])
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--json", help="write the table as JSON here")
    args = p.parse_args(argv)

    from photic import denoise
    from photic.render import render
    from photic.scenes import stepped_pool

    def scene():
        s = stepped_pool(resolution=tuple(args.size), integrator="hybrid")
        s.cameras = [c for c in s.cameras if c.name == "under"]
        s.validate()
        return s

    t0 = time.perf_counter()
    ref = render(scene(), samples=args.ref, seed=1000, threads=args.threads).images["under"]
    m = float(ref.mean.mean())
    noise2 = float(np.mean(ref.variance))
    print(f"reference: {args.ref} spp in {time.perf_counter() - t0:.0f} s, its own noise (RMS standard "
          f"error over the mean) {100 * math.sqrt(noise2) / m:.2f} %", flush=True)
    # Caustic lines: where the surface beams make most of the light and vary most from pixel to
    # pixel (the top quarter of the reference's relative detail).
    beams = ref.components["beam_surface"].sum(2)
    rel = np.abs(beams - box5(beams[:, :, None])[:, :, 0]) / np.maximum(box5(ref.mean).sum(2), 1e-300)
    caustic = (beams >= 0.5 * ref.mean.sum(2)) & (rel >= np.quantile(rel, 0.75))
    ref_detail = (ref.mean - box5(ref.mean))[caustic]

    def error(x):
        return math.sqrt(max(float(np.mean((x - ref.mean) ** 2)) - noise2, 0.0)) / m

    def caustic_figures(x):
        detail = (x - box5(x))[caustic]
        contrast = float(np.std(detail) / np.std(ref_detail))
        bias = float(np.mean(x[caustic] - ref.mean[caustic]) / np.mean(ref.mean[caustic]))
        return contrast, bias

    rows = []
    for spp in args.budgets:
        t0 = time.perf_counter()
        res = render(scene(), samples=spp, seed=spp, threads=args.threads, guides=True)
        t_render = time.perf_counter() - t0
        img = res.images["under"]
        t1 = time.perf_counter()
        clean = denoise.denoise_bands(img.mean, img.albedo, img.normal)
        t_denoise = time.perf_counter() - t1
        c_noisy, b_noisy = caustic_figures(img.mean)
        c_clean, b_clean = caustic_figures(clean)
        rows.append(dict(spp=spp, time_s=t_render, denoise_s=t_denoise,
                         error_noisy=error(img.mean), error_denoised=error(clean),
                         stderr_noisy=math.sqrt(float(np.mean(img.variance))) / m,
                         caustic_contrast_noisy=c_noisy, caustic_contrast_denoised=c_clean,
                         caustic_bias_noisy=b_noisy, caustic_bias_denoised=b_clean))
        print(f"  {spp:4d} spp: {t_render:6.1f} s, noisy {100 * rows[-1]['error_noisy']:5.1f} %, "
              f"denoised {100 * rows[-1]['error_denoised']:5.1f} % (+{t_denoise:.2f} s)", flush=True)
    # The noisy curve as error = k t^-1/2 fitted in log space, for equal-time comparisons.
    lt = np.log([r["time_s"] for r in rows])
    le = np.log([r["error_noisy"] for r in rows])
    k = float(np.mean(le + 0.5 * lt))
    for r in rows:
        r["error_noisy_at_equal_time"] = math.exp(k - 0.5 * math.log(r["time_s"] + r["denoise_s"]))

    print(f"\nstepped pool, underwater view {args.size[0]}x{args.size[1]}, hybrid, {args.threads} threads; "
          f"reference {args.ref} spp; caustic pixels {100 * caustic.mean():.0f} %")
    print(f"{'spp':>5} {'time s':>7} {'noisy':>7} {'its SE':>7} {'denoised':>9} {'noisy, equal t':>15} "
          f"{'caustic contrast n/d':>21} {'caustic bias n/d':>17}")
    for r in rows:
        print(f"{r['spp']:5d} {r['time_s'] + r['denoise_s']:7.1f} {100 * r['error_noisy']:6.1f}% "
              f"{100 * r['stderr_noisy']:6.1f}% "
              f"{100 * r['error_denoised']:8.1f}% {100 * r['error_noisy_at_equal_time']:14.1f}% "
              f"{r['caustic_contrast_noisy']:10.2f} / {r['caustic_contrast_denoised']:.2f} "
              f"{100 * r['caustic_bias_noisy']:+7.1f}% / {100 * r['caustic_bias_denoised']:+.1f}%")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(size=list(args.size), ref_spp=args.ref, threads=args.threads,
                           reference_noise=math.sqrt(noise2) / m,
                           caustic_fraction=float(caustic.mean()), rows=rows), f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
