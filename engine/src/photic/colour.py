"""Display colour of band images: bands -> CIE 1931 XYZ -> linear sRGB.

The band values are taken as samples of a continuous spectrum at the band centres (linear
between centres, zero beyond the outermost bands' edges) and integrated against the CIE 1931
2-degree colour-matching functions in the analytic multi-lobe form of Wyman, Sloan & Shirley
(2013, "Simple analytic approximations to the CIE XYZ color matching functions", JCGT 2(2)),
within about 1 % of the tabulated functions. XYZ goes to linear sRGB (IEC 61966-2-1 matrix,
D65), then each channel is scaled so that a flat spectrum of value v shows as (v, v, v)
(white balance to the equal-energy spectrum: under water, "white" is whatever the sun gives).
"""
from __future__ import annotations

import numpy as np

# numpy 2 renamed trapz (removed in 2.4); numpy 1.x, which bpy 5.0 needs, has only trapz.
trapezoid = getattr(np, "trapezoid", None) or np.trapz

XYZ_TO_LINEAR_SRGB = np.array([[3.2406, -1.5372, -0.4986],
                               [-0.9689, 1.8758, 0.0415],
                               [0.0557, -0.2040, 1.0570]])

# (weight, centre nm, sigma below, sigma above) of each lobe (Wyman et al. 2013, table 1 form).
_LOBES = {
    "x": ((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),
    "y": ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),
    "z": ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)),
}
WAVELENGTHS = np.arange(360.0, 830.5, 0.5)


def cmf(wavelength_nm) -> np.ndarray:
    """x-bar, y-bar, z-bar at the given wavelengths (nm): array (..., 3)."""
    lam = np.asarray(wavelength_nm, float)
    out = []
    for axis in "xyz":
        v = np.zeros_like(lam)
        for w, mu, s1, s2 in _LOBES[axis]:
            s = np.where(lam < mu, s1, s2)
            v = v + w * np.exp(-0.5 * ((lam - mu) / s) ** 2)
        out.append(v)
    return np.stack(out, -1)


def band_matrix(bands) -> np.ndarray:
    """(nbands, 3) matrix taking band values to linear sRGB (white balanced to a flat spectrum).

    ``bands``: ``photic.scene.Band``s or (centre_nm, width_nm) pairs."""
    pairs = [(b.center_nm, b.width_nm) if hasattr(b, "center_nm") else (b[-2], b[-1]) for b in bands]
    centres = np.array([c for c, _ in pairs], float)
    order = np.argsort(centres)
    lo = centres[order[0]] - pairs[order[0]][1] / 2
    hi = centres[order[-1]] + pairs[order[-1]][1] / 2
    lam = WAVELENGTHS
    inside = (lam >= lo) & (lam <= hi)
    xyz = np.zeros((len(pairs), 3))
    for k in range(len(pairs)):  # the spectrum's response to a unit value in band k (hat function)
        e = np.zeros(len(pairs))
        e[k] = 1.0
        spectrum = np.interp(lam, centres[order], e[order]) * inside
        xyz[k] = trapezoid(spectrum[:, None] * cmf(lam), lam, axis=0)
    rgb = xyz @ XYZ_TO_LINEAR_SRGB.T
    white = rgb.sum(axis=0)
    if np.any(white <= 0):
        raise ValueError("the bands do not span enough of the visible spectrum for a colour image")
    return rgb / white


def bands_to_rgb(image: np.ndarray, bands) -> np.ndarray:
    """(..., nbands) band values -> (..., 3) linear sRGB."""
    return np.asarray(image, float) @ band_matrix(bands)
