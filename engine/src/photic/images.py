"""Images for people: tone mapping of radiance to sRGB, and PNG files (written by matplotlib)."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def write_png(path: str | Path, image: np.ndarray) -> Path:
    """Write an 8-bit PNG with ``matplotlib.image.imsave``.

    Parameters
    ----------
    path : str or Path
        Output file; parent folders are created.
    image : ndarray
        (H, W) grey or (H, W, 3) RGB, either uint8 or floats in [0, 1] (clipped, rounded).
    """
    from matplotlib.image import imsave

    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(np.round(np.nan_to_num(img.astype(np.float64)) * 255.0), 0, 255).astype(np.uint8)
    if img.ndim == 2:  # grey as RGB: imsave would colour-map a 2-D array
        img = np.repeat(img[:, :, None], 3, axis=2)
    elif not (img.ndim == 3 and img.shape[2] == 3):
        raise ValueError(f"image must be (H, W) or (H, W, 3), got shape {img.shape}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    imsave(path, np.ascontiguousarray(img), format="png")
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
