"""Closed forms and one-dimensional quadratures used as references by the statistical tests."""
import numpy as np

from photic import _core
from photic.colour import trapezoid


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
    return 2 * np.pi * trapezoid(f, mu)


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
    integral = trapezoid(trapezoid(f, ph, axis=1), r)
    return e_sun / (np.pi * np.sin(a) ** 2) * integral


def fresnel_unpolarized(cos_i, n1, n2):
    """Unpolarised Fresnel reflectance (numpy, vectorised) for light arriving at cosine cos_i
    in a medium of index n1 on one of index n2; 1 beyond the critical angle."""
    ci = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    s2 = (n1 / n2) ** 2 * (1.0 - ci ** 2)
    ct = np.sqrt(np.clip(1.0 - s2, 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
        rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
        r = 0.5 * (rs ** 2 + rp ** 2)
    return np.where(s2 >= 1.0, 1.0, np.nan_to_num(r, nan=1.0))


class FloorCase:
    """Closed form of the light field above a Lambertian floor under a flat sea, b = 0.

    Water of absorption a and index n over a floor of reflectance R at depth H; a black or
    uniform sky (radiance L_sky) and a sun of irradiance E_sun (on a plane normal to it), a
    disk of uniform radiance L_s = E_sun / (pi sin^2 alpha) of angular radius alpha. The light
    reaching the floor straight from the surface (E_0) is reflected as L_f = R E_floor / pi;
    the surface reflects a part of it back down (Fresnel, total internal reflection beyond the
    critical angle), which reaches the floor again, and so on:

        E_floor = E_0 / (1 - R r),  r = int_0^1 2 R_F(mu) exp(-2 a H / mu) mu dmu.

    At height h above the floor the radiance travelling down at cosine mu (looking up) is the
    sky through Snell's window, n^2 T_F L_sky exp(-a (H - h) / mu), plus the floor's light
    reflected by the surface, L_f R_F(mu) exp(-a (2 H - h) / mu), plus the refracted sun's
    disk; travelling up (looking down) it is L_f exp(-a h / mu). Each radiometer quantity is an
    integral of these over directions, computed here by quadrature. Everything is derived from
    this description, not fitted to any render.
    """

    def __init__(self, R, a, H, h, zenith_deg=0.0, e_sun=1.0, sun_diameter_deg=0.53, l_sky=0.0, n=1.34,
                 npts=200001):
        self.R, self.a, self.H, self.h, self.n, self.l_sky = R, a, H, h, n, l_sky
        self.mu = np.linspace(0.0, 1.0, npts)[1:]  # cosines in water (0 excluded: weight 0)
        self._disk(zenith_deg, e_sun, sun_diameter_deg)
        e0 = self.sky_down(self.H, lambda m: m) + self.sun_down(self.H, lambda m: m)
        r_eff = self._int(2 * self.rf(self.mu) * np.exp(-2 * a * H / self.mu) * self.mu)
        self.e_floor = e0 / (1.0 - R * r_eff)
        self.l_floor = R * self.e_floor / np.pi

    # --- pieces ---------------------------------------------------------------------------
    def _int(self, f):
        return trapezoid(np.concatenate([[0.0], f]), np.concatenate([[0.0], self.mu]))

    def rf(self, mu_w):
        """Reflectance of the surface seen from below at in-water cosine mu_w."""
        return fresnel_unpolarized(mu_w, self.n, 1.0)

    def mu_air(self, mu_w):
        return np.sqrt(np.clip(1.0 - self.n ** 2 * (1.0 - np.asarray(mu_w) ** 2), 0.0, None))

    def _disk(self, zenith_deg, e_sun, diameter_deg, nr=400, nphi=400):
        """Quadrature nodes of the sun's disk: in-water cosines and weights L_s T mu_a / mu_w
        dOmega_a, so that sum(w W(mu_w) exp(-a l / mu_w)) is the direct light's integral."""
        alpha = np.radians(diameter_deg) / 2
        if e_sun == 0.0:
            self.sun_mu_w, self.sun_w = np.zeros(0), np.zeros(0)
            return
        l_s = e_sun / (np.pi * np.sin(alpha) ** 2)
        # Midpoint nodes in (1 - cos rho) (uniform in solid angle) and azimuth around the centre.
        x = (np.arange(nr) + 0.5) / nr * (1 - np.cos(alpha))
        rho = np.arccos(1 - x)
        phi = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
        RHO, PHI = np.meshgrid(rho, phi, indexing="ij")
        th0 = np.radians(zenith_deg)
        mu_a = np.cos(th0) * np.cos(RHO) + np.sin(th0) * np.sin(RHO) * np.cos(PHI)
        d_omega = (1 - np.cos(alpha)) / nr * 2 * np.pi / nphi
        mu_a = mu_a.ravel()
        keep = mu_a > 0
        mu_a = mu_a[keep]
        mu_w = np.sqrt(1 - (1 - mu_a ** 2) / self.n ** 2)
        t = 1 - fresnel_unpolarized(mu_a, 1.0, self.n)
        self.sun_mu_w = mu_w
        self.sun_w = l_s * t * mu_a / mu_w * d_omega

    def sun_down(self, path_depth, W):
        """Direct sun at a depth `path_depth` below the surface, weighted by W(mu_w)."""
        return float(np.sum(self.sun_w * W(self.sun_mu_w) * np.exp(-self.a * path_depth / self.sun_mu_w)))

    def sky_down(self, path_depth, W, mu_lo=0.0, mu_hi=1.0):
        """2 pi int W(mu) L_sky,w(mu) dmu over [mu_lo, mu_hi]: the sky through Snell's window."""
        if self.l_sky == 0.0:
            return 0.0
        mu = self.mu
        t = 1 - fresnel_unpolarized(self.mu_air(mu), 1.0, self.n)
        inside = (self.mu_air(mu) > 0) & (mu >= mu_lo) & (mu <= mu_hi)
        f = np.where(inside, self.n ** 2 * t * self.l_sky * np.exp(-self.a * path_depth / mu), 0.0) * W(mu)
        return 2 * np.pi * self._int(f)

    def l_down(self, mu):
        """Diffuse radiance travelling down at the sensor (looking up at cosine mu)."""
        mu = np.asarray(mu, float)
        sky = np.where(self.mu_air(mu) > 0, self.n ** 2 * (1 - fresnel_unpolarized(self.mu_air(mu), 1.0, self.n))
                       * self.l_sky * np.exp(-self.a * (self.H - self.h) / mu), 0.0)
        return sky + self.l_floor * self.rf(mu) * np.exp(-self.a * (2 * self.H - self.h) / mu)

    def l_up(self, mu):
        """Radiance travelling up at the sensor (looking down at cosine mu)."""
        return self.l_floor * np.exp(-self.a * self.h / np.asarray(mu, float))

    # --- radiometer quantities --------------------------------------------------------------
    def irradiance(self, quantity, direct=True):
        """Ed, Eu, Eo, Eod or Eou at the sensor (direct=False: without the sun's disk)."""
        mu, ld, lu = self.mu, self.l_down(self.mu), self.l_up(self.mu)
        sun = lambda W: self.sun_down(self.H - self.h, W) if direct else 0.0
        one = lambda m: np.ones_like(m)
        down = {"Ed": 2 * np.pi * self._int(ld * mu) + sun(lambda m: m),
                "Eod": 2 * np.pi * self._int(ld) + sun(one)}
        up = {"Eu": 2 * np.pi * self._int(lu * mu), "Eou": 2 * np.pi * self._int(lu)}
        if quantity == "Eo":
            return down["Eod"] + up["Eou"]
        return {**down, **up}[quantity]

    @staticmethod
    def _mean_over(L, lo, hi, npts=20001):
        """Mean of L(mu) over mu in [lo, hi] (uniform in solid angle), on nodes of its own: a
        mask on the shared grid cut the interval's ends by up to half a step (0.07 % of a 5 deg
        cap's mean, 0.3 % of a 2 deg cap's)."""
        mu = np.linspace(lo, hi, npts)
        return trapezoid(L(mu), mu) / (hi - lo)

    def radiance_cap(self, looking_up, half_angle_deg):
        """Radiance averaged over a polar cap of looking directions around the zenith
        (looking_up) or the nadir; the sun's disk is not included (keep it outside the cap)."""
        c = np.cos(np.radians(half_angle_deg))
        return self._mean_over(self.l_down if looking_up else self.l_up, c, 1.0)

    def radiance_bin(self, mu_lo, mu_hi):
        """Radiance averaged over looking directions with cos(polar angle from +z) in
        [mu_lo, mu_hi] (one side of the horizon), the sun's disk not included."""
        up = mu_lo >= 0
        lo, hi = (mu_lo, mu_hi) if up else (-mu_hi, -mu_lo)
        return self._mean_over(self.l_down if up else self.l_up, max(lo, 1e-12), hi)

    def sun_in_bin(self, mu_lo, mu_hi):
        """Whether any direction of the refracted sun's disk looks into [mu_lo, mu_hi]."""
        return bool(np.any((self.sun_mu_w >= mu_lo) & (self.sun_mu_w <= mu_hi)))

    def air_radiance_down(self, half_angle_deg):
        """Radiance looking down from the air just above the surface, averaged over a cap of
        looking directions around the nadir: the floor's light transmitted (n^-2 law) and the
        uniform sky reflected; the sun's glint is not included (keep it outside the cap)."""
        c = np.cos(np.radians(half_angle_deg))

        def L(mu_a):
            mu_w = np.sqrt(1 - (1 - mu_a ** 2) / self.n ** 2)
            t = 1 - fresnel_unpolarized(mu_a, 1.0, self.n)
            up = self.l_floor * np.exp(-self.a * self.H / mu_w)
            return t * up / self.n ** 2 + fresnel_unpolarized(mu_a, 1.0, self.n) * self.l_sky
        return self._mean_over(L, c, 1.0)


# Six 90-degree perspective cameras that together see every direction once: (forward, up).
CUBE_FACES = (((1, 0, 0), (0, 0, 1)), ((-1, 0, 0), (0, 0, 1)), ((0, 1, 0), (0, 0, 1)),
              ((0, -1, 0), (0, 0, 1)), ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0)))


def cube_cameras(position, resolution, prefix="cube"):
    """Scene-file cameras of a cube map at `position` (square images, box filter)."""
    return [{"name": f"{prefix}{i}", "type": "perspective", "position": list(position), "direction": list(f),
             "up": list(u), "fov_deg": 90.0, "resolution": [resolution, resolution]}
            for i, (f, u) in enumerate(CUBE_FACES)]


def pixel_integrals(forward, up, fov_deg, resolution, functions, sub=8):
    """For a square perspective camera (box filter) looking along `forward`, the integral over
    each pixel's solid angle of each of `functions` (each maps unit look directions (..., 3) to
    weights), by sub x sub midpoint nodes in the image plane (dOmega = dA / |x|^3 for a plane at
    distance 1). A pixel's value is the image-plane average of the radiance over it, so the sum
    over pixels of value x integral(g) estimates int L g dOmega to second order in the pixel
    size, also where L or g jump. Returns one (res, res) array per function."""
    n = resolution
    f = np.asarray(forward, float) / np.linalg.norm(forward)
    right = np.cross(f, np.asarray(up, float))
    right /= np.linalg.norm(right)
    upv = np.cross(right, f)
    tan_half = np.tan(np.radians(fov_deg) / 2)
    # Pixel (row, col): image x = 2 (col + s) / n - 1 to the right, y = 1 - 2 (row + t) / n up.
    s = (np.arange(sub) + 0.5) / sub
    c = (np.arange(n)[:, None] + s[None, :]).ravel()
    X, Y = np.meshgrid((2 * c / n - 1) * tan_half, (1 - 2 * c / n) * tan_half, indexing="xy")
    v = f + X[..., None] * right + Y[..., None] * upv
    r = np.linalg.norm(v, axis=-1)
    jac = (2 * tan_half / (n * sub)) ** 2 / r ** 3
    d = v / r[..., None]
    return [(g(d) * jac).reshape(n, sub, n, sub).sum(axis=(1, 3)) for g in functions]


def cube_pixel_integrals(resolution, functions, sub=8):
    """pixel_integrals for the six faces of cube_cameras: one (6, res, res) array per function."""
    faces = [pixel_integrals(f, u, 90.0, resolution, functions, sub) for f, u in CUBE_FACES]
    return [np.stack([face[gi] for face in faces]) for gi in range(len(functions))]


def cube_estimate(images, weights, band=0):
    """sum over faces and pixels of image x weight, and its standard error (pixels
    independent): images is the list of six ImageResults in CUBE_FACES order."""
    value, var = 0.0, 0.0
    for fi, img in enumerate(images):
        value += float(np.sum(img.mean[..., band] * weights[fi]))
        var += float(np.sum(img.variance[..., band] * weights[fi] ** 2))
    return value, np.sqrt(var)
