"""Line plots of the benchmarks and checks, drawn by matplotlib (Agg, no pyplot state).

Panels are dicts (see :func:`loglog_panels` and :func:`linear_panels`) placed side by side in
one figure, ``size`` pixels each (at 100 dpi); :func:`save_figure` writes it as a PNG.
matplotlib is imported when a figure is made, so importing photic does not need it.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

DPI = 100
GRID = (200, 200, 200)


def colour(c):
    """A matplotlib colour from an (r, g, b) of 0..255 integers; other colours pass through."""
    if isinstance(c, (tuple, list)) and len(c) in (3, 4) and any(v > 1 for v in c):
        return tuple(v / 255.0 for v in c)
    return c


def _figure(n: int, size):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pw, ph = size
    fig = Figure(figsize=(pw * n / DPI, ph / DPI), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(1, n, squeeze=False)[0]


def _decorate(ax, p: dict) -> None:
    ax.set_title(p.get("title", ""), fontsize=9)
    ax.set_xlabel(p.get("xlabel", ""), fontsize=9)
    ax.set_ylabel(p.get("ylabel", ""), fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, which="major", color=colour(GRID), linewidth=0.8)
    ax.set_axisbelow(True)
    if p.get("legend", False) and p["series"]:
        ax.legend(loc="best", fontsize=8, labelcolor="linecolor", framealpha=0.85)


def decade_label(e: int, percent: bool) -> str:
    """The label of 10**e: "0.01", "1", "100" or as a percentage "1%", "10%"."""
    v = 10.0 ** e * (100.0 if percent else 1.0)
    s = f"{v:.0f}" if v >= 1 else f"{v:.{-int(math.floor(math.log10(v)))}f}"
    return s + ("%" if percent else "")


def loglog_panels(panels: list[dict], size=(480, 380)):
    """Log-log line plots side by side, as a matplotlib ``Figure``.

    Each panel is ``{"title", "xlabel", "ylabel", "series": [(label, xs, ys, colour)],
    "hlines": [(y, colour, label)], "percent": bool (y ticks as percentages), "legend":
    bool}``; colours are (r, g, b) in 0..255 or matplotlib colours. Axes span whole decades
    around the data (y from 1e-4 to 1e2 at most; values outside are drawn on the edge);
    ticks at decades (labelled) and their multiples 2..9. Points with x or y <= 0 are left
    out. Dashed horizontal lines are labelled at the right, the highest above itself and the
    others below (above where the axis ends under them); the legend goes where it hides the
    fewest points (matplotlib's "best").
    """
    from matplotlib.ticker import FixedFormatter, FixedLocator

    fig, axes = _figure(len(panels), size)
    for ax, p in zip(axes, panels):
        hlines = list(p.get("hlines", []))
        xs_all = np.concatenate([np.asarray(s[1], float) for s in p["series"]] or [np.ones(1)])
        ys_all = np.concatenate([np.asarray(s[2], float) for s in p["series"]]
                                + [np.array([h[0] for h in hlines], float)])
        xs_all, ys_all = xs_all[xs_all > 0], ys_all[ys_all > 0]
        ex0 = int(np.floor(np.log10(xs_all.min()))) if xs_all.size else 0
        ex1 = max(int(np.ceil(np.log10(xs_all.max()))) if xs_all.size else 1, ex0 + 1)
        ey0 = max(int(np.floor(np.log10(ys_all.min()))) if ys_all.size else -2, -4)
        ey1 = max(min(int(np.ceil(np.log10(ys_all.max()))) if ys_all.size else 0, 2), ey0 + 1)
        ylo, yhi = 10.0 ** ey0, 10.0 ** ey1
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(10.0 ** ex0, 10.0 ** ex1)
        ax.set_ylim(ylo, yhi)
        for axis, e0, e1, percent in ((ax.xaxis, ex0, ex1, False),
                                      (ax.yaxis, ey0, ey1, p.get("percent", False))):
            decades = range(e0, e1 + 1)
            axis.set_major_locator(FixedLocator([10.0 ** e for e in decades]))
            axis.set_major_formatter(FixedFormatter([decade_label(e, percent) for e in decades]))
            axis.set_minor_locator(FixedLocator([m * 10.0 ** e for e in range(e0, e1) for m in range(2, 10)]))
        for k, (yv, c, label) in enumerate(sorted(hlines, key=lambda h: -h[0])):
            y = float(np.clip(yv, ylo, yhi))
            ax.axhline(y, color=colour(c), linestyle=(0, (4, 4)), linewidth=1.0, zorder=1.5)
            if label:
                above = k == 0 or (math.log10(y) - ey0) / (ey1 - ey0) < 0.08  # room below?
                ax.annotate(label, xy=(1.0, y), xycoords=("axes fraction", "data"),
                            xytext=(-4, 3 if above else -3), textcoords="offset points",
                            ha="right", va="bottom" if above else "top", fontsize=8, color=colour(c))
        for label, xs, ys, c in p["series"]:
            pts = [(x, float(np.clip(y, ylo, yhi))) for x, y in zip(xs, ys) if x > 0 and y > 0]
            px, py = (list(v) for v in zip(*pts)) if pts else ([], [])
            ax.plot(px, py, color=colour(c), linewidth=1.5, marker="o", markersize=4, label=label)
        _decorate(ax, p)
    return fig


def linear_panels(panels: list[dict], size=(480, 380)):
    """Line plots on linear axes side by side, as a matplotlib ``Figure``.

    Each panel is ``{"title", "xlabel", "ylabel", "series": [(label, xs, ys, colour)], "xlim",
    "ylim", "xticks", "yticks", "legend": bool}``; limits default to the data's range and
    ticks to five intervals (labelled with ``:g``); values outside ``ylim`` are drawn on its
    edge and non-finite points are left out. The legend goes where it hides the fewest points
    (matplotlib's "best").
    """
    fig, axes = _figure(len(panels), size)
    for ax, p in zip(axes, panels):
        xs_all = np.concatenate([np.asarray(s[1], float) for s in p["series"]])
        ys_all = np.concatenate([np.asarray(s[2], float) for s in p["series"]])
        x0, x1 = p.get("xlim", (float(xs_all.min()), float(xs_all.max())))
        y0, y1 = p.get("ylim", (float(ys_all.min()), float(ys_all.max())))
        if x1 <= x0:
            x1 = x0 + 1.0
        if y1 <= y0:
            y1 = y0 + 1.0
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        for set_ticks, ticks in ((ax.set_xticks, p.get("xticks", np.linspace(x0, x1, 6))),
                                 (ax.set_yticks, p.get("yticks", np.linspace(y0, y1, 6)))):
            set_ticks(list(ticks), labels=[f"{v:g}" for v in ticks])
        for label, xs, ys, c in p["series"]:
            xs, ys = np.asarray(xs, float), np.asarray(ys, float)
            ok = np.isfinite(xs) & np.isfinite(ys)
            ax.plot(xs[ok], np.clip(ys[ok], y0, y1), color=colour(c), linewidth=1.5, label=label)
        _decorate(ax, p)
    return fig


def save_figure(fig, path: str | Path) -> Path:
    """Write ``fig`` as a PNG of its own pixel size (``size`` per panel); parent folders are created."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI, format="png", facecolor="white")
    return path
