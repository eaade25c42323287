"""Denoising a rendered image with Intel Open Image Denoise (OIDN), guided by the camera's
albedo and normal (``Scene::camera_guides``), the way Cycles users know it.

OIDN is the denoiser Blender itself ships; its Python binding ``pyoidn`` (a requirement of
the package) carries the library. OIDN filters three channels at a time, so an image of
``n`` bands is denoised as ceil(n / 3) RGB images of consecutive bands (the last padded with
its own last band), each with the same bands of the albedo.

A denoised image is an estimate with a bias: it has no standard error, and it smooths detail
that the noise hides at the sample count given, caustic networks first (see
docs/benchmarks.md, "Denoising"). Keep the noisy image for numbers.
"""
from __future__ import annotations

import numpy as np

GUIDE_RAYS_PER_AXIS = 2  # 4 fixed sub-pixel rays per pixel: anti-aliased, noise-free guides


class DenoiserMissing(RuntimeError):
    """OpenImageDenoise (``pyoidn``) is not installed."""


def available() -> bool:
    try:
        import pyoidn  # noqa: F401
    except (ImportError, OSError):
        return False
    return True


def _oidn():
    try:
        import pyoidn
    except (ImportError, OSError) as exc:
        raise DenoiserMissing("denoising needs OpenImageDenoise's Python binding: pip install pyoidn "
                              f"(scripts/install.sh installs it) ({exc})") from exc
    return pyoidn


def denoise_rgb(color: np.ndarray, albedo: np.ndarray | None = None,
                normal: np.ndarray | None = None) -> np.ndarray:
    """An (H, W, 3) HDR image denoised, with optional (H, W, 3) albedo in [0, 1] and normal
    guides (noise-free: no prefiltering). Non-finite values in the colour are taken as 0."""
    pyoidn = _oidn()
    c = np.ascontiguousarray(np.nan_to_num(np.asarray(color, np.float32), nan=0.0, posinf=0.0, neginf=0.0))
    c = np.maximum(c, 0.0)
    a = None if albedo is None else np.ascontiguousarray(np.clip(albedo, 0.0, 1.0), np.float32)
    n = None if normal is None else np.ascontiguousarray(np.clip(normal, -1.0, 1.0), np.float32)
    if a is None and n is not None:
        n = None  # OIDN takes a normal only together with an albedo
    out = pyoidn.denoise(c, a, n, hdr=True, clean_aux=a is not None, quality="high")
    return np.asarray(out, np.float32)


def _triples(nbands: int) -> list[list[int]]:
    return [[min(i + k, nbands - 1) for k in range(3)] for i in range(0, nbands, 3)]


def denoise_bands(mean: np.ndarray, albedo: np.ndarray | None = None,
                  normal: np.ndarray | None = None) -> np.ndarray:
    """An (H, W, bands) image denoised three bands at a time (float64 out, as the engine's
    images), each triple with the same bands of an (H, W, bands) albedo and the (H, W, 3)
    normal."""
    mean = np.asarray(mean)
    out = np.empty(mean.shape, np.float64)
    for idx in _triples(mean.shape[2]):
        d = denoise_rgb(mean[:, :, idx], None if albedo is None else albedo[:, :, idx], normal)
        for k, b in enumerate(idx):
            out[:, :, b] = d[:, :, k]
    return out


def guides(core, camera_index: int, threads: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(albedo (H, W, bands), normal (H, W, 3)) of a compiled scene's camera."""
    a, n = core.camera_guides(camera_index, GUIDE_RAYS_PER_AXIS, threads)
    return np.asarray(a), np.asarray(n)
