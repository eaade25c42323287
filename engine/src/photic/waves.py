"""Wave models: periodic sea-surface height fields from ocean wave spectra (Tessendorf 2001).

A :class:`WaveModel` describes a sea state (a spectrum, wind, directional spreading) and the
periodic patch it is sampled on. :func:`generate` turns it into one realisation on an
``Nx x Ny`` grid: heights, exact spectral slopes, optional choppy displacement and the unit
normals. :func:`patch_mesh` makes the triangle patch an ocean ``surface`` of kind ``"patch"``
needs (the scene format's ``"waves"`` surface does this at load time).

Conventions: lengths in m, times in s, angles in degrees unless a name says ``_rad``,
directions in the xy-plane measured from +x towards +y (like the sun's azimuth), z up.
Gravity ``G`` = 9.80665 m s^-2.

Spectra (all one-sided frequency spectra ``S(omega)`` in m^2 s, with ``omega`` in rad/s):

- ``"pierson_moskowitz"``: ``S = alpha g^2 omega^-5 exp(-beta (omega_0 / omega)^4)``,
  ``alpha = 8.1e-3``, ``beta = 0.74``, ``omega_0 = g / U_19.5`` (Pierson & Moskowitz 1964).
  ``U_19.5`` is the wind at 19.5 m, taken as ``1.026 U_10`` (Stewart, *Introduction to
  Physical Oceanography*, 2008, sec. 16.5, drag coefficient 1.3e-3). It integrates to
  ``Hs = 4 sqrt(m0) = 2 sqrt(alpha / beta) U_19.5^2 / g = 0.209 U_19.5^2 / g`` (the published
  ``Hs ~ 0.21 U_19.5^2 / g``) with the peak at ``omega_p = (4 beta / 5)^(1/4) g / U_19.5 =
  0.877 g / U_19.5``.
- ``"jonswap"`` (Hasselmann et al. 1973): ``S = alpha g^2 omega^-5 exp(-5/4 (omega_p /
  omega)^4) gamma^r``, ``r = exp(-(omega - omega_p)^2 / (2 sigma^2 omega_p^2))``,
  ``sigma = 0.07`` (omega <= omega_p) or ``0.09``; fetch-limited ``alpha = 0.076
  (U_10^2 / (F g))^0.22`` and ``omega_p = 22 (g^2 / (U_10 F))^(1/3)`` (as quoted by Stewart
  2008, sec. 16.5). The dimensionless fetch ``g F / U_10^2`` is capped at the fully
  developed value where this ``omega_p`` reaches the Pierson-Moskowitz peak.
- ``"phillips"`` (Phillips 1958 saturation range with Tessendorf's low-wavenumber cut-off
  ``exp(-1/(k L)^2)``, ``L = U_10^2 / g``): ``S = alpha g^2 omega^-5 exp(-(g / (U_10
  omega))^4)``, ``alpha = 8.1e-3``. In deep water its wavenumber spectrum is
  ``(alpha / 2) k^-4 exp(-1/(k L)^2) D(theta)``: Tessendorf's ``A exp(-1/(kL)^2) / k^4``
  with a physical amplitude.
- ``"flat"``: no waves. ``"sinusoids"``: an explicit sum of ``a cos(k.x - omega t + phase)``.

Directional spreading ``D(theta)`` (1/rad, integrates to 1 over the circle), ``theta``
relative to the wind direction: ``"cos2s"`` (default) ``Q(s) |cos(theta / 2)|^(2s)`` with
``Q(s) = Gamma(s + 1) / (2 sqrt(pi) Gamma(s + 1/2))`` (Longuet-Higgins et al. 1963,
Mitsuyasu et al. 1975), ``s = 10`` by default (Goda's s_max for wind waves); ``"cos2"``:
``(2 / pi) cos^2(theta)`` for ``|theta| < 90 deg``, else 0 (Tessendorf's ``|k.w|^2`` without
the waves that travel against the wind).

Spectrum to grid: the directional wavenumber spectrum (m^4) is ``Psi(kx, ky) = S(omega(k))
D(theta) (d omega / dk) / k``, with the dispersion relation ``omega^2 = g k tanh(k D)``
(``D`` the water depth; deep water ``omega^2 = g k``). Each grid wavevector ``k = (2 pi n /
Lx, 2 pi m / Ly)``, ``-N/2 < n, m < N/2`` (the mean and the Nyquist rows and columns are left
out), gets ``h0(k) = (xi_r + i xi_i) sqrt(Psi dkx dky / 4)``, ``xi`` standard normal, and
``h(k, t) = h0(k) exp(-i omega t) + conj(h0(-k)) exp(i omega t)``: a real field whose
components travel along ``+k`` with ``E|h(k)|^2 = (Psi(k) + Psi(-k)) dkx dky / 2``, so that
the expected height variance is ``sum Psi dkx dky`` over the grid (:func:`height_variance`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from functools import lru_cache
from typing import Any

import numpy as np

__all__ = [
    "G", "SPECTRA", "SPREADINGS", "WaveModel", "WaveField", "dispersion", "group_velocity",
    "frequency_spectrum", "spreading_function", "directional_spectrum", "wavenumber_grid",
    "amplitudes", "generate", "evaluate", "height_variance", "slope_variance",
    "resolved_slope_variance", "subpixel_slope_variance", "patch_mesh", "surface_patch",
    "SurfaceFoldsError",
    "WaveNumbersError",
]

#: Standard gravity (m s^-2).
G = 9.80665
#: Spectrum kinds.
SPECTRA = ("flat", "sinusoids", "pierson_moskowitz", "jonswap", "phillips")
#: Directional spreading functions.
SPREADINGS = ("cos2s", "cos2")

PM_ALPHA = 8.1e-3        # Phillips constant of Pierson-Moskowitz (and of "phillips")
PM_BETA = 0.74
U19_5_PER_U10 = 1.026    # Stewart 2008, sec. 16.5


class WaveNumbersError(ValueError):
    """A wave model whose patch is not made of finite numbers (parameters beyond what the
    spectrum's formulas hold)."""


class SurfaceFoldsError(ValueError):
    """The choppy displacement folds the surface over (Jacobian <= 0): no height field."""


@dataclass(frozen=True)
class WaveModel:
    """A sea state and the periodic patch it is sampled on.

    Fields (units in brackets; defaults in parentheses):

    - ``spectrum`` [-] ("pierson_moskowitz"): one of :data:`SPECTRA`.
    - ``wind_speed`` [m/s] (5.0): wind speed U_10 at 10 m above the sea, >= 0 (> 0 for the
      wind-driven spectra). Pierson-Moskowitz uses U_19.5 = 1.026 U_10; JONSWAP's fetch
      relations and Phillips' ``L = U^2/g`` use U_10 itself.
    - ``wind_direction_deg`` [deg] (0): direction the wind blows *towards* (the waves' mean
      direction of travel), from +x towards +y.
    - ``patch_size_m`` [m] ((50, 50)): period (Lx, Ly) of the patch, each > 0.
    - ``resolution`` [-] ((64, 64)): grid points (Nx, Ny), each 2..4096; any size works,
      products of small primes are fastest.
    - ``seed`` [-] (0): seed of the random amplitudes, 0..2^63-1.
    - ``time_s`` [s] (0): time of the realisation; components advance with their own omega.
    - ``choppiness`` [-] (0): lambda of the horizontal displacement ``x + lambda D``; 0 is
      none, ~1 is typical; the surface must not fold (Jacobian > 0).
    - ``water_depth_m`` [m] (None): depth D for the dispersion ``omega^2 = g k tanh(k D)``;
      None is deep water. The spectrum is mapped to wavenumbers with it (no TMA depth
      limitation of the spectrum itself).
    - ``fetch_m`` [m] (None): fetch F of ``"jonswap"`` (required there, not allowed elsewhere).
    - ``gamma`` [-] (3.3): peak enhancement of ``"jonswap"``, >= 1 (1 is the PM shape).
    - ``spreading`` [-] ("cos2s"): one of :data:`SPREADINGS`.
    - ``spreading_s`` [-] (10.0): exponent s of ``"cos2s"``, > 0.
    - ``mesh_refinement`` [-] (1): the patch's triangles are this many times finer than the
      grid, 1..16: the same band-limited surface (the grid's waves, no shorter ones) sampled
      at ``(r Nx) x (r Ny)`` points by its own Fourier series, so that the facets follow the
      curvature of the shortest waves, which the grid samples only 2-4 times per wavelength.
      Caustics below the surface depend on it: Ed at points 5 m below a 20 m, 64 x 64 JONSWAP
      patch (6 m/s, sun 30 deg) differs from the 16x surface's by 49 % RMS at 1x, 11 % at 4x,
      2.5 % at 8x (1 m down: 9.6, 2.6, 1.0 %); the mean over the period does not change.
      Costs r^2 more triangles (docs/physics.md, "Wave patches and caustics").
    - ``sinusoids`` [m, m, deg, rad] (()): for ``"sinusoids"``: (amplitude, wavelength,
      direction of travel, phase) per component, ``h = a cos(k.x - omega t + phase)``. Each
      wavevector must fit the patch a whole number of times in x and y and be resolved by
      the grid (below the Nyquist wavenumber).
    """

    spectrum: str = "pierson_moskowitz"
    wind_speed: float = 5.0
    wind_direction_deg: float = 0.0
    patch_size_m: tuple[float, float] = (50.0, 50.0)
    resolution: tuple[int, int] = (64, 64)
    seed: int = 0
    time_s: float = 0.0
    choppiness: float = 0.0
    water_depth_m: float | None = None
    fetch_m: float | None = None
    gamma: float = 3.3
    spreading: str = "cos2s"
    spreading_s: float = 10.0
    sinusoids: tuple[tuple[float, float, float, float], ...] = ()
    mesh_refinement: int = 1

    def __post_init__(self):
        # Lists become tuples so that the model is hashable (patches are cached by model).
        for name in ("patch_size_m", "resolution"):
            value = getattr(self, name)
            if isinstance(value, (list, np.ndarray)):
                object.__setattr__(self, name, tuple(np.asarray(value).tolist()))
        if isinstance(self.sinusoids, (list, tuple, np.ndarray)):
            try:
                object.__setattr__(self, "sinusoids", tuple(
                    tuple(np.asarray(c, dtype=np.float64).tolist()) for c in self.sinusoids))
            except (TypeError, ValueError):
                pass  # validate() reports it

    def validate(self, obj: str = "wave model", prefix: str = "") -> None:
        """Check every field; raise ``SceneError(obj, prefix + field, ...)`` on the first
        problem (``obj`` e.g. ``"water 'sea'"``, ``prefix`` e.g. ``"surface."``)."""
        from .parameters import check_parameter
        from .scene.checks import SceneError, _check_choice, _check_real, _show

        def check(name, value, fld=None):  # the declared range of surface.<name>
            check_parameter(obj, f"surface.{name}", value, f"{prefix}{fld or name}")

        _check_choice(obj, f"{prefix}spectrum", self.spectrum, SPECTRA)
        check("wind_speed", self.wind_speed)
        if self.spectrum in ("pierson_moskowitz", "jonswap", "phillips") and self.wind_speed == 0:
            raise SceneError(obj, f"{prefix}wind_speed", f"must be > 0 for spectrum "
                                                         f"'{self.spectrum}', got 0")
        _check_real(obj, f"{prefix}wind_direction_deg", self.wind_direction_deg)
        for name in ("patch_size_m", "resolution"):
            value = getattr(self, name)
            if not isinstance(value, tuple) or len(value) != 2:
                raise SceneError(obj, f"{prefix}{name}", f"must be 2 numbers [x, y], got "
                                                         f"{_show(value)}")
            for i, x in enumerate(value):
                check(name, x, f"{name}[{i}]")
        check("seed", self.seed)
        _check_real(obj, f"{prefix}time_s", self.time_s)
        check("choppiness", self.choppiness)
        if self.water_depth_m is not None:
            check("water_depth_m", self.water_depth_m)
        if self.spectrum == "jonswap":
            if self.fetch_m is None:
                raise SceneError(obj, f"{prefix}fetch_m", "required by spectrum 'jonswap' "
                                                          "(fetch in m)")
            check("fetch_m", self.fetch_m)
        elif self.fetch_m is not None:
            raise SceneError(obj, f"{prefix}fetch_m", "only allowed for spectrum 'jonswap'")
        check("gamma", self.gamma)
        _check_choice(obj, f"{prefix}spreading", self.spreading, SPREADINGS)
        check("spreading_s", self.spreading_s)
        check("mesh_refinement", self.mesh_refinement)
        for i, n in enumerate(self.resolution):
            if int(n) * int(self.mesh_refinement) > MAX_MESH_POINTS:
                raise SceneError(obj, f"{prefix}mesh_refinement", f"resolution[{i}] x mesh_refinement is "
                                                                  f"{int(n) * int(self.mesh_refinement)}, more than "
                                                                  f"{MAX_MESH_POINTS} mesh points per side")
        if self.spectrum != "sinusoids":
            if self.sinusoids:
                raise SceneError(obj, f"{prefix}sinusoids", "only allowed for spectrum "
                                                            "'sinusoids'")
            return
        if not isinstance(self.sinusoids, tuple):
            raise SceneError(obj, f"{prefix}sinusoids", f"must be a list of (amplitude, "
                                                        f"wavelength, direction, phase), got "
                                                        f"{_show(self.sinusoids)}")
        for i, comp in enumerate(self.sinusoids):
            where = f"{prefix}sinusoids[{i}]"
            if not isinstance(comp, tuple) or len(comp) != 4:
                raise SceneError(obj, where, f"must be (amplitude_m, wavelength_m, "
                                             f"direction_deg, phase_rad), got {_show(comp)}")
            a, wavelength, direction, phase = comp
            _check_real(obj, f"{where}.amplitude_m", a, 0)
            _check_real(obj, f"{where}.wavelength_m", wavelength, 0, lo_open=True)
            _check_real(obj, f"{where}.direction_deg", direction)
            _check_real(obj, f"{where}.phase_rad", phase)
            n, m = _sinusoid_mode(self, wavelength, direction)
            nr, mr = round(n), round(m)
            if abs(n - nr) > 1e-6 * max(1.0, abs(n)) or abs(m - mr) > 1e-6 * max(1.0, abs(m)):
                raise SceneError(obj, where, f"is not periodic over the patch: it fits "
                                             f"{n:.6g} x {m:.6g} times in (Lx, Ly); the "
                                             f"wavevector must be (2 pi n / Lx, 2 pi m / Ly) "
                                             f"with whole n, m (e.g. wavelength_m "
                                             f"{self.patch_size_m[0] / max(1, abs(nr)):.6g} "
                                             f"with direction_deg 0)")
            nx, ny = self.resolution
            if not (abs(nr) < nx / 2 and abs(mr) < ny / 2):
                raise SceneError(obj, where, f"wavelength {wavelength!r} m is not resolved by "
                                             f"the grid: |n| < Nx/2 and |m| < Ny/2 are needed, "
                                             f"got n = {nr}, m = {mr}")

    def replace(self, **changes: Any) -> "WaveModel":
        """A copy with some fields changed."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return WaveModel(**values)


def _sinusoid_mode(model: WaveModel, wavelength: float, direction_deg: float):
    """(n, m): how many times a sinusoid fits the patch along x and y (whole if periodic)."""
    phi = math.radians(direction_deg)
    lx, ly = model.patch_size_m
    return lx * math.cos(phi) / wavelength, ly * math.sin(phi) / wavelength


# ----------------------------------------------------------------------------------------
# Dispersion, spectra and spreading
# ----------------------------------------------------------------------------------------

def dispersion(k: Any, depth: float | None = None) -> np.ndarray:
    """Angular frequency omega (rad/s) of gravity waves of wavenumber ``k`` (rad/m):
    ``omega^2 = g k tanh(k depth)``, deep water (``depth`` None) ``omega^2 = g k``."""
    k = np.asarray(k, dtype=np.float64)
    if depth is None:
        return np.sqrt(G * k)
    return np.sqrt(G * k * np.tanh(k * depth))


def group_velocity(k: Any, depth: float | None = None) -> np.ndarray:
    """d omega / dk (m/s) of :func:`dispersion`; 0 at k = 0 in deep water is returned as 0."""
    k = np.asarray(k, dtype=np.float64)
    w = dispersion(k, depth)
    with np.errstate(divide="ignore", invalid="ignore"):
        if depth is None:
            cg = G / (2.0 * w)
        else:
            t = np.tanh(k * depth)
            cg = G * (t + k * depth * (1.0 - t * t)) / (2.0 * w)
    return np.where(k > 0, cg, 0.0 if depth is None else math.sqrt(G * depth))


def _jonswap_parameters(model: WaveModel) -> tuple[float, float]:
    """(alpha, omega_p) of JONSWAP from the fetch relations, fetch capped at full development."""
    u = model.wind_speed
    chi = G * model.fetch_m / (u * u)               # dimensionless fetch
    omega_pm = (0.8 * PM_BETA) ** 0.25 * G / (U19_5_PER_U10 * u)
    chi_full = (22.0 * G / (u * omega_pm)) ** 3     # where 22 chi^-1/3 g/U reaches the PM peak
    chi = min(chi, chi_full)
    return 0.076 * chi ** -0.22, 22.0 * (G / u) * chi ** (-1.0 / 3.0)


def frequency_spectrum(model: WaveModel, omega: Any) -> np.ndarray:
    """Omnidirectional one-sided spectrum S(omega) (m^2 s) of ``model`` at ``omega`` (rad/s).

    Zero for ``"flat"`` and ``"sinusoids"`` (a discrete spectrum) and for omega <= 0.
    """
    omega = np.asarray(omega, dtype=np.float64)
    out = np.zeros_like(omega)
    pos = omega > 0
    w = omega[pos]
    u = model.wind_speed
    if model.spectrum in ("flat", "sinusoids") or u <= 0:
        return out
    if model.spectrum == "pierson_moskowitz":
        w0 = G / (U19_5_PER_U10 * u)
        out[pos] = PM_ALPHA * G * G * w ** -5 * np.exp(-PM_BETA * (w0 / w) ** 4)
    elif model.spectrum == "phillips":
        w0 = G / u
        out[pos] = PM_ALPHA * G * G * w ** -5 * np.exp(-((w0 / w) ** 4))
    elif model.spectrum == "jonswap":
        alpha, wp = _jonswap_parameters(model)
        sigma = np.where(w <= wp, 0.07, 0.09)
        r = np.exp(-((w - wp) ** 2) / (2.0 * sigma ** 2 * wp ** 2))
        out[pos] = alpha * G * G * w ** -5 * np.exp(-1.25 * (wp / w) ** 4) * model.gamma ** r
    else:
        raise ValueError(f"unknown spectrum {model.spectrum!r}")
    return out


def spreading_function(model: WaveModel, theta_rad: Any) -> np.ndarray:
    """Directional spreading D(theta) (1/rad), ``theta`` the direction of travel relative to
    the wind direction; integrates to 1 over the circle."""
    theta = np.asarray(theta_rad, dtype=np.float64)
    if model.spreading == "cos2":
        c = np.cos(theta)
        return np.where(c > 0, (2.0 / math.pi) * c * c, 0.0)
    s = float(model.spreading_s)
    q = math.exp(math.lgamma(s + 1.0) - math.lgamma(s + 0.5)) / (2.0 * math.sqrt(math.pi))
    return q * np.abs(np.cos(0.5 * theta)) ** (2.0 * s)


def directional_spectrum(model: WaveModel, kx: Any, ky: Any) -> np.ndarray:
    """Directional wavenumber spectrum Psi(kx, ky) (m^4) of a wind-driven ``model``:
    ``S(omega(k)) D(theta) (d omega / dk) / k``; its integral over the plane is the height
    variance (m^2). Zero at k = 0."""
    kx, ky = np.broadcast_arrays(np.asarray(kx, np.float64), np.asarray(ky, np.float64))
    k = np.hypot(kx, ky)
    out = np.zeros_like(k)
    pos = k > 0
    kp = k[pos]
    omega = dispersion(kp, model.water_depth_m)
    theta = np.arctan2(ky[pos], kx[pos]) - math.radians(model.wind_direction_deg)
    out[pos] = (frequency_spectrum(model, omega) * spreading_function(model, theta)
                * group_velocity(kp, model.water_depth_m) / kp)
    return out


# ----------------------------------------------------------------------------------------
# The grid and the random amplitudes
# ----------------------------------------------------------------------------------------

def _mode_numbers(n: int) -> np.ndarray:
    """Integer mode numbers of an n-point FFT axis (numpy order), e.g. 0, 1, .., -1."""
    return np.fft.fftfreq(n, 1.0 / n).round().astype(np.int64)


def wavenumber_grid(model: WaveModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kx (Nx, 1), ky (1, Ny), mask (Nx, Ny)) in rad/m, FFT order; ``mask`` is False for the
    mean (k = 0) and the Nyquist rows/columns, which the fields leave out."""
    (nx, ny), (lx, ly) = model.resolution, model.patch_size_m
    n, m = _mode_numbers(nx), _mode_numbers(ny)
    kx = (2.0 * math.pi / lx) * n[:, None]
    ky = (2.0 * math.pi / ly) * m[None, :]
    mask = (2 * np.abs(n)[:, None] < nx) & (2 * np.abs(m)[None, :] < ny)
    mask[0, 0] = False
    return kx, ky, mask


def _negated(a: np.ndarray) -> np.ndarray:
    """``a`` at the negated wavevector: ``out[i, j] = a[-i mod Nx, -j mod Ny]``."""
    return np.roll(np.flip(a, (0, 1)), 1, (0, 1))


def _grid_psi(model: WaveModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(kx, ky, Psi dkx dky on the used modes, 0 elsewhere; dkx dky)."""
    kx, ky, mask = wavenumber_grid(model)
    dk2 = (2.0 * math.pi) ** 2 / (model.patch_size_m[0] * model.patch_size_m[1])
    if model.spectrum in ("flat", "sinusoids"):
        return kx, ky, np.zeros(mask.shape), dk2
    return kx, ky, np.where(mask, directional_spectrum(model, kx, ky), 0.0) * dk2, dk2


def amplitudes(model: WaveModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kx (Nx, 1), ky (1, Ny), H (Nx, Ny) complex, m): the Fourier amplitudes h(k, t) at
    ``model.time_s`` with ``h(x) = sum_k H e^(i k.x)``; Hermitian, H(-k) = conj(H(k))."""
    model.validate()
    kx, ky, energy, _ = _grid_psi(model)
    omega = dispersion(np.hypot(kx, ky), model.water_depth_m)
    t = float(model.time_s)
    if model.spectrum == "sinusoids":
        h = np.zeros(energy.shape, dtype=np.complex128)
        nx, ny = model.resolution
        for a, wavelength, direction, phase in model.sinusoids:
            n, m = (round(x) for x in _sinusoid_mode(model, wavelength, direction))
            if n == 0 and m == 0:
                continue  # an infinitely long wave is a constant offset: not a wave
            w = omega[n % nx, m % ny]
            c = 0.5 * a * np.exp(1j * (phase - w * t))
            h[n % nx, m % ny] += c
            h[-n % nx, -m % ny] += np.conj(c)
        return kx, ky, h
    rng = np.random.default_rng(int(model.seed))
    xi = rng.standard_normal((2,) + energy.shape)
    h0 = (xi[0] + 1j * xi[1]) * np.sqrt(energy / 4.0)
    phase = np.exp(-1j * omega * t)
    return kx, ky, h0 * phase + np.conj(_negated(h0) * phase)


def _synthesise(h: np.ndarray) -> np.ndarray:
    """The real field ``sum_k h(k) e^(i k.x)`` on the grid of ``h``'s shape."""
    return np.fft.ifft2(h).real * h.size


# ----------------------------------------------------------------------------------------
# Fields
# ----------------------------------------------------------------------------------------

@dataclass(eq=False)
class WaveField:
    """One realisation of a :class:`WaveModel` on its grid; arrays are indexed ``[i, j]`` at
    ``(x[i], y[j]) = (i Lx / Nx, j Ly / Ny)`` (the undisplaced grid point).

    - ``height`` (Nx, Ny) [m]: h, mean 0 over the patch.
    - ``slope_x``, ``slope_y`` (Nx, Ny) [-]: dh/dx, dh/dy of the undisplaced field, exact
      (``i k h`` through the FFT).
    - ``displacement`` (Nx, Ny, 2) [m]: horizontal displacement ``lambda D`` of the point,
      ``D = sum i (k/|k|) h e^(i k.x)`` (the sign makes lambda > 0 sharpen the crests, as
      Gerstner waves); zero without choppiness. The surface point is
      ``(x + dx, y + dy, height)``.
    - ``jacobian`` (Nx, Ny) [-]: det of d(x + lambda D)/dx; 1 without choppiness; <= 0 where
      the surface folds (a whitecap proxy).
    - ``surface_slope_x``, ``surface_slope_y`` (Nx, Ny) [-]: slopes dz/dx', dz/dy' of the
      displaced surface at the displaced point (equal to ``slope_x``, ``slope_y`` without
      choppiness); undefined (inf) where it folds.
    - ``normals`` (Nx, Ny, 3) [-]: unit normals of the displaced surface,
      ``(-sx', -sy', 1) / sqrt(1 + sx'^2 + sy'^2)``, pointing up (out of the water) where
      the Jacobian is positive.
    - ``amplitudes`` (Nx, Ny) complex [m]: the Fourier amplitudes H (see :func:`amplitudes`).
    """

    model: WaveModel
    x: np.ndarray
    y: np.ndarray
    height: np.ndarray
    slope_x: np.ndarray
    slope_y: np.ndarray
    displacement: np.ndarray
    jacobian: np.ndarray
    surface_slope_x: np.ndarray
    surface_slope_y: np.ndarray
    normals: np.ndarray
    amplitudes: np.ndarray = field(repr=False)


def _fields_from_amplitudes(h: np.ndarray, kx: np.ndarray, ky: np.ndarray, lam: float,
                            ) -> dict[str, np.ndarray]:
    """Height, slopes, displacement and normals on the grid of ``h``'s shape."""
    height = _synthesise(h)
    sx, sy = _synthesise(1j * kx * h), _synthesise(1j * ky * h)
    shape = h.shape
    if lam == 0.0:
        disp = np.zeros(shape + (2,))
        jac = np.ones(shape)
        nx_, ny_, nz_ = -sx, -sy, np.ones(shape)
    else:
        k = np.hypot(kx, ky)
        with np.errstate(divide="ignore", invalid="ignore"):
            hk = np.where(k > 0, h / k, 0.0)
        disp = np.stack([_synthesise(1j * kx * hk), _synthesise(1j * ky * hk)], axis=-1) * lam
        dxx = 1.0 + lam * _synthesise(-kx * kx * hk)       # d(x + lam Dx)/dx
        dyy = 1.0 + lam * _synthesise(-ky * ky * hk)
        dxy = lam * _synthesise(-kx * ky * hk)             # d(lam Dx)/dy = d(lam Dy)/dx
        jac = dxx * dyy - dxy * dxy
        # Normal: (d/dx of the surface point) x (d/dy of the surface point).
        nx_ = dxy * sy - dyy * sx
        ny_ = dxy * sx - dxx * sy
        nz_ = jac
    with np.errstate(divide="ignore", invalid="ignore"):
        ssx, ssy = -nx_ / nz_, -ny_ / nz_
    normals = np.stack([nx_, ny_, nz_], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return dict(height=height, slope_x=sx, slope_y=sy, displacement=disp, jacobian=jac,
                surface_slope_x=ssx, surface_slope_y=ssy, normals=normals)


def generate(model: WaveModel) -> WaveField:
    """One realisation of ``model`` at ``model.time_s`` on its ``Nx x Ny`` grid.

    Raises
    ------
    SceneError
        If a field of the model is invalid (named as ``wave model: field '...'``).
    """
    kx, ky, h = amplitudes(model)
    (nx, ny), (lx, ly) = model.resolution, model.patch_size_m
    values = _fields_from_amplitudes(h, kx, ky, float(model.choppiness))
    return WaveField(model=model, x=np.arange(nx) * (lx / nx), y=np.arange(ny) * (ly / ny),
                     amplitudes=h, **values)


def evaluate(model: WaveModel, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(h, dh/dx, dh/dy) of the undisplaced field at arbitrary points (m), by the direct
    Fourier sum: the band-limited, periodic interpolant of :func:`generate`'s grid values.
    Costs (points x modes); meant for checks and a few points."""
    kx, ky, h = amplitudes(model)
    i, j = np.nonzero(h)
    kxs, kys, hs = np.broadcast_to(kx, h.shape)[i, j], np.broadcast_to(ky, h.shape)[i, j], h[i, j]
    x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
    e = np.exp(1j * (x[..., None] * kxs + y[..., None] * kys)) * hs
    return e.sum(-1).real, (1j * kxs * e).sum(-1).real, (1j * kys * e).sum(-1).real


# ----------------------------------------------------------------------------------------
# Variances
# ----------------------------------------------------------------------------------------

def height_variance(model: WaveModel) -> float:
    """Expected height variance (m^2) of the realisations: the spectrum integrated over the
    grid's band (``sum Psi dkx dky`` over the used modes); for ``"sinusoids"`` the exact
    variance of the (deterministic) field."""
    model.validate()
    if model.spectrum == "sinusoids":
        return float(np.sum(np.abs(amplitudes(model)[2]) ** 2))
    return float(np.sum(_grid_psi(model)[2]))


def _wave_energy(model: WaveModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kx, ky, expected |h|^2) of the model's components: its sinusoids, or the grid's
    spectrum times dkx dky."""
    model.validate()
    if model.spectrum == "sinusoids":
        kx, ky, h = amplitudes(model)
        return kx, ky, np.abs(h) ** 2
    kx, ky, energy, _ = _grid_psi(model)
    return kx, ky, energy


def slope_variance(model: WaveModel, axis: str | None = None) -> float:
    """Expected mean square slope of the realisations over the grid's band: ``sum k^2 Psi
    dkx dky`` (both axes, the Cox-Munk sigma^2), or ``sum kx^2 Psi`` (``axis="x"``) or
    ``sum ky^2 Psi`` (``axis="y"``)."""
    kx, ky, energy = _wave_energy(model)
    weight = {None: kx * kx + ky * ky, "x": kx * kx + 0 * ky, "y": ky * ky + 0 * kx}[axis]
    return float(np.sum(weight * energy))


def slope_variance_along(model: WaveModel, azimuth_deg: float) -> float:
    """Expected mean square slope along the horizontal direction at ``azimuth_deg`` (from +x
    towards +y): ``sum (k.e)^2 Psi``; along the wind and across it these are the resolved
    upwind and crosswind variances."""
    kx, ky, energy = _wave_energy(model)
    a = math.radians(azimuth_deg)
    return float(np.sum((kx * math.cos(a) + ky * math.sin(a)) ** 2 * energy))


def resolved_slope_variance(model: WaveModel) -> float:
    """sigma^2_resolved: the mean square slope (both axes) the grid resolves, i.e.
    :func:`slope_variance`. The sub-pixel roughness is what a Cox-Munk sigma^2 adds to it."""
    return slope_variance(model)


def subpixel_slope_variance(model: WaveModel, sigma2_total: float) -> float:
    """The sub-pixel slope budget ``max(0, sigma2_total - sigma2_resolved)``, e.g. with
    ``sigma2_total`` the Cox-Munk mean square slope for the model's wind."""
    return max(0.0, float(sigma2_total) - resolved_slope_variance(model))


# ----------------------------------------------------------------------------------------
# The triangle patch
# ----------------------------------------------------------------------------------------

def _catmull_rom(values: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Periodic Catmull-Rom interpolation of ``values`` (Nx, Ny, ...) at fractional grid
    indices ``u``, ``v``."""
    nx, ny = values.shape[:2]
    iu, iv = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)

    def weights(t):
        t2, t3 = t * t, t * t * t
        return [0.5 * (-t3 + 2 * t2 - t), 0.5 * (3 * t3 - 5 * t2 + 2),
                0.5 * (-3 * t3 + 4 * t2 + t), 0.5 * (t3 - t2)]

    wu, wv = weights(u - iu), weights(v - iv)
    out = 0.0
    for a in range(4):
        ia = (iu + a - 1) % nx
        row = 0.0
        for b in range(4):
            wb = wv[b] if values.ndim == 2 else wv[b][..., None]
            row = row + wb * values[ia, (iv + b - 1) % ny]
        out = out + (wu[a] if values.ndim == 2 else wu[a][..., None]) * row
    return out


def _resample_displaced(fld: WaveField) -> tuple[np.ndarray, np.ndarray]:
    """Height (Nx, Ny) and normals (Nx, Ny, 3) of the choppy surface at the regular grid
    points: solve ``x0 + lambda D(x0) = x`` (Newton) on the band-limited field upsampled
    f times, with periodic Catmull-Rom interpolation."""
    model = fld.model
    (nx, ny), (lx, ly) = model.resolution, model.patch_size_m
    f = max(2, min(8, 2048 // max(nx, ny)))
    big = np.zeros((f * nx, f * ny), dtype=np.complex128)
    ix, iy = _mode_numbers(nx) % (f * nx), _mode_numbers(ny) % (f * ny)
    big[np.ix_(ix, iy)] = fld.amplitudes
    bkx = (2.0 * math.pi / lx) * _mode_numbers(f * nx)[:, None]
    bky = (2.0 * math.pi / ly) * _mode_numbers(f * ny)[None, :]
    fine = _fields_from_amplitudes(big, bkx, bky, float(model.choppiness))
    # Checked on the fine field: folds between grid points count too.
    jmin = float(fine["jacobian"].min())
    if jmin <= 0.0:
        raise SurfaceFoldsError(f"the choppy surface folds over (Jacobian down to {jmin:.3g} "
                                f"<= 0): reduce the choppiness")
    lam = float(model.choppiness)
    k = np.hypot(bkx, bky)
    with np.errstate(divide="ignore", invalid="ignore"):
        hk = np.where(k > 0, big / k, 0.0)
    grads = np.stack([1.0 + lam * _synthesise(-bkx * bkx * hk), lam * _synthesise(-bkx * bky * hk),
                      1.0 + lam * _synthesise(-bky * bky * hk)], axis=-1)
    dxf, dyf = lx / (f * nx), ly / (f * ny)
    target = np.stack(np.meshgrid(fld.x, fld.y, indexing="ij"), axis=-1)
    x0 = target - fld.displacement  # first guess: one fixed-point step
    for _ in range(50):
        u, v = x0[..., 0] / dxf, x0[..., 1] / dyf
        disp = _catmull_rom(fine["displacement"], u, v)
        a, b, c = np.moveaxis(_catmull_rom(grads, u, v), -1, 0)
        rx, ry = (x0 + disp - target)[..., 0], (x0 + disp - target)[..., 1]
        det = a * c - b * b
        x0 = x0 - np.stack([(c * rx - b * ry) / det, (a * ry - b * rx) / det], axis=-1)
        if max(np.abs(rx).max() / lx, np.abs(ry).max() / ly) < 1e-12:
            break
    u, v = x0[..., 0] / dxf, x0[..., 1] / dyf
    height = _catmull_rom(fine["height"], u, v)
    normals = _catmull_rom(fine["normals"], u, v)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return height, normals


MAX_MESH_POINTS = 4096  # a patch mesh's points per side (resolution x mesh_refinement)


def refined_field(fld: WaveField, r: int) -> WaveField:
    """The same band-limited surface as ``fld`` on a grid ``r`` times finer: its Fourier
    amplitudes placed among the finer grid's modes (no new waves), all fields synthesised
    there. At the coarse grid's points the values are ``fld``'s (to rounding)."""
    if r == 1:
        return fld
    model = fld.model
    (nx, ny), (lx, ly) = model.resolution, model.patch_size_m
    big = np.zeros((r * nx, r * ny), dtype=np.complex128)
    big[np.ix_(_mode_numbers(nx) % (r * nx), _mode_numbers(ny) % (r * ny))] = fld.amplitudes
    kx = (2.0 * math.pi / lx) * _mode_numbers(r * nx)[:, None]
    ky = (2.0 * math.pi / ly) * _mode_numbers(r * ny)[None, :]
    values = _fields_from_amplitudes(big, kx, ky, float(model.choppiness))
    fine = model.replace(resolution=(r * nx, r * ny), mesh_refinement=1)
    return WaveField(model=fine, x=np.arange(r * nx) * (lx / (r * nx)), y=np.arange(r * ny) * (ly / (r * ny)),
                     amplitudes=big, **values)


def patch_mesh(fld: WaveField, z: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The periodic triangle patch of a field: (vertices (N, 3) float64 m, triangles (M, 3)
    int64, vertex normals (N, 3) unit, up).

    The vertices are the regular grid over exactly ``[0, Lx] x [0, Ly]``, ``(Nx + 1) x
    (Ny + 1)`` of them (index ``i (Ny + 1) + j``), the last row and column repeating the
    first (heights and normals equal, so the patch tiles), at height ``z + h``. Each grid
    cell is two triangles facing up. With choppiness the displaced surface is resampled at
    the regular grid points (Newton inversion of the displacement on the field upsampled
    with its own Fourier series, cubic interpolation: errors ~1e-3 of the shortest waves'
    amplitude), so that the patch stays a height field over the same rectangle.

    Raises
    ------
    SurfaceFoldsError
        If the choppy surface folds over (Jacobian <= 0 somewhere).
    """
    model = fld.model
    (nx, ny), (lx, ly) = model.resolution, model.patch_size_m
    if model.choppiness > 0:
        height, normals = _resample_displaced(fld)
    else:
        height, normals = fld.height, fld.normals
    wrap_i, wrap_j = np.r_[0:nx, 0], np.r_[0:ny, 0]
    gx = np.r_[fld.x, lx]
    gy = np.r_[fld.y, ly]
    xx, yy = np.meshgrid(gx, gy, indexing="ij")
    zz = z + height[np.ix_(wrap_i, wrap_j)]
    vertices = np.stack([xx.ravel(), yy.ravel(), zz.ravel()], axis=1)
    vn = normals[np.ix_(wrap_i, wrap_j)].reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    v00 = (i * (ny + 1) + j).ravel()
    v10, v01 = v00 + (ny + 1), v00 + 1
    v11 = v10 + 1
    triangles = np.concatenate([np.stack([v00, v10, v11], 1), np.stack([v00, v11, v01], 1)])
    return vertices, triangles.astype(np.int64), vn


@lru_cache(maxsize=2)
def surface_patch(model: WaveModel, z: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`patch_mesh` of :func:`generate` (cached by model; arrays read-only).

    Two entries: a scene's validation and compilation reuse its patch, while a long-lived
    worker rendering many time steps does not hold many 2048^2 patches (about 0.4 GB each)."""
    try:
        with np.errstate(all="ignore"):
            out = patch_mesh(refined_field(generate(model), int(model.mesh_refinement)), z)
    except (ArithmeticError, ValueError) as exc:
        if isinstance(exc, SurfaceFoldsError):
            raise
        raise WaveNumbersError(f"the wave model's numbers overflow ({type(exc).__name__}: {exc})") from None
    vertices, _, normals = out
    heights = vertices[:, 2] - z
    if not (np.isfinite(heights).all() and np.isfinite(normals).all()) or \
            float(np.abs(heights).max()) > 1e6 or not (normals[:, 2] > 0).all():
        raise WaveNumbersError("the wave model gives heights or slopes that are not finite "
                               "numbers, higher than 1e6 m or overhanging (its wind_speed, "
                               "gamma, fetch_m, water_depth_m or choppiness is beyond what the "
                               "spectrum's formulas hold)")
    for a in out:
        a.flags.writeable = False
    return out
