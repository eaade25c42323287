"""Phase functions: closed forms, tabulations and their compiled counterparts.

The compiled core evaluates and samples Henyey-Greenstein, isotropic and the pure-water shape
in closed form. Petzold's tabulated average-particle function and Fournier-Forand are turned
into dense tables, piecewise linear in ``x = 1 - cos(psi)``, that the core treats as *the*
phase function: evaluation and inverse-CDF sampling of the table agree exactly, and the table
follows the source function to interpolation accuracy (tested).
"""
from __future__ import annotations

import functools
from importlib import resources

import numpy as np

PURE_WATER_A = 0.835  # depolarisation 0.09, Morel 1974
PETZOLD_POWER_LAW = -1.346  # slope below 0.1 deg used by Mobley et al. 1993


def table_grid_psi() -> np.ndarray:
    """Scattering angles (radians) of the tabulation: dense and logarithmic in the peak."""
    fine = np.logspace(np.log10(1e-4), np.log10(10.0), 700)
    coarse = np.linspace(10.0, 180.0, 341)[1:]
    return np.radians(np.concatenate([fine, coarse]))


def psi_to_x(psi: np.ndarray) -> np.ndarray:
    """x = 1 - cos(psi), computed without cancellation near psi = 0."""
    return 2.0 * np.sin(0.5 * np.asarray(psi)) ** 2


# --- Petzold average particle -------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def petzold_data() -> tuple[np.ndarray, np.ndarray]:
    """(psi in degrees, phase function in 1/sr) from Mobley et al. 1993 Table 2."""
    text = resources.files("photic.data").joinpath(
        "petzold_average_particle_phase_function.csv").read_text()
    rows = [line.split(",") for line in text.splitlines()
            if line and not line.startswith("#") and not line.startswith("psi")]
    psi = np.array([float(r[0]) for r in rows])
    val = np.array([float(r[1]) for r in rows])
    return psi, val


def petzold(psi_rad: np.ndarray) -> np.ndarray:
    """Petzold phase function (1/sr, as published: integrates to about 0.993), log-log
    interpolated, extended below 0.1 deg as psi^-1.346."""
    psi_d, val = petzold_data()
    deg = np.degrees(np.asarray(psi_rad, dtype=float))
    deg = np.clip(deg, 1e-12, 180.0)
    out = np.exp(np.interp(np.log(deg), np.log(psi_d), np.log(val)))
    small = deg < psi_d[0]
    out[small] = val[0] * (deg[small] / psi_d[0]) ** PETZOLD_POWER_LAW
    return out


# --- Fournier-Forand ----------------------------------------------------------------------

def ff_particle_index(junge_slope: float) -> float:
    """Real refractive index of the particles on Mobley et al. 2002's line."""
    return 1.01 + 0.1542 * (junge_slope - 3.0)


def fournier_forand(psi_rad: np.ndarray, n: float, junge_slope: float) -> np.ndarray:
    """Fournier-Forand phase function (1/sr) for particle index n and Junge slope mu."""
    psi = np.asarray(psi_rad, dtype=float)
    nu = 0.5 * (3.0 - junge_slope)
    s2 = np.sin(0.5 * psi) ** 2
    d = 4.0 / (3.0 * (n - 1.0) ** 2) * s2
    d180 = 4.0 / (3.0 * (n - 1.0) ** 2)
    dnu = d ** nu
    with np.errstate(divide="ignore", invalid="ignore"):
        main = (nu * (1 - d) - (1 - dnu) + (d * (1 - dnu) - nu * (1 - d)) / s2) / (
            4 * np.pi * (1 - d) ** 2 * dnu)
    back = (1 - d180 ** nu) / (16 * np.pi * (d180 - 1) * d180 ** nu) * (3 * np.cos(psi) ** 2 - 1)
    return main + back


def ff_backscatter_fraction(n: float, junge_slope: float) -> float:
    """Closed-form backscatter fraction of Fournier-Forand."""
    nu = 0.5 * (3.0 - junge_slope)
    d90 = 4.0 / (3.0 * (n - 1.0) ** 2) * np.sin(np.pi / 4) ** 2
    return 1.0 - (1.0 - d90 ** (nu + 1) - 0.5 * (1.0 - d90 ** nu)) / ((1.0 - d90) * d90 ** nu)


@functools.lru_cache(maxsize=64)
def ff_parameters(backscatter_fraction: float) -> tuple[float, float]:
    """(n, Junge slope) giving the backscatter fraction (Mobley et al. 2002), by bisection."""
    lo, hi = 3.0 + 1e-6, 5.5
    f = lambda mu: ff_backscatter_fraction(ff_particle_index(mu), mu) - backscatter_fraction
    if f(lo) > 0 or f(hi) < 0:
        raise ValueError(f"backscatter fraction {backscatter_fraction} outside the Fournier-Forand range")
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0:
            hi = mid
        else:
            lo = mid
    mu = 0.5 * (lo + hi)
    return ff_particle_index(mu), mu


# --- tables and compiled objects ----------------------------------------------------------

def tabulate(func) -> tuple[np.ndarray, np.ndarray]:
    """Nodes x (0..2) and values of a phase function given as func(psi_rad)."""
    psi = table_grid_psi()
    x = np.concatenate([[0.0], psi_to_x(psi)])
    v = func(psi)
    v = np.concatenate([[v[0]], v])  # the peak below 1e-4 deg is held constant (flux ~5e-4)
    x[-1] = 2.0
    return x, v


def phase_callable(ptype: str, params: dict):
    """The source function psi -> 1/sr of a phase function description (for tests, plots)."""
    if ptype == "isotropic":
        return lambda psi: np.full_like(np.asarray(psi, float), 1 / (4 * np.pi))
    if ptype == "henyey_greenstein":
        g = float(params["g"])
        return lambda psi: (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * np.cos(psi)) ** 1.5)
    if ptype == "pure_water":
        a = PURE_WATER_A
        return lambda psi: 3 * (1 + a * np.cos(psi) ** 2) / (4 * np.pi * (3 + a))
    if ptype == "petzold":
        return petzold
    if ptype == "fournier_forand":
        n, mu = ff_parameters(float(params["backscatter_fraction"]))
        return lambda psi: fournier_forand(psi, n, mu)
    raise ValueError(f"unknown phase function type {ptype!r}")


def make_core_phase(ptype: str, params: dict | None = None):
    """The compiled PhaseFunction for a scene description's phase function."""
    from . import _core
    params = params or {}
    if ptype == "isotropic":
        return _core.PhaseFunction.isotropic()
    if ptype == "henyey_greenstein":
        return _core.PhaseFunction.henyey_greenstein(float(params["g"]))
    if ptype == "pure_water":
        return _core.PhaseFunction.quadratic(PURE_WATER_A)
    if ptype in ("petzold", "fournier_forand"):
        x, v = tabulate(phase_callable(ptype, params))
        return _core.PhaseFunction.table(x, v)
    raise ValueError(f"unknown phase function type {ptype!r}")
