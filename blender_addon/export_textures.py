"""Blender images as Photic's reflectance textures and sky tables: pixels read in bulk
(``foreach_get``), decoded to linear values from the image's colour space, and reduced to at
most MAX_SIDE texels on a side.

An image's linear RGB is kept while the image is unchanged (name, file, size, colour space), so
viewport re-exports do not read it again; the band conversion (nearest primary) is done per
export. Blender's ``Image.pixels`` start at the bottom-left pixel, which is the texture's
(u, v) = (0, 0): rows go up, as Photic's textures do.
"""
from __future__ import annotations

import numpy as np

from . import bands as bandmod

MAX_SIDE = 2048            # texels on a side kept (larger images are box-filtered down)
MAX_READ = 8192 * 8192     # pixels read at most (an image beyond is not used: a warning says so)
LINEAR_SPACES = ("linear", "non-color", "raw", "xyz", "working space", "scene_linear")
_CACHE: dict = {}
_CACHE_ITEMS = 8


class ImageProblem(Exception):
    """An image that cannot be used: the message says why."""


def _key(image) -> tuple:
    return (image.name_full, image.filepath, tuple(image.size), image.colorspace_settings.name,
            bool(image.is_dirty), image.source)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.0) + 0.055) / 1.055) ** 2.4)


def _box_reduce(img: np.ndarray, max_side: int) -> np.ndarray:
    """Average blocks of f x f pixels, f the smallest integer bringing both sides <= max_side."""
    h, w = img.shape[:2]
    f = max(1, -(-max(h, w) // max_side))
    if f == 1:
        return img
    h2, w2 = h // f, w // f
    return img[:h2 * f, :w2 * f].reshape(h2, f, w2, f, -1).mean(axis=(1, 3)).astype(np.float32)


def linear_rgb(image, max_side: int = MAX_SIDE) -> tuple[np.ndarray, str | None]:
    """(H, W, 3) float32 linear RGB of a Blender image (bottom row first), at most ``max_side``
    on a side, and a note when its colour space is approximated (else None).

    Raises ImageProblem for an image without pixels or too large to read."""
    w, h = (int(x) for x in image.size)
    if w <= 0 or h <= 0:
        where = image.filepath or image.name
        raise ImageProblem(f"image '{image.name}' has no pixels (file not found or not loaded: {where})")
    if w * h > MAX_READ:
        raise ImageProblem(f"image '{image.name}' is {w} x {h} pixels, beyond the {MAX_READ:,} Photic "
                           f"reads: scale it down")
    key = _key(image) + (max_side,)
    if key in _CACHE:
        return _CACHE[key]
    channels = int(image.channels)
    buf = np.empty(w * h * channels, np.float32)
    image.pixels.foreach_get(buf)
    px = buf.reshape(h, w, channels)
    rgb = np.repeat(px[:, :, :1], 3, axis=2) if channels < 3 else px[:, :, :3]
    rgb = np.ascontiguousarray(rgb)
    note = None
    space = image.colorspace_settings.name
    if not image.is_float:  # byte images come as their encoded values (floats are linear)
        if space.lower() == "srgb":
            rgb = srgb_to_linear(rgb)
        elif not any(space.lower().startswith(s) for s in LINEAR_SPACES):
            rgb = srgb_to_linear(rgb)
            note = f"image '{image.name}': colour space '{space}' is approximated as sRGB"
    out = (_box_reduce(rgb.astype(np.float32), max_side), note)
    if len(_CACHE) >= _CACHE_ITEMS:
        _CACHE.pop(next(iter(_CACHE)))
    _CACHE[key] = out
    return out


def to_bands(rgb: np.ndarray, bands) -> np.ndarray:
    """(H, W, 3) RGB as (H, W, nbands) float32, each band its nearest primary (as colours)."""
    idx = [bandmod._primary(c) for _, c, _ in bands]
    return np.ascontiguousarray(rgb[:, :, idx], dtype=np.float32)
