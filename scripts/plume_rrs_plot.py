"""Figures of the sediment-plume example from a render of it: the tone-mapped image and the
Rrs spectra above the plume and above clear water, with their standard errors.

    .venv/bin/photic blend example_blends/sediment_plume.blend --out out/plume
    .venv/bin/python scripts/plume_rrs_plot.py out/plume          # -> docs/images/

Reads ``sediment_plume_0001.exr`` (the Combined pass: display RGB, linear) and
``sediment_plume_0001_radiometers.json`` from the folder; Rrs is computed as
``example_blends/make_examples.py`` defines it (``plume_rrs``: Lw = Lu - rho Lsky, Rrs = Lw / Ed,
photic.derived). Prints the Rrs table. Needs matplotlib (requirements.txt).
"""
from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def load_examples():
    spec = importlib.util.spec_from_file_location("make_examples",
                                                  REPO / "example_blends" / "make_examples.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def tone_mapped(exr: Path, percentile: float = 99.5) -> np.ndarray:
    """The Combined pass as 8-bit sRGB: exposure puts the ``percentile`` of the luminance at
    white (the beach and the brightest plume water may clip a little)."""
    import OpenEXR
    from photic.images import srgb_encode
    with OpenEXR.File(str(exr), separate_channels=True) as f:
        channels = {name: ch.pixels for part in f.parts for name, ch in part.channels.items()}
    rgb = np.stack([channels[f"ViewLayer.Combined.{c}"] for c in "RGB"], axis=-1).astype(float)
    luminance = rgb @ np.array([0.2126, 0.7152, 0.0722])
    return srgb_encode(rgb / np.percentile(luminance, percentile))


def plot_rrs(rrs: dict, bands, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    centres = np.array([c for _, c in bands])
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=110)
    style = {"plume": ("#9a6a2f", "above the sediment plume"),
             "clear": ("#1f5fa8", "above clear water")}
    for name, d in rrs.items():
        colour, label = style[name]
        ax.errorbar(centres, d.value, yerr=d.stderr, color=colour, marker="o", ms=4, capsize=3,
                    lw=1.5, label=label)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("remote-sensing reflectance Rrs (sr$^{-1}$)")
    ax.set_title("Sediment plume example: Rrs = (Lu - ρ Lsky) / Ed, 1 m above the sea")
    ax.title.set_fontsize(10)
    ax.legend(frameon=False)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("render", type=Path, help="folder of the render (photic blend --out)")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "images",
                        help="where to write the PNGs (default: docs/images)")
    args = parser.parse_args(argv)
    from photic.derived import load_table
    from photic.images import write_png
    examples = load_examples()
    table = load_table(args.render / "sediment_plume_0001_radiometers.json")
    rrs = examples.plume_rrs(table)
    print(f"Rrs (sr^-1) +- standard error, rho = {examples.PLUME_RHO:.5f}")
    print(f"{'band':>6} " + " ".join(f"{name:>20}" for name in rrs))
    for k, (name, _) in enumerate(table.bands):
        print(f"{name:>6} " + " ".join(f"{d.value[k]:11.5f} +- {d.stderr[k]:.5f}"
                                       for d in rrs.values()))
    plot_rrs(rrs, table.bands, args.out / "sediment_plume_rrs.png")
    write_png(args.out / "sediment_plume.png",
              tone_mapped(args.render / "sediment_plume_0001.exr"))
    print(f"wrote {args.out / 'sediment_plume.png'} and {args.out / 'sediment_plume_rrs.png'}")


if __name__ == "__main__":
    main()
