"""Inelastic scattering: Raman scattering by water, fluorescence by chlorophyll and CDOM,
coupled across a scene's bands.

Raman scattering by water molecules (the O-H stretching band) re-emits light shifted by about
3,400 cm^-1 in wavenumber to longer wavelengths. The model, as ocean-colour radiative transfer
codes use it:

- the Raman scattering coefficient b_R(lambda') = 2.7e-4 m^-1 (488 nm / lambda')^5.5 for
  excitation wavelength lambda', normalised to energy (Bartlett, Voss, Sathyendranath and
  Vodacek 1998, Appl. Opt. 37, 3324: (2.7 +- 0.2) 1e-4 m^-1 at 488 nm, lambda'^-(5.5 +- 0.4));
- the phase function 3 / (4 pi (3 + rho)) (1 + rho cos^2 psi) with rho = 0.55 (a
  depolarisation ratio of 0.17), normalised over the sphere;
- the emission's wavenumber shift the O-H band as Walrafen (1967) resolves it: four Gaussians
  at 3,250, 3,425, 3,530 and 3,625 cm^-1 with full widths at half maximum of 210, 175, 140
  and 140 cm^-1 and weights 0.41, 0.39, 0.10, 0.10 (Mobley 1994, "Light and Water", Table
  5.3, as HydroLight uses them): a mean shift of 3,384 cm^-1.

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
# Walrafen's four Gaussians of the wavenumber shift (cm^-1): weights, centres, full widths
RAMAN_WEIGHTS = np.array([0.41, 0.39, 0.10, 0.10])
RAMAN_CENTRES_CM = np.array([3250.0, 3425.0, 3530.0, 3625.0])
RAMAN_FWHM_CM = np.array([210.0, 175.0, 140.0, 140.0])
RAMAN_SHIFT_CM = float(RAMAN_WEIGHTS @ RAMAN_CENTRES_CM / RAMAN_WEIGHTS.sum())  # the mean shift
# the shifts from the first Gaussian's half maximum below to the last's above (most of the light)
RAMAN_SHIFT_RANGE_CM = (float((RAMAN_CENTRES_CM - RAMAN_FWHM_CM).min()), float((RAMAN_CENTRES_CM + RAMAN_FWHM_CM).max()))
RAMAN_RHO = 0.55           # phase function 1 + rho cos^2 (depolarisation ratio 0.17)
_SIGMA_CM = RAMAN_FWHM_CM / (2.0 * math.sqrt(2.0 * math.log(2.0)))
# each Gaussian is cut 4 full widths from its centre (9.4 sigma: beyond, < 1e-19 of its peak)
_REACH_LO_CM = float((RAMAN_CENTRES_CM - 4.0 * RAMAN_FWHM_CM).min())
_REACH_HI_CM = float((RAMAN_CENTRES_CM + 4.0 * RAMAN_FWHM_CM).max())
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
    shift = np.asarray(k_ex - 1e7 / lam)[..., None]
    z = (shift - RAMAN_CENTRES_CM) / _SIGMA_CM
    g = np.where(np.abs(z) <= 4.0 * 2.0 * math.sqrt(2.0 * math.log(2.0)),
                 RAMAN_WEIGHTS * np.exp(-0.5 * z * z) / (_SIGMA_CM * math.sqrt(2 * math.pi)), 0.0)
    g = g.sum(axis=-1) / RAMAN_WEIGHTS.sum()
    return g * 1e7 / lam ** 2  # per cm^-1 of wavenumber -> per nm of wavelength


def excitation_nm(emission_nm) -> np.ndarray:
    """The excitation wavelength (nm) whose Raman light is centred on ``emission_nm``."""
    return 1e7 / (1e7 / np.asarray(emission_nm, float) + RAMAN_SHIFT_CM)


def _inside(grid: np.ndarray, bands) -> np.ndarray:
    """Which wavelengths of ``grid`` lie inside one of the bands."""
    inside = np.zeros_like(grid, dtype=bool)
    for b in bands:
        inside |= np.abs(grid - float(b.center_nm)) <= 0.5 * float(b.width_nm)
    return inside


def _band_nodes(center: float, width: float) -> np.ndarray:
    """Midpoint nodes over [center - width / 2, center + width / 2], at wavelengths above 1 nm
    (a band wider than twice its centre reaches below 0: no light there)."""
    return np.maximum(center + width * ((np.arange(_NODES) + 0.5) / _NODES - 0.5), 1.0)


def _key(bands) -> tuple:
    return tuple((float(b.center_nm), float(b.width_nm)) for b in bands)


def raman_coupling(bands) -> np.ndarray:
    """(nb, nb) coupling [emission j, excitation i] (m^-1) for ``bands`` (objects with
    ``center_nm`` and ``width_nm``): int over band i of b_R(l') f(l' -> l) dl', averaged over
    l in band j; 0 where no shift (within 4 widths of Walrafen's Gaussians) reaches."""
    return _raman_coupling(_key(bands)).copy()


@functools.lru_cache(maxsize=64)
def _raman_coupling(bands: tuple) -> np.ndarray:  # (asked for warnings, band groups and each compile)
    centers = [c for c, _ in bands]
    widths = [w for _, w in bands]
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
    return _raman_auto(_key(bands))


@functools.lru_cache(maxsize=64)
def _raman_auto(bands: tuple) -> bool:  # (asked per image and per unit: a few ms each)
    bs = [types.SimpleNamespace(center_nm=c, width_nm=w) for c, w in bands]
    return len(bs) > 1 and bool((raman_coverage(bs) >= AUTO_COVERAGE).any() and _raman_coupling(bands).any())


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
        lo = 1e7 / (1e7 / lem.min() + _REACH_HI_CM)
        hi = 1e7 / (1e7 / lem.max() + _REACH_LO_CM)
        grid = np.linspace(lo, hi, 4 * _NODES)
        step = grid[1] - grid[0]
        src = (raman_b(grid)[None, :] * emission_density(grid[None, :], lem[:, None])).mean(axis=0) * step
        inside = _inside(grid, bands)
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
    lo, hi = CHL_EXCITATION_NM
    absorbed = np.zeros(len(bands))  # per excitation band: phi a_ph int lambda' d lambda' over its part in lo..hi
    for i, bi in enumerate(bands):
        c, w = float(bi.center_nm), float(bi.width_nm)
        left, right = max(c - 0.5 * w, lo), min(c + 0.5 * w, hi)
        if right > left and a[i] > 0:
            absorbed[i] = quantum_yield * a[i] * (right - left) * 0.5 * (left + right)
    emitted = np.array([np.mean(chlorophyll_emission(lem, peak_nm, fwhm_nm) / lem)  # per emission band: mean g / lambda
                        for lem in (_band_nodes(float(b.center_nm), float(b.width_nm)) for b in bands)])
    return np.outer(emitted, absorbed)


def chlorophyll_coverage(bands, peak_nm: float = CHL_PEAK_NM, fwhm_nm: float = CHL_FWHM_NM) -> float:
    """The share of the emitted photons whose wavelengths lie inside the scene's bands."""
    grid = np.linspace(peak_nm - CHL_REACH * fwhm_nm, peak_nm + CHL_REACH * fwhm_nm, 4001)
    inside = _inside(grid, bands)
    g = chlorophyll_emission(grid, peak_nm, fwhm_nm)
    return float(np.trapz(g * inside, grid) / np.trapz(g, grid))


# ---- CDOM fluorescence -----------------------------------------------------------------------
#
# Coloured dissolved organic matter re-emits a small share of the light it absorbs, isotropically
# and broadly, red of the excitation. The spectral fluorescence quantum efficiency eta(l', l)
# (photons emitted per nm at l per photon absorbed at l') is Hawes' (1992) fit for fulvic acid
# FA7, as HydroLight uses it (Mobley 1994, "Light and Water", 5.14, Fig. 5.11):
#   eta = A0(l') exp(-[(1/l - A1/l' - B1) / (0.6 (A2/l' + B2))]^2),
# a Gaussian in wavenumber whose centre and width follow the excitation, with A0 tabulated from
# 310 to 490 nm (Hawes' Table 3) and tapered to 0 at 550 nm as HydroLight does. Like HydroLight,
# the Gaussian is not cut at l = l' (its blue tail is a few % of the light). The quantum yield,
# int eta dl, is 0.9-1.9 % over 310-490 nm (0 from 550 nm).

HAWES_EXCITATION_NM = np.arange(310.0, 551.0, 20.0)
HAWES_A0 = 1e-5 * np.array([5.18, 6.34, 8.00, 9.89, 9.39, 10.48, 12.59, 13.48, 13.61, 9.27, 4.00, 1.00, 0.0])  # nm^-1
HAWES_A1, HAWES_A2 = 0.470, 0.407    # dimensionless
HAWES_B1, HAWES_B2 = 8.077e-4, -4.57e-4  # nm^-1


def cdom_efficiency(excitation_nm, emission_nm) -> np.ndarray:
    """eta(l' -> l) (nm^-1): the photons emitted per nm at ``emission_nm`` per photon the CDOM
    absorbs at ``excitation_nm`` (0 outside 310-550 nm excitation)."""
    lx = np.asarray(excitation_nm, float)
    lm = np.asarray(emission_nm, float)
    a0 = np.interp(lx, HAWES_EXCITATION_NM, HAWES_A0, left=0.0, right=0.0)
    z = (1.0 / lm - HAWES_A1 / lx - HAWES_B1) / (0.6 * (HAWES_A2 / lx + HAWES_B2))
    return a0 * np.exp(-z * z)


def cdom_quantum_yield(excitation_nm) -> np.ndarray:
    """int eta(l' -> l) dl over all emission wavelengths: photons emitted per photon absorbed."""
    lx = np.atleast_1d(np.asarray(excitation_nm, float))
    nu = np.linspace(1.0 / 2000.0, 1.0 / 200.0, 20001)  # in wavenumber: d l = d nu / nu^2
    eta = cdom_efficiency(lx[:, None], 1.0 / nu[None, :])
    out = np.trapz(eta / nu ** 2, nu, axis=1)
    return out if np.ndim(excitation_nm) else float(out[0])


def cdom_coupling(bands, absorption, efficiency_scale: float = 1.0) -> np.ndarray:
    """(nb, nb) coupling [emission j, excitation i] (m^-1), or (layers, nb, nb) for one
    absorption spectrum per layer, as ``chlorophyll_coupling``'s: s a_CDOM[i] int over band i of
    eta(l' -> l) l' / l dl', averaged over l in band j (isotropic phase function)."""
    a = np.asarray(absorption, float)
    if a.ndim == 2:
        return np.stack([cdom_coupling(bands, row, efficiency_scale) for row in a])
    return efficiency_scale * a[None, :] * _cdom_shape(_key(bands))


@functools.lru_cache(maxsize=64)
def _cdom_shape(bands: tuple) -> np.ndarray:  # int over band i of eta l' / l dl', mean over band j
    nodes = [_band_nodes(c, w) for c, w in bands]
    m = np.zeros((len(bands), len(bands)))
    for i, ((_, wi), lex) in enumerate(zip(bands, nodes)):
        if not np.any(np.interp(lex, HAWES_EXCITATION_NM, HAWES_A0, left=0.0, right=0.0) > 0):
            continue
        for j, lem in enumerate(nodes):
            eta = cdom_efficiency(lex[None, :], lem[:, None]) * lex[None, :] / lem[:, None]
            m[j, i] = float(np.mean(eta.sum(axis=1))) * wi / _NODES
    return m


def cdom_coverage(bands, absorption) -> float:
    """The share of the photons the CDOM emits (for light flat in wavelength over the bands
    that excite it, weighted by ``absorption``) whose wavelengths lie inside the bands."""
    a = np.asarray(absorption, float)
    a = a.mean(axis=0) if a.ndim == 2 else a
    grid = np.linspace(250.0, 1200.0, 3801)
    inside = _inside(grid, bands)
    emitted = np.zeros_like(grid)
    for ai, b in zip(a, bands):
        if ai > 0:
            lex = _band_nodes(float(b.center_nm), float(b.width_nm))
            emitted += ai * float(b.width_nm) * cdom_efficiency(lex[None, :], grid[:, None]).mean(axis=1)
    total = np.trapz(emitted, grid)
    return float(np.trapz(emitted * inside, grid) / total) if total > 0 else 1.0


KIND_RAMAN, KIND_CHLOROPHYLL, KIND_CDOM = 0, 1, 2  # the core's InelasticKind
KIND_NAMES = {KIND_RAMAN: "Raman", KIND_CHLOROPHYLL: "chlorophyll", KIND_CDOM: "CDOM"}  # (in messages)


def water_processes(scene, water) -> list[tuple[int, np.ndarray, float]]:
    """The inelastic processes of a water body for the core (Scene.set_water_inelastic):
    (kind, coupling over all the scene's bands, phase rho): Raman scattering (with
    raman_active), chlorophyll fluorescence (``fluorescence``), CDOM fluorescence
    (``cdom_fluorescence``)."""
    out = []
    if raman_active(scene):
        out.append((KIND_RAMAN, raman_coupling(scene.bands), RAMAN_RHO))
    f = getattr(water, "fluorescence", None)
    if f is not None:
        out.append((KIND_CHLOROPHYLL, chlorophyll_coupling(scene.bands, f.absorption, f.quantum_yield,
                                                           f.peak_nm, f.fwhm_nm), 0.0))
    f = getattr(water, "cdom_fluorescence", None)
    if f is not None:
        out.append((KIND_CDOM, cdom_coupling(scene.bands, f.absorption, f.efficiency_scale), 0.0))
    return out
