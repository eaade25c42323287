"""The rough sea surface: Cox-Munk slope statistics, the 6S sun-glint closed form, Fresnel, and
the compiled rough air-water interface BSDF (``photic._core.RoughInterface``).

Conventions (see ``engine/src/core/rough_interface.h`` and docs/physics.md, "Rough air-water
interface"): the macro normal is +z, air above and water below, directions point away from
the surface; ``eval(wi, wo)`` is the BSDF in 1/sr without the cosine, ``sample`` returns
``weight = f |wo_z| / pdf``; ``mode="radiance"`` (camera paths, the default) or
``"importance"`` (light tracing).

Slope variances: Cox & Munk (1954) give the mean-square slope ``sigma^2 = 0.003 + 5.12e-3 U``
(isotropic, sum of both axes) and per-axis ``sigma_c^2 = 0.003 + 1.92e-3 U`` (crosswind),
``sigma_u^2 = 3.16e-3 U`` (upwind); U in m/s at 12.5 m.

``python -m photic.surface [PATH]`` writes the plot of directional-hemispherical reflectance
against incidence angle (default ``docs/images/rough_interface_reflectance.png``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

N_WATER = 1.34  # relative index n_water / n_air used for the sea surface
MIN_VARIANCE = 1e-6  # floor of a sub-pixel per-axis slope variance


def cox_munk_variance(U, anisotropic: bool = False):
    """Cox-Munk slope variance for wind speed U (m/s, at 12.5 m).

    Isotropic: the total mean-square slope ``0.003 + 5.12e-3 U`` (each axis holds half).
    Anisotropic: the per-axis pair ``(sigma_u^2, sigma_c^2) = (3.16e-3 U, 0.003 + 1.92e-3 U)``.
    """
    U = np.asarray(U, float)
    if np.any(U < 0):
        raise ValueError("cox_munk_variance: wind speed U must be >= 0 m/s")
    if anisotropic:
        return 3.16e-3 * U, 0.003 + 1.92e-3 * U
    return 0.003 + 5.12e-3 * U


def slope_variances(U, anisotropic: bool = True, resolved=(0.0, 0.0),
                    min_variance: float = MIN_VARIANCE) -> tuple[float, float]:
    """Per-axis (upwind, crosswind) slope variances of the sub-pixel roughness: Cox-Munk less
    the per-axis variance ``resolved`` by a wave height field, at least ``min_variance``."""
    if anisotropic:
        s2u, s2c = cox_munk_variance(U, True)
    else:
        s2u = s2c = 0.5 * cox_munk_variance(U, False)
    return (float(max(min_variance, s2u - resolved[0])), float(max(min_variance, s2c - resolved[1])))


def rough_interface(U, anisotropic: bool = True, wind_azimuth: float = 0.0, eta: float = N_WATER,
                    resolved=(0.0, 0.0), min_variance: float = MIN_VARIANCE):
    """The compiled BSDF for wind speed U (m/s); ``wind_azimuth`` (rad from +x) is the upwind axis."""
    from . import _core
    s2u, s2c = slope_variances(U, anisotropic, resolved, min_variance)
    return _core.RoughInterface(s2u, s2c, wind_azimuth, eta)


def fresnel(cos_i, n1: float = 1.0, n2: float = N_WATER):
    """Unpolarised Fresnel reflectance for light in medium n1 at cosine ``cos_i`` onto n2
    (1 beyond the critical angle); vectorised."""
    c = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    eta = n1 / n2
    sin2_t = eta * eta * (1.0 - c * c)
    tir = sin2_t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    with np.errstate(invalid="ignore", divide="ignore"):  # 0/0 only where TIR applies
        rs = (n1 * c - n2 * ct) / (n1 * c + n2 * ct)
        rp = (n2 * c - n1 * ct) / (n2 * c + n1 * ct)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))


def glint_reflectance(theta_s, theta_v, phi, U, eta: float = N_WATER, anisotropic: bool = False,
                      wind_azimuth: float = 0.0):
    """Cox-Munk sun-glint reflectance factor (6S form, no shadowing)
    ``rho = pi R_F(chi) p(z) / (4 cos(theta_s) cos(theta_v) cos^4(beta))``.

    theta_s, theta_v: sun and view zenith angles (rad); phi: azimuth of the view direction
    minus that of the sun direction, both seen from the surface (phi = pi is the specular
    plane, where the glint is). beta is the tilt of the facet that reflects the sun into the
    view, chi half the scattering angle. p is the isotropic Gaussian of ``cox_munk_variance``
    or, if ``anisotropic``, the anisotropic one with the upwind axis at ``wind_azimuth`` from
    the sun's azimuth (no Gram-Charlier terms). Equal to pi f_r / G of RoughInterface.
    """
    ts, tv, ph = np.broadcast_arrays(*(np.asarray(a, float) for a in (theta_s, theta_v, phi)))
    s = np.stack([np.sin(ts), np.zeros_like(ts), np.cos(ts)], -1)
    v = np.stack([np.sin(tv) * np.cos(ph), np.sin(tv) * np.sin(ph), np.cos(tv)], -1)
    h = s + v
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    zx, zy = -h[..., 0] / h[..., 2], -h[..., 1] / h[..., 2]
    if anisotropic:
        s2u, s2c = cox_munk_variance(U, True)
        zu = zx * np.cos(wind_azimuth) + zy * np.sin(wind_azimuth)
        zc = -zx * np.sin(wind_azimuth) + zy * np.cos(wind_azimuth)
        p = np.exp(-0.5 * (zu * zu / s2u + zc * zc / s2c)) / (2 * np.pi * np.sqrt(s2u * s2c))
    else:
        s2 = cox_munk_variance(U, False)
        p = np.exp(-(zx * zx + zy * zy) / s2) / (np.pi * s2)
    rf = fresnel(np.sum(s * h, -1), 1.0, eta)
    cos_beta = h[..., 2]
    return np.pi * rf * p / (4 * np.cos(ts) * np.cos(tv) * cos_beta ** 4)


# --- Quadrature over a hemisphere, fine around a lobe ----------------------------------------

def lobe_grid(theta_c: float, width: float, n_theta: int = 45, n_phi: int = 32, n_fine: int = 24):
    """Bin edges (polar angle from the hemisphere's pole, azimuth relative to the lobe's) for
    a lobe centred at polar angle ``theta_c`` with angular half-width ``width``: a uniform grid
    joined with edges at ``theta_c +- width x`` (``n_fine`` values of x log-spaced from 1e-3
    to 1, likewise in azimuth), so that lobes much narrower than ``width`` (a transmitted
    lobe) are resolved too. The horizon is a bin edge."""
    half = np.pi / 2
    off = np.concatenate([[0.0], np.geomspace(1e-3, 1.0, n_fine)])
    off = np.concatenate([-off[::-1], off])
    te = np.concatenate([np.linspace(0.0, half, n_theta + 1), np.clip(theta_c + width * off, 0.0, half)])
    pw = min(np.pi, width / max(np.sin(theta_c), width))
    pe = np.concatenate([np.linspace(-np.pi, np.pi, n_phi + 1), pw * off])
    return _merge(te), _merge(pe)


def _merge(edges):
    e = np.unique(edges)
    return e[np.concatenate([[True], np.diff(e) > 1e-9])]


def hemisphere_quadrature(theta_edges, phi_edges, upper: bool, phi_c: float, sub: int = 2, order: int = 3):
    """Gauss-Legendre nodes (``sub x sub`` cells of ``order x order`` per bin) on the upper
    (+z) or lower hemisphere; azimuths relative to ``phi_c``. Returns (directions (M, 3),
    solid-angle weights (M,), bin index (M,)) with bin = i_theta * (len(phi_edges) - 1) + i_phi."""
    g, gw = np.polynomial.legendre.leggauss(order)
    unit = ((np.arange(sub)[:, None] + 0.5 * (g[None, :] + 1)) / sub).ravel()
    unit_w = np.tile(gw / (2 * sub), sub)
    th = theta_edges[:-1, None] + np.diff(theta_edges)[:, None] * unit           # (nt, q)
    thw = np.diff(theta_edges)[:, None] * unit_w * np.sin(th)
    ph = phi_edges[:-1, None] + np.diff(phi_edges)[:, None] * unit               # (np, q)
    phw = np.diff(phi_edges)[:, None] * unit_w
    nt, npb, q = th.shape[0], ph.shape[0], unit.size
    TH = np.broadcast_to(th[:, None, :, None], (nt, npb, q, q))
    PH = np.broadcast_to(ph[None, :, None, :] + phi_c, (nt, npb, q, q))
    W = thw[:, None, :, None] * phw[None, :, None, :]
    st = np.sin(TH)
    d = np.stack([st * np.cos(PH), st * np.sin(PH), (1.0 if upper else -1.0) * np.cos(TH)], -1)
    idx = np.broadcast_to((np.arange(nt)[:, None] * npb + np.arange(npb)[None, :])[:, :, None, None],
                          (nt, npb, q, q))
    return d.reshape(-1, 3), W.ravel(), idx.ravel()


def hemisphere_bin(directions, theta_edges, phi_edges, phi_c: float):
    """Bin index (as in ``hemisphere_quadrature``) of each direction, on either hemisphere."""
    d = np.asarray(directions, float)
    theta = np.arctan2(np.hypot(d[:, 0], d[:, 1]), np.abs(d[:, 2]))
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]) - phi_c + np.pi, 2 * np.pi) - np.pi
    it = np.clip(np.searchsorted(theta_edges, theta, side="right") - 1, 0, len(theta_edges) - 2)
    ip = np.clip(np.searchsorted(phi_edges, phi, side="right") - 1, 0, len(phi_edges) - 2)
    return it * (len(phi_edges) - 1) + ip


def lobe_centres(wi, eta: float = N_WATER):
    """Polar angles (from each hemisphere's pole) and azimuth of the reflection and the
    transmission lobe: the mirror direction and the refracted one (the horizon past the
    critical angle); both lie at the azimuth opposite to wi's."""
    wi = np.asarray(wi, float)
    n1, n2 = (1.0, eta) if wi[2] > 0 else (eta, 1.0)
    sin_i = np.hypot(wi[0], wi[1])
    theta_r = np.arctan2(sin_i, abs(wi[2]))
    theta_t = np.arcsin(min(1.0, sin_i * n1 / n2))
    phi_c = np.arctan2(-wi[1], -wi[0]) if sin_i > 0 else 0.0
    return theta_r, theta_t, phi_c


def lobe_width(iface) -> float:
    """Angular half-width (rad) of the fine part of the quadrature grids: 12 slope deviations."""
    return float(min(np.pi / 2, 12 * np.sqrt(max(iface.sigma2_up, iface.sigma2_cross))))


def directional_albedo(iface, wi, mode: str = "importance", n_theta: int = 45, n_phi: int = 32,
                       n_fine: int = 24, sub: int = 1, order: int = 4) -> tuple[float, float]:
    """(R, T): integrals of ``eval(wi, wo) |wo_z|`` over the reflected and the transmitted
    hemisphere by Gauss-Legendre quadrature on grids refined around the two lobes. With mode
    "importance" these are the fractions of the flux arriving from wi that are reflected and
    transmitted (directional-hemispherical reflectance and transmittance)."""
    wi = np.asarray(wi, float)
    theta_r, theta_t, phi_c = lobe_centres(wi, iface.eta)
    width = lobe_width(iface)
    out = []
    for theta_c, same_side in ((theta_r, True), (theta_t, False)):
        te, pe = lobe_grid(theta_c, width, n_theta, n_phi, n_fine)
        d, w, _ = hemisphere_quadrature(te, pe, (wi[2] > 0) == same_side, phi_c, sub, order)
        out.append(float(np.sum(iface.eval(wi, d, mode) * np.abs(d[:, 2]) * w)))
    return out[0], out[1]


# --- The reflectance plot ---------------------------------------------------------------------

DEFAULT_PLOT = Path("docs") / "images" / "rough_interface_reflectance.png"
WIND_COLORS = {2.0: (40, 110, 200), 7.0: (30, 150, 60), 15.0: (200, 60, 40)}


def reflectance_curves(winds=(2.0, 7.0, 15.0), angles_deg=None, eta: float = N_WATER):
    """Directional-hemispherical reflectance R(theta) from air and from water for isotropic
    Cox-Munk roughness at each wind speed, plus Fresnel. Returns a dict of arrays."""
    if angles_deg is None:
        angles_deg = np.concatenate([np.arange(0.0, 40.0, 5.0), np.arange(40.0, 89.5, 1.5), [89.0]])
    fine = np.linspace(0.0, 89.0, 357)
    res = {"angles": angles_deg, "fresnel_angles": fine,
           "fresnel_air": fresnel(np.cos(np.radians(fine)), 1.0, eta),
           "fresnel_water": fresnel(np.cos(np.radians(fine)), eta, 1.0)}
    for U in winds:
        iface = rough_interface(U, anisotropic=False, eta=eta)
        for side, sign in (("air", 1.0), ("water", -1.0)):
            R = []
            for a in np.radians(angles_deg):
                R.append(directional_albedo(iface, [np.sin(a), 0.0, sign * np.cos(a)])[0])
            res[f"{side}_{U:g}"] = np.array(R)
    return res


def plot_reflectance(path: str | Path = DEFAULT_PLOT, winds=(2.0, 7.0, 15.0)) -> Path:
    from .plots import linear_panels, save_figure
    c = reflectance_curves(winds)
    panels = []
    for side, title, fres in (("air", "from air", "fresnel_air"), ("water", "from water", "fresnel_water")):
        series = [("Fresnel (flat)", c["fresnel_angles"], c[fres], (0, 0, 0))]
        series += [(f"U = {U:g} m/s", c["angles"], c[f"{side}_{U:g}"], WIND_COLORS.get(U, (120, 0, 160)))
                   for U in winds]
        panels.append({"title": f"Rough interface reflectance, {title}", "xlabel": "incidence (deg)",
                       "ylabel": "R", "series": series, "xlim": (0, 90), "ylim": (0, 1),
                       "xticks": list(range(0, 91, 15)), "yticks": [0, 0.2, 0.4, 0.6, 0.8, 1.0],
                       "legend": True})
    return save_figure(linear_panels(panels, size=(520, 400)), path)


if __name__ == "__main__":
    print(plot_reflectance(sys.argv[1] if len(sys.argv) > 1 else DEFAULT_PLOT))
