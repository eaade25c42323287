"""Inherent optical properties of pure water, per band.

- Absorption: Pope & Fry (1997), 380-727.5 nm, averaged over each band (linear interpolation
  of the 2.5 nm table, trapezoidal mean over [centre - width/2, centre + width/2]).
- Scattering: pure sea water, b_w = 0.00288 (lambda / 500 nm)^-4.32 m^-1 (Morel 1974; Smith &
  Baker 1981), averaged over the band, with the pure-water phase function (1 + 0.835 cos^2).

The natural-waters work adds the chlorophyll, CDOM and particle models on top of these.
"""
from __future__ import annotations

import csv
from functools import lru_cache
from importlib import resources

import numpy as np

POPE_FRY_RANGE_NM = (380.0, 727.5)


@lru_cache(maxsize=1)
def _pope_fry() -> tuple[np.ndarray, np.ndarray]:
    text = resources.files("photic.data").joinpath("pope_fry_1997_pure_water_absorption.csv").read_text()
    rows = list(csv.DictReader(line for line in text.splitlines() if line and not line.startswith("#")))
    return (np.array([float(r["wavelength_nm"]) for r in rows]),
            np.array([float(r["aw_per_m"]) for r in rows]))


def _band_grid(center_nm: float, width_nm: float) -> np.ndarray:
    lo, hi = center_nm - width_nm / 2.0, center_nm + width_nm / 2.0
    return np.linspace(lo, hi, max(2, int(np.ceil((hi - lo) / 0.5)) + 1))


def pure_water_absorption(center_nm: float, width_nm: float = 0.0) -> float:
    """Band-averaged absorption coefficient of pure water (1/m), Pope & Fry 1997.

    Raises
    ------
    ValueError
        If the band reaches outside 380-727.5 nm, where the table has no data."""
    lo, hi = center_nm - width_nm / 2.0, center_nm + width_nm / 2.0
    if lo < POPE_FRY_RANGE_NM[0] - 1e-9 or hi > POPE_FRY_RANGE_NM[1] + 1e-9:
        raise ValueError(f"band {center_nm:g} +- {width_nm / 2:g} nm reaches outside the Pope & Fry "
                         f"table ({POPE_FRY_RANGE_NM[0]:g}-{POPE_FRY_RANGE_NM[1]:g} nm)")
    wl, aw = _pope_fry()
    if width_nm <= 0.0:
        return float(np.interp(center_nm, wl, aw))
    grid = _band_grid(center_nm, width_nm)
    return float(np.trapz(np.interp(grid, wl, aw), grid) / (grid[-1] - grid[0]))


def pure_water_scattering(center_nm: float, width_nm: float = 0.0) -> float:
    """Band-averaged scattering coefficient of pure sea water (1/m), 0.00288 (lambda/500)^-4.32."""
    if width_nm <= 0.0:
        return 0.00288 * (center_nm / 500.0) ** -4.32
    grid = _band_grid(center_nm, width_nm)
    return float(np.trapz(0.00288 * (grid / 500.0) ** -4.32, grid) / (grid[-1] - grid[0]))
