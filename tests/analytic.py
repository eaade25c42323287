"""Closed forms and one-dimensional quadratures used as references by the statistical tests."""
import numpy as np

from photic import _core


def transmitted_uniform_sky(depth, a, n=1.34, sky_radiance=1.0, weight="Ed", mu_min=None, npts=200001):
    """Ed or Eo at `depth` below a flat surface under a uniform sky, water with b = 0.

    In-water radiance inside Snell's window (cosine mu_w >= mu_c) is n^2 T_F L_sky; outside it
    the view sees total internal reflection of upwelling light, zero here. Each direction is
    attenuated by exp(-a z / mu_w).
    """
    mu_c = np.sqrt(1 - 1 / n**2)
    lo = mu_c if mu_min is None else max(mu_c, mu_min)
    mu = np.linspace(lo, 1.0, npts)
    T = 1 - np.array([_core.fresnel(m, n, 1.0) for m in mu]) if npts <= 5001 else \
        1 - np.vectorize(lambda m: _core.fresnel(m, n, 1.0))(mu)
    L = n**2 * T * sky_radiance * np.exp(-a * depth / mu)
    f = {"Ed": L * mu, "Eo": L, "L": L}[weight]
    return 2 * np.pi * np.trapz(f, mu)


def simpson(y, h):
    """Composite Simpson rule on an odd number of equally spaced values."""
    y = np.asarray(y)
    return h / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())


def sun_disk_planar_irradiance(zenith_deg, e_sun=1.0, diameter_deg=0.53, n=2001):
    """Irradiance on a horizontal plane from a uniform sun disk, sun directions below the
    horizon not counted: E_sun / (pi sin^2 a) * int_disk max(0, cos theta) dw (quadrature)."""
    a = np.radians(diameter_deg) / 2
    th0 = np.radians(zenith_deg)
    r = np.linspace(0, a, n)              # angle from the disk centre
    ph = np.linspace(0, 2 * np.pi, n)
    R, P = np.meshgrid(r, ph, indexing="ij")
    # cos(zenith) of a direction at angle R from the centre, azimuth P around it.
    cz = np.cos(th0) * np.cos(R) + np.sin(th0) * np.sin(R) * np.cos(P)
    f = np.maximum(cz, 0) * np.sin(R)
    integral = np.trapz(np.trapz(f, ph, axis=1), r)
    return e_sun / (np.pi * np.sin(a) ** 2) * integral
