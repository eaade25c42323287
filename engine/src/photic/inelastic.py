"""Inelastic scattering: Raman scattering by water, coupled across a scene's bands.

Raman scattering by water molecules (the O-H stretching band) re-emits light shifted by about
3,400 cm^-1 in wavenumber to longer wavelengths. The model, as ocean-colour radiative transfer
codes use it:

- the Raman scattering coefficient b_R(lambda') = 2.7e-4 m^-1 (488 nm / lambda')^5.5 for
  excitation wavelength lambda', normalised to energy (Bartlett, Voss, Sathyendranath and
  Vodacek 1998, Appl. Opt. 37, 3324: (2.7 +- 0.2) 1e-4 m^-1 at 488 nm, lambda'^-(5.5 +- 0.4));
- the phase function 3 / (4 pi (3 + rho)) (1 + rho cos^2 psi) with rho = 0.55 (a
  depolarisation ratio of 0.17), normalised over the sphere;
- the emission's wavenumber shift a Gaussian centred at 3,400 cm^-1 with a full width at half
  maximum of 400 cm^-1 (one Gaussian for the O-H band, which Walrafen (1967) resolves into
  four: an approximation, stated where its results are reported).

A scene's bands are sampled spectra (a band's value is a spectral density at its centre,
representative of its width). The coupling ``raman_coupling(bands)[j, i]`` (m^-1) is the
band-averaged source: light of spectral irradiance E (per nm) spread evenly over excitation
band i, Raman-scattered, gives emission band j the mean spectral source coupling[j, i] E per
unit solid angle times the phase function, i.e. the integral over band i of b_R f d(lambda'),
averaged over band j, where f(lambda' -> lambda) is the emission's density per nm.
``raman_coverage(bands)`` says how much of each emission band's excitation the bands hold.
"""
from __future__ import annotations

import functools
import math
import types

import numpy as np

RAMAN_B_488 = 2.7e-4       # m^-1, excitation at 488 nm (Bartlett et al. 1998)
RAMAN_EXPONENT = 5.5       # b_R ~ lambda'^-5.5, energy-normalised (Bartlett et al. 1998)
RAMAN_SHIFT_CM = 3400.0    # cm^-1, the centre of the wavenumber shift
RAMAN_FWHM_CM = 400.0      # cm^-1, the shift's full width at half maximum (one Gaussian)
RAMAN_RHO = 0.55           # phase function 1 + rho cos^2 (depolarisation ratio 0.17)
_SIGMA_CM = RAMAN_FWHM_CM / (2.0 * math.sqrt(2.0 * math.log(2.0)))
_REACH_CM = 4.0 * RAMAN_FWHM_CM  # the shift's Gaussian is cut there (9.4 sigma)
_NODES = 64                # quadrature nodes per band and per excitation range


def raman_b(excitation_nm) -> np.ndarray:
    """The Raman scattering coefficient b_R (m^-1) at excitation wavelengths (nm)."""
    return RAMAN_B_488 * (488.0 / np.asarray(excitation_nm, float)) ** RAMAN_EXPONENT


def raman_phase(mu) -> np.ndarray:
    """The Raman phase function (sr^-1) at the cosine of the scattering angle."""
    mu = np.asarray(mu, float)
    return 3.0 / (4.0 * math.pi * (3.0 + RAMAN_RHO)) * (1.0 + RAMAN_RHO * mu * mu)


def emission_density(excitation_nm, emission_nm) -> np.ndarray:
    """f(lambda' -> lambda) (nm^-1): the share of light Raman-scattered at ``excitation_nm``
    emitted per nm at ``emission_nm`` (normalised over lambda for each lambda')."""
    k_ex = 1e7 / np.asarray(excitation_nm, float)
    lam = np.asarray(emission_nm, float)
    shift = k_ex - 1e7 / lam
    g = np.exp(-0.5 * ((shift - RAMAN_SHIFT_CM) / _SIGMA_CM) ** 2) / (_SIGMA_CM * math.sqrt(2 * math.pi))
    g = np.where(np.abs(shift - RAMAN_SHIFT_CM) <= _REACH_CM, g, 0.0)  # (beyond: < 1e-19 of the peak)
    return g * 1e7 / lam ** 2  # per cm^-1 of wavenumber -> per nm of wavelength


def excitation_nm(emission_nm) -> np.ndarray:
    """The excitation wavelength (nm) whose Raman light is centred on ``emission_nm``."""
    return 1e7 / (1e7 / np.asarray(emission_nm, float) + RAMAN_SHIFT_CM)


def _band_nodes(center: float, width: float) -> np.ndarray:
    """Midpoint nodes over [center - width / 2, center + width / 2], at wavelengths above 1 nm
    (a band wider than twice its centre reaches below 0: no light there)."""
    return np.maximum(center + width * ((np.arange(_NODES) + 0.5) / _NODES - 0.5), 1.0)


def raman_coupling(bands) -> np.ndarray:
    """(nb, nb) coupling [emission j, excitation i] (m^-1) for ``bands`` (objects with
    ``center_nm`` and ``width_nm``): int over band i of b_R(l') f(l' -> l) dl', averaged over
    l in band j; 0 where no shift (within 4 widths of 3,400 cm^-1) reaches."""
    centers = [float(b.center_nm) for b in bands]
    widths = [float(b.width_nm) for b in bands]
    nb = len(bands)
    m = np.zeros((nb, nb))
    for i in range(nb):
        lex = _band_nodes(centers[i], widths[i])
        bex = raman_b(lex) * widths[i] / _NODES  # b_R dl' per node
        for j in range(nb):
            lem = _band_nodes(centers[j], widths[j])
            m[j, i] = float(np.mean(emission_density(lex[None, :], lem[:, None]) @ bex))
    return m


AUTO_COVERAGE = 0.05  # "auto" turns Raman on where a band gets at least this share of its Raman light


def raman_auto(bands) -> bool:
    """Whether ``settings.raman = "auto"`` (the default) renders Raman scattering for these
    bands: where some band gets at least 5 % of its Raman light from the bands' own excitation
    (else there is nothing to see, and the scene renders as purely elastic)."""
    return _raman_auto(tuple((float(b.center_nm), float(b.width_nm)) for b in bands))


@functools.lru_cache(maxsize=64)
def _raman_auto(bands: tuple) -> bool:  # (asked per image and per unit: a few ms each)
    bs = [types.SimpleNamespace(center_nm=c, width_nm=w) for c, w in bands]
    return len(bs) > 1 and bool((raman_coverage(bs) >= AUTO_COVERAGE).any() and raman_coupling(bs).any())


def raman_active(scene) -> bool:
    """Whether a scene renders Raman scattering: ``settings.raman`` true, or "auto" where
    ``raman_auto`` says its bands can receive it."""
    mode = getattr(scene.settings, "raman", "auto")
    return raman_auto(scene.bands) if mode == "auto" else bool(mode)


def raman_coverage(bands) -> np.ndarray:
    """Per band (as an emission band): the share of its Raman source, for light flat in
    wavelength, that comes from excitation wavelengths inside the scene's bands (1: all of
    it; the rest the render cannot see)."""
    out = np.ones(len(bands))
    for j, bj in enumerate(bands):
        lem = _band_nodes(float(bj.center_nm), float(bj.width_nm))
        lo = 1e7 / (1e7 / lem.min() + RAMAN_SHIFT_CM + _REACH_CM)
        hi = 1e7 / (1e7 / lem.max() + RAMAN_SHIFT_CM - _REACH_CM)
        grid = np.linspace(lo, hi, 4 * _NODES)
        step = grid[1] - grid[0]
        src = (raman_b(grid)[None, :] * emission_density(grid[None, :], lem[:, None])).mean(axis=0) * step
        inside = np.zeros_like(grid, dtype=bool)
        for b in bands:
            inside |= np.abs(grid - float(b.center_nm)) <= 0.5 * float(b.width_nm)
        total = src.sum()
        out[j] = float(src[inside].sum() / total) if total > 0 else 1.0
    return out


# ---- Chlorophyll fluorescence ----------------------------------------------------------------
#
# Phytoplankton re-emit a small share of the light their chlorophyll absorbs, isotropically,
# around 685 nm (the emission of chlorophyll a in vivo: a Gaussian of about 25 nm full width,
# e.g. Gordon 1979, Appl. Opt. 18, 1161; Mobley 1994, "Light and Water", 5.13). The excitation
# is the phytoplankton's absorption a_ph between 370 and 690 nm; the quantum yield (photons
# emitted per photon absorbed) is a parameter, 0.02 by default (natural waters: about
# 0.01-0.05). Energy: an absorbed photon of lambda' gives an emitted photon of lambda, so the
# energy re-emitted is phi (lambda' / lambda) of the energy absorbed.

CHL_EXCITATION_NM = (370.0, 690.0)  # the chlorophyll's excitation range
CHL_PEAK_NM = 685.0
CHL_FWHM_NM = 25.0
CHL_YIELD = 0.02
CHL_REACH = 4.0  # the emission's Gaussian is cut at 4 full widths (beyond: < 1e-19 of its peak)


def chlorophyll_emission(emission_nm, peak_nm: float = CHL_PEAK_NM, fwhm_nm: float = CHL_FWHM_NM) -> np.ndarray:
    """g(lambda) (nm^-1): the share of emitted photons per nm (normalised over lambda)."""
    lam = np.asarray(emission_nm, float)
    sigma = fwhm_nm / (2.0 * math.sqrt(2.0 * math.log(2.0)))
    g = np.exp(-0.5 * ((lam - peak_nm) / sigma) ** 2) / (sigma * math.sqrt(2.0 * math.pi))
    return np.where(np.abs(lam - peak_nm) <= CHL_REACH * fwhm_nm, g, 0.0)


def chlorophyll_coupling(bands, absorption, quantum_yield: float = CHL_YIELD, peak_nm: float = CHL_PEAK_NM,
                         fwhm_nm: float = CHL_FWHM_NM) -> np.ndarray:
    """(nb, nb) coupling [emission j, excitation i] (m^-1), or (layers, nb, nb) for one
    absorption spectrum per layer, as ``raman_coupling``'s: light of spectral irradiance E
    (per nm) flat over excitation band i, absorbed by the phytoplankton (a_ph[i], flat over
    the band's part in 370-690 nm), gives emission band j the mean spectral source
    coupling[j, i] E per unit solid angle times the isotropic phase function 1 / (4 pi):
    phi a_ph[i] int (lambda' / lambda) g(lambda) dlambda', averaged over lambda in band j."""
    a = np.asarray(absorption, float)
    if a.ndim == 2:
        return np.stack([chlorophyll_coupling(bands, row, quantum_yield, peak_nm, fwhm_nm) for row in a])
    nb = len(bands)
    lo, hi = CHL_EXCITATION_NM
    m = np.zeros((nb, nb))
    for i, bi in enumerate(bands):
        c, w = float(bi.center_nm), float(bi.width_nm)
        left, right = max(c - 0.5 * w, lo), min(c + 0.5 * w, hi)
        if not (right > left) or not (a[i] > 0):
            continue
        lam_ex = 0.5 * (left + right)  # int over the excitation part of lambda' d lambda' = its width x its mean
        absorbed = quantum_yield * a[i] * (right - left) * lam_ex
        for j, bj in enumerate(bands):
            lem = _band_nodes(float(bj.center_nm), float(bj.width_nm))
            m[j, i] = absorbed * float(np.mean(chlorophyll_emission(lem, peak_nm, fwhm_nm) / lem))
    return m


def chlorophyll_coverage(bands, peak_nm: float = CHL_PEAK_NM, fwhm_nm: float = CHL_FWHM_NM) -> float:
    """The share of the emitted photons whose wavelengths lie inside the scene's bands."""
    grid = np.linspace(peak_nm - CHL_REACH * fwhm_nm, peak_nm + CHL_REACH * fwhm_nm, 4001)
    inside = np.zeros_like(grid, dtype=bool)
    for b in bands:
        inside |= np.abs(grid - float(b.center_nm)) <= 0.5 * float(b.width_nm)
    g = chlorophyll_emission(grid, peak_nm, fwhm_nm)
    return float(np.trapz(g * inside, grid) / np.trapz(g, grid))


def water_processes(scene, water) -> list[tuple[int, np.ndarray, float]]:
    """The inelastic processes of a water body for the core (Scene.set_water_inelastic):
    (kind, coupling over all the scene's bands, phase rho); kind 0 Raman scattering (with
    raman_active), 1 chlorophyll fluorescence (a water with ``fluorescence``)."""
    out = []
    if raman_active(scene):
        out.append((0, raman_coupling(scene.bands), RAMAN_RHO))
    f = getattr(water, "fluorescence", None)
    if f is not None:
        out.append((1, chlorophyll_coupling(scene.bands, f.absorption, f.quantum_yield, f.peak_nm, f.fwhm_nm), 0.0))
    return out
