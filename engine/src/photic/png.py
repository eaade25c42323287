"""A minimal PNG writer (zlib + struct, no imaging library) and a tone mapper for previews."""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np


def _chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an 8-bit PNG.

    Parameters
    ----------
    path : str or Path
        Output file; parent folders are created.
    image : ndarray
        (H, W) grey or (H, W, 3) RGB, either uint8 or floats in [0, 1] (clipped, rounded).
    """
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(np.round(np.nan_to_num(img.astype(np.float64)) * 255.0), 0, 255).astype(np.uint8)
    if img.ndim == 2:
        color_type, channels = 0, 1
    elif img.ndim == 3 and img.shape[2] == 3:
        color_type, channels = 2, 3
    else:
        raise ValueError(f"image must be (H, W) or (H, W, 3), got shape {img.shape}")
    h, w = img.shape[:2]
    rows = np.ascontiguousarray(img.reshape(h, w * channels))
    raw = b"".join(b"\x00" + rows[y].tobytes() for y in range(h))  # filter type 0 per row
    png = (b"\x89PNG\r\n\x1a\n"
           + _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, color_type, 0, 0, 0))
           + _chunk(b"IDAT", zlib.compress(raw, 9))
           + _chunk(b"IEND", b""))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png)
    return path


def srgb_encode(linear: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] to sRGB-encoded values in [0, 1]."""
    x = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)


def tonemap(radiance: np.ndarray, percentile: float = 99.0) -> np.ndarray:
    """Radiance (H, W, nbands) to an sRGB image (H, W, 3) in [0, 1].

    The exposure maps the ``percentile`` of the pixel luminance to 1; then the sRGB curve. With
    three bands they are taken as (blue, green, red) in increasing wavelength order, i.e. the
    last band is red; one band gives grey; other counts use the first, middle and last band.
    """
    r = np.nan_to_num(np.asarray(radiance, dtype=np.float64))
    if r.ndim == 2:
        r = r[:, :, None]
    nb = r.shape[2]
    if nb == 1:
        rgb = np.repeat(r, 3, axis=2)
    else:
        rgb = r[:, :, [nb - 1, nb // 2, 0]]
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    scale = float(np.percentile(lum, percentile)) if lum.size else 0.0
    if not scale > 0:
        scale = float(lum.max()) if lum.size and lum.max() > 0 else 1.0
    return srgb_encode(rgb / scale)


def write_preview(path: str | Path, radiance: np.ndarray, percentile: float = 99.0) -> Path:
    """Tone-map ``radiance`` (H, W, nbands) with :func:`tonemap` and write it as a PNG."""
    return write_png(path, tonemap(radiance, percentile))


# ----------------------------------------------------------------------------------------
# A tiny raster plotter (no matplotlib): log-log line plots with a 3 x 5 pixel font.
# ----------------------------------------------------------------------------------------

_GLYPHS = {
    "0": "111101101101111", "1": "010110010010111", "2": "111001111100111", "3": "111001111001111",
    "4": "101101111001001", "5": "111100111001111", "6": "111100111101111", "7": "111001001010010",
    "8": "111101111101111", "9": "111101111001111", "A": "010101111101101", "B": "110101110101110",
    "C": "011100100100011", "D": "110101101101110", "E": "111100110100111", "F": "111100110100100",
    "G": "011100101101011", "H": "101101111101101", "I": "111010010010111", "J": "001001001101010",
    "K": "101101110101101", "L": "100100100100111", "M": "101111111101101", "N": "110101101101101",
    "O": "010101101101010", "P": "110101110100100", "Q": "010101101110011", "R": "110101110101101",
    "S": "011100010001110", "T": "111010010010010", "U": "101101101101111", "V": "101101101101010",
    "W": "101101111111101", "X": "101101010101101", "Y": "101101010010010", "Z": "111001010100111",
    " ": "000000000000000", ".": "000000000000010", ",": "000000000010100", "%": "101001010100101",
    "-": "000000111000000", "+": "000010111010000", "(": "001010010010001", ")": "100010010010100",
    ":": "000010000010000", "/": "001001010100100", "=": "000111000111000", "_": "000000000000111",
    "<": "001010100010001", ">": "100010001010100", "*": "000101010101000",
}


def draw_text(img: np.ndarray, x: int, y: int, text: str, color, scale: int = 2,
              anchor: str = "left") -> None:
    """Draw ``text`` (upper-cased; 3 x 5 glyphs scaled by ``scale``) with its top at row ``y``;
    ``anchor`` "left", "center" or "right" places it around column ``x``."""
    text = text.upper()
    adv = 4 * scale
    width = len(text) * adv - scale
    if anchor == "center":
        x -= width // 2
    elif anchor == "right":
        x -= width
    h, w = img.shape[:2]
    for k, ch in enumerate(text):
        bits = _GLYPHS.get(ch, _GLYPHS["*"])
        for r in range(5):
            for c in range(3):
                if bits[3 * r + c] == "1":
                    x0, y0 = x + k * adv + c * scale, y + r * scale
                    if 0 <= x0 and x0 + scale <= w and 0 <= y0 and y0 + scale <= h:
                        img[y0:y0 + scale, x0:x0 + scale] = color


def draw_line(img: np.ndarray, x0, y0, x1, y1, color, width: int = 1, dash: int = 0) -> None:
    """A straight line of ``width`` pixels; ``dash`` > 0 draws dashes of that length."""
    n = int(max(abs(x1 - x0), abs(y1 - y0)) * 2) + 1
    t = np.linspace(0.0, 1.0, n)
    xs, ys = x0 + (x1 - x0) * t, y0 + (y1 - y0) * t
    if dash > 0:
        along = t * np.hypot(x1 - x0, y1 - y0)
        keep = (along // dash) % 2 == 0
        xs, ys = xs[keep], ys[keep]
    h, w = img.shape[:2]
    r0 = -(width // 2)
    for dx in range(r0, r0 + width):
        for dy in range(r0, r0 + width):
            xi, yi = np.round(xs).astype(int) + dx, np.round(ys).astype(int) + dy
            ok = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
            img[yi[ok], xi[ok]] = color


def _decade_label(e: int, percent: bool) -> str:
    v = 10.0 ** e * (100.0 if percent else 1.0)
    s = f"{v:.0f}" if v >= 1 else f"{v:.{-int(np.floor(np.log10(v)))}f}"
    return s + ("%" if percent else "")


def loglog_panels(panels: list[dict], size=(480, 380)) -> np.ndarray:
    """Log-log line plots side by side, as an (H, W, 3) uint8 image.

    Each panel is ``{"title", "xlabel", "ylabel", "series": [(label, xs, ys, rgb)], "hlines":
    [(y, rgb, label)], "percent": bool (y ticks as percentages), "legend": bool}``. Axes span
    whole decades around the data; ticks at decades (labelled) and their multiples 2..9.
    """
    pw, ph = size
    img = np.full((ph, pw * len(panels), 3), 255, np.uint8)
    black, grey = (0, 0, 0), (200, 200, 200)
    for k, p in enumerate(panels):
        ox = k * pw
        left, right, top, bottom = ox + 70, ox + pw - 15, 34, ph - 46
        xs_all = np.concatenate([np.asarray(s[1], float) for s in p["series"]] or [np.ones(1)])
        ys_all = np.concatenate([np.asarray(s[2], float) for s in p["series"]] +
                                [np.array([h[0] for h in p.get("hlines", [])], float)])
        xs_all, ys_all = xs_all[xs_all > 0], ys_all[ys_all > 0]
        ex0 = int(np.floor(np.log10(xs_all.min()))) if xs_all.size else 0
        ex1 = max(int(np.ceil(np.log10(xs_all.max()))) if xs_all.size else 1, ex0 + 1)
        ey0 = max(int(np.floor(np.log10(ys_all.min()))) if ys_all.size else -2, -4)
        ey1 = max(min(int(np.ceil(np.log10(ys_all.max()))) if ys_all.size else 0, 2), ey0 + 1)

        def X(v):
            return left + (np.log10(v) - ex0) / (ex1 - ex0) * (right - left)

        def Y(v):
            v = np.clip(v, 10.0 ** ey0, 10.0 ** ey1)
            return bottom - (np.log10(v) - ey0) / (ey1 - ey0) * (bottom - top)

        for e in range(ex0, ex1 + 1):                       # x grid and ticks
            for m in range(1, 10):
                v = m * 10.0 ** e
                if e == ex1 and m > 1:
                    break
                x = X(v)
                if m == 1:
                    draw_line(img, x, top, x, bottom, grey)
                    draw_line(img, x, bottom, x, bottom + 6, black)
                    draw_text(img, int(x), bottom + 10, _decade_label(e, False), black, anchor="center")
                else:
                    draw_line(img, x, bottom, x, bottom + 3, black)
        for e in range(ey0, ey1 + 1):                       # y grid and ticks
            for m in range(1, 10):
                v = m * 10.0 ** e
                if e == ey1 and m > 1:
                    break
                y = Y(v)
                if m == 1:
                    draw_line(img, left, y, right, y, grey)
                    draw_line(img, left - 6, y, left, y, black)
                    draw_text(img, left - 9, int(y) - 5, _decade_label(e, p.get("percent", False)),
                              black, anchor="right")
                else:
                    draw_line(img, left - 3, y, left, y, black)
        draw_line(img, left, top, left, bottom, black)
        draw_line(img, left, bottom, right, bottom, black)
        hl = sorted(p.get("hlines", []), key=lambda h: -h[0])
        for k2, (yv, color, label) in enumerate(hl):
            draw_line(img, left, Y(yv), right, Y(yv), color, dash=6)
            if label:  # the highest line labelled above itself, the others below
                draw_text(img, right - 4, int(Y(yv)) + (-13 if k2 == 0 else 4), label, color, anchor="right")
        for label, xs, ys, color in p["series"]:
            pts = [(X(x), Y(y)) for x, y in zip(xs, ys) if x > 0 and y > 0]
            for (a, b), (c, d) in zip(pts, pts[1:]):
                draw_line(img, a, b, c, d, color, width=2)
            for a, b in pts:
                draw_line(img, a - 1, b, a + 1, b, color, width=5)
        draw_text(img, (left + right) // 2, 10, p.get("title", ""), black, anchor="center")
        draw_text(img, (left + right) // 2, ph - 20, p.get("xlabel", ""), black, anchor="center")
        # y label: stacked above the axis (no rotated text)
        draw_text(img, ox + 6, top - 20, p.get("ylabel", ""), black)
        if p.get("legend", False):  # top left
            ly = top + 8
            lx = left + 10
            for label, _, _, color in p["series"]:
                draw_line(img, lx, ly + 5, lx + 20, ly + 5, color, width=3)
                draw_text(img, lx + 26, ly, label, color)
                ly += 16
    return img


def _tick_label(v: float) -> str:
    return f"{v:g}"


def linear_panels(panels: list[dict], size=(480, 380)) -> np.ndarray:
    """Line plots on linear axes side by side, as an (H, W, 3) uint8 image.

    Each panel is ``{"title", "xlabel", "ylabel", "series": [(label, xs, ys, rgb)], "xlim",
    "ylim", "xticks", "yticks", "legend": bool}``; limits default to the data's range and
    ticks to five intervals. The legend sits in the top left corner.
    """
    pw, ph = size
    img = np.full((ph, pw * len(panels), 3), 255, np.uint8)
    black, grey = (0, 0, 0), (200, 200, 200)
    for k, p in enumerate(panels):
        ox = k * pw
        left, right, top, bottom = ox + 60, ox + pw - 20, 34, ph - 46
        xs_all = np.concatenate([np.asarray(s[1], float) for s in p["series"]])
        ys_all = np.concatenate([np.asarray(s[2], float) for s in p["series"]])
        x0, x1 = p.get("xlim", (float(xs_all.min()), float(xs_all.max())))
        y0, y1 = p.get("ylim", (float(ys_all.min()), float(ys_all.max())))
        if x1 <= x0:
            x1 = x0 + 1.0
        if y1 <= y0:
            y1 = y0 + 1.0

        def X(v):
            return left + (np.asarray(v, float) - x0) / (x1 - x0) * (right - left)

        def Y(v):
            v = np.clip(np.asarray(v, float), y0, y1)
            return bottom - (v - y0) / (y1 - y0) * (bottom - top)

        for v in p.get("xticks", np.linspace(x0, x1, 6)):
            x = X(v)
            draw_line(img, x, top, x, bottom, grey)
            draw_line(img, x, bottom, x, bottom + 6, black)
            draw_text(img, int(x), bottom + 10, _tick_label(v), black, anchor="center")
        for v in p.get("yticks", np.linspace(y0, y1, 6)):
            y = Y(v)
            draw_line(img, left, y, right, y, grey)
            draw_line(img, left - 6, y, left, y, black)
            draw_text(img, left - 9, int(y) - 5, _tick_label(v), black, anchor="right")
        draw_line(img, left, top, left, bottom, black)
        draw_line(img, left, bottom, right, bottom, black)
        for label, xs, ys, color in p["series"]:
            pts = [(X(x), Y(y)) for x, y in zip(xs, ys) if np.isfinite(x) and np.isfinite(y)]
            for (a, b), (c, d) in zip(pts, pts[1:]):
                draw_line(img, a, b, c, d, color, width=2)
        draw_text(img, (left + right) // 2, 10, p.get("title", ""), black, anchor="center")
        draw_text(img, (left + right) // 2, ph - 20, p.get("xlabel", ""), black, anchor="center")
        draw_text(img, ox + 6, top - 20, p.get("ylabel", ""), black)
        if p.get("legend", False):
            ly, lx = top + 8, left + 10
            for label, _, _, color in p["series"]:
                draw_line(img, lx, ly + 5, lx + 20, ly + 5, color, width=3)
                draw_text(img, lx + 26, ly, label, color)
                ly += 16
    return img
