"""Sky radiance models that the core reads as a table.

- Harrison & Coombes (1988), as HydroLight uses it (PHYSICS-NOTES 7): with psi the angle
  between the sky direction and the sun, theta_s the sun's zenith angle and mu the cosine of
  the sky direction's zenith angle (radians),
  N_clear = (1.63 + 53.7 exp(-5.49 psi) + 2.04 cos^2(psi) cos(theta_s)) (1 - exp(-0.19 / mu))
            (1 - exp(-0.53 / cos(theta_s))),
  N_overcast = 0.45 + 0.12 theta_s + 0.43 mu + 0.72 exp(-1.88 psi),
  N = C N_overcast + (1 - C) N_clear for the cloud fraction C. The model is not normalised:
  the table is scaled numerically so that the sky's downwelling plane irradiance on a
  horizontal surface is pi times the sky's L0 (the scene's 'radiance', or 'irradiance' / pi).
  As in HydroLight the sun is kept at most 89 degrees from the zenith for the model.

The table holds the relative radiance on zenith-angle nodes 0..90 degrees (``N_THETA``) and
azimuth nodes 0..360 degrees (``N_PHI``, periodic); the core interpolates it bilinearly.
"""
from __future__ import annotations

import math

import numpy as np

N_THETA = 181   # every 0.5 degree of zenith angle
N_PHI = 360     # every degree of azimuth
MAX_SUN_ZENITH_DEG = 89.0


def harrison_coombes(theta, phi, sun_zenith_deg: float, sun_azimuth_deg: float,
                     cloud_fraction: float = 0.0) -> np.ndarray:
    """Unnormalised sky radiance N at zenith angle ``theta`` and azimuth ``phi`` (radians)."""
    ts = math.radians(min(sun_zenith_deg, MAX_SUN_ZENITH_DEG))
    ps = math.radians(sun_azimuth_deg)
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    mu = np.maximum(np.cos(theta), 1e-6)
    cos_psi = np.clip(np.cos(theta) * math.cos(ts) + np.sin(theta) * math.sin(ts) * np.cos(phi - ps), -1, 1)
    psi = np.arccos(cos_psi)
    clear = ((1.63 + 53.7 * np.exp(-5.49 * psi) + 2.04 * cos_psi ** 2 * math.cos(ts))
             * (1 - np.exp(-0.19 / mu)) * (1 - math.exp(-0.53 / math.cos(ts))))
    overcast = 0.45 + 0.12 * ts + 0.43 * mu + 0.72 * np.exp(-1.88 * psi)
    return cloud_fraction * overcast + (1 - cloud_fraction) * clear


def _bilinear(table: np.ndarray, theta, phi) -> np.ndarray:
    """The core's interpolation of a table (for the normalisation)."""
    nt, nphi = table.shape
    th = np.clip(theta / (0.5 * math.pi), 0, 1) * (nt - 1)
    ph = (np.mod(phi, 2 * math.pi) / (2 * math.pi)) * nphi
    i0 = np.minimum(nt - 2, th.astype(int))
    j0 = ph.astype(int) % nphi
    j1 = (j0 + 1) % nphi
    ft, fp = th - i0, ph - np.floor(ph)
    return ((1 - ft) * ((1 - fp) * table[i0, j0] + fp * table[i0, j1])
            + ft * ((1 - fp) * table[i0 + 1, j0] + fp * table[i0 + 1, j1]))


def horizontal_irradiance(table: np.ndarray, n_theta: int = 720, n_phi: int = 720) -> float:
    """Integral of the interpolated table times cos(theta) over the upper hemisphere (sr)."""
    t = (np.arange(n_theta) + 0.5) * (0.5 * math.pi / n_theta)
    p = (np.arange(n_phi) + 0.5) * (2 * math.pi / n_phi)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    w = np.cos(tt) * np.sin(tt) * (0.5 * math.pi / n_theta) * (2 * math.pi / n_phi)
    return float(np.sum(_bilinear(table, tt, pp) * w))


def sky_table(sun_zenith_deg: float, sun_azimuth_deg: float, cloud_fraction: float = 0.0) -> np.ndarray:
    """The normalised Harrison-Coombes table: relative radiance whose horizontal irradiance is
    pi (so L0 = E_diffuse / pi gives the diffuse irradiance E_diffuse)."""
    t = np.linspace(0.0, 0.5 * math.pi, N_THETA)
    p = np.arange(N_PHI) * (2 * math.pi / N_PHI)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    table = harrison_coombes(tt, pp, sun_zenith_deg, sun_azimuth_deg, cloud_fraction)
    return table * (math.pi / horizontal_irradiance(table))
