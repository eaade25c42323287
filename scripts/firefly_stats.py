"""Where an image's noise sits: per band of a Photic EXR (as `photic blend` writes it), the image's
RMS standard error over its mean, the share of the image's variance held by its noisiest 0.1 %,
1 % and 10 % of pixels (fireflies hold most of it when these are high), and the median pixel's
relative standard error. From the Noisy Image and Photic Variance passes (the variance of each
pixel's mean), so it measures the light transport, not the denoiser.

    .venv/bin/python scripts/firefly_stats.py out/underwater_objects_0001.exr [more.exr ...]
"""
import sys

import numpy as np
import OpenEXR


def passes(path: str) -> tuple[np.ndarray, np.ndarray]:
    channels = OpenEXR.File(path).parts[0].channels
    pick = {k.split(".", 1)[-1]: v.pixels for k, v in channels.items()}
    # (the image before the denoiser; without Denoise on, Combined is that image)
    image = pick["Noisy Image"] if "Noisy Image" in pick else pick["Combined"]
    return (np.asarray(image, float)[..., :3], np.asarray(pick["Photic Variance"], float)[..., :3])


def band_stats(mean: np.ndarray, var: np.ndarray) -> dict:
    m = float(mean.mean())
    v = np.sort(var.ravel())[::-1]
    total = float(v.sum())
    share = {q: float(v[:max(1, int(round(q * v.size)))].sum() / total) if total > 0 else 0.0
             for q in (0.001, 0.01, 0.1)}
    lit = mean > 0.05 * m  # (relative errors of nearly black pixels say little)
    rel = np.sqrt(np.maximum(var[lit], 0.0)) / mean[lit]
    return {"image_rel_se": float(np.sqrt(var.mean()) / m) if m > 0 else float("nan"),
            "share": share, "median_rel_se": float(np.median(rel)) if rel.size else float("nan")}


def main(paths: list[str]) -> None:
    print("| file | band | image RMS SE / mean | variance in top 0.1 / 1 / 10 % of pixels | median pixel relative SE |")
    print("| --- | --- | --- | --- | --- |")
    for path in paths:
        mean, var = passes(path)
        for c, name in enumerate("RGB"):
            s = band_stats(mean[..., c], var[..., c])
            sh = s["share"]
            print(f"| {path} | {name} | {100 * s['image_rel_se']:.1f} % | {100 * sh[0.001]:.0f} / "
                  f"{100 * sh[0.01]:.0f} / {100 * sh[0.1]:.0f} % | {100 * s['median_rel_se']:.1f} % |")


if __name__ == "__main__":
    main(sys.argv[1:])
