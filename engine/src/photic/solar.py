"""The sun at a place and time: its position, and the spectral irradiance of its direct beam
under a clear sky. A helper for setting up scenes (the Blender add-on's "Clear-Sky Sun"), not
a radiative-transfer model of the atmosphere.

- Position: the NOAA General Solar Position approximation (fractional-year series for the
  declination and the equation of time; Spencer 1971), good to about 0.2 deg between the polar
  circles, no refraction.
- Direct normal spectral irradiance: a 5778 K black body scaled to the total solar irradiance
  (1361 W m^-2, Kopp & Lean 2011) at the day's Earth-Sun distance, times exp(-m (tau_R + tau_a))
  with Rayleigh scattering (Hansen & Travis 1974, scaled by pressure), aerosols by the
  Angstrom law (tau_a = beta lambda^-alpha, lambda in um) and the relative air mass of Kasten &
  Young (1989). No ozone or water-vapour absorption and no Fraunhofer lines: within about 10 %
  of measured clear-sky spectra between 400 and 700 nm, plausible rather than exact.

Angles follow the scene format: zenith from the vertical, azimuth counterclockwise from +x
towards +y, with +x east and +y north (so a geographic azimuth A, clockwise from north, is
90 - A here).
"""
from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np

from .colour import trapezoid

TOTAL_SOLAR_IRRADIANCE = 1361.0  # W m^-2 at 1 AU (Kopp & Lean 2011)
SUN_TEMPERATURE = 5778.0         # K, the black body standing in for the sun's spectrum
H, C, KB = 6.62607015e-34, 2.99792458e8, 1.380649e-23


def _fractional_year(when: datetime) -> tuple[float, int]:
    when = when.astimezone(timezone.utc) if when.tzinfo else when.replace(tzinfo=timezone.utc)
    start = datetime(when.year, 1, 1, tzinfo=timezone.utc)
    days = 366 if (when.year % 4 == 0 and (when.year % 100 != 0 or when.year % 400 == 0)) else 365
    doy = (when - start).days + 1
    hour = when.hour + when.minute / 60 + when.second / 3600
    return 2 * math.pi / days * (doy - 1 + (hour - 12) / 24), doy


def solar_position(latitude_deg: float, longitude_deg: float, when: datetime) -> tuple[float, float]:
    """(zenith_deg, azimuth_deg) of the sun at a place (degrees north, east) and a time (UTC if
    naive), azimuth in the scene's convention (counterclockwise from east)."""
    if not -90.0 <= latitude_deg <= 90.0:
        raise ValueError(f"latitude {latitude_deg} is not in -90 .. 90 degrees")
    if not -180.0 <= longitude_deg <= 360.0:
        raise ValueError(f"longitude {longitude_deg} is not in -180 .. 360 degrees")
    g, _ = _fractional_year(when)
    eqtime = 229.18 * (0.000075 + 0.001868 * math.cos(g) - 0.032077 * math.sin(g)
                       - 0.014615 * math.cos(2 * g) - 0.040849 * math.sin(2 * g))  # minutes
    decl = (0.006918 - 0.399912 * math.cos(g) + 0.070257 * math.sin(g) - 0.006758 * math.cos(2 * g)
            + 0.000907 * math.sin(2 * g) - 0.002697 * math.cos(3 * g) + 0.00148 * math.sin(3 * g))
    w = when.astimezone(timezone.utc) if when.tzinfo else when
    minutes = w.hour * 60 + w.minute + w.second / 60
    true_solar = minutes + eqtime + 4 * longitude_deg
    hour_angle = math.radians(true_solar / 4 - 180)
    lat = math.radians(latitude_deg)
    cos_z = math.sin(lat) * math.sin(decl) + math.cos(lat) * math.cos(decl) * math.cos(hour_angle)
    zenith = math.acos(max(-1.0, min(1.0, cos_z)))
    # geographic azimuth, clockwise from north
    east = -math.cos(decl) * math.sin(hour_angle)
    north = math.cos(lat) * math.sin(decl) - math.sin(lat) * math.cos(decl) * math.cos(hour_angle)
    azimuth_geo = math.degrees(math.atan2(east, north)) % 360.0
    return math.degrees(zenith), (90.0 - azimuth_geo) % 360.0


def declination_deg(when: datetime) -> float:
    """The sun's declination (degrees) on that day."""
    g, _ = _fractional_year(when)
    return math.degrees(0.006918 - 0.399912 * math.cos(g) + 0.070257 * math.sin(g)
                        - 0.006758 * math.cos(2 * g) + 0.000907 * math.sin(2 * g)
                        - 0.002697 * math.cos(3 * g) + 0.00148 * math.sin(3 * g))


def air_mass(zenith_deg: float) -> float:
    """Relative optical air mass (Kasten & Young 1989); inf below the horizon."""
    if zenith_deg >= 90.0:
        return math.inf
    return 1.0 / (math.cos(math.radians(zenith_deg)) + 0.50572 * (96.07995 - zenith_deg) ** -1.6364)


def extraterrestrial(wavelength_nm, day_of_year: int = 80) -> np.ndarray:
    """Spectral irradiance above the atmosphere, W m^-2 nm^-1: the black body at
    SUN_TEMPERATURE scaled to TOTAL_SOLAR_IRRADIANCE, times the Earth-Sun distance factor."""
    lam = np.asarray(wavelength_nm, float) * 1e-9

    def planck(l):
        return 2 * H * C ** 2 / l ** 5 / np.expm1(H * C / (l * KB * SUN_TEMPERATURE))

    grid = np.linspace(100e-9, 100e-6, 200001)
    total = trapezoid(planck(grid), grid)
    distance = 1.0 + 0.033 * math.cos(2 * math.pi * day_of_year / 365.0)
    return TOTAL_SOLAR_IRRADIANCE * distance * planck(lam) / total * 1e-9


def rayleigh_optical_depth(wavelength_nm, pressure_hpa: float = 1013.25) -> np.ndarray:
    """Rayleigh optical depth of the atmosphere (Hansen & Travis 1974), scaled by pressure."""
    um = np.asarray(wavelength_nm, float) / 1000.0
    return 0.008569 * um ** -4 * (1 + 0.0113 * um ** -2 + 0.00013 * um ** -4) * pressure_hpa / 1013.25


def clear_sky_direct(wavelength_nm, zenith_deg: float, aerosol_beta: float = 0.05,
                     angstrom_alpha: float = 1.3, pressure_hpa: float = 1013.25,
                     day_of_year: int = 80) -> np.ndarray:
    """Direct normal spectral irradiance of the sun at the surface under a clear sky,
    W m^-2 nm^-1 (0 with the sun below the horizon). ``aerosol_beta``: Angstrom's turbidity
    (aerosol optical depth at 1 um; 0.05 clear, 0.2 hazy)."""
    if not (aerosol_beta >= 0 and math.isfinite(aerosol_beta)):
        raise ValueError(f"aerosol_beta {aerosol_beta} must be a finite number >= 0")
    lam = np.asarray(wavelength_nm, float)
    if not np.all((lam >= 280.0) & (lam <= 4000.0)):
        raise ValueError("wavelengths must be in 280 .. 4000 nm")
    m = air_mass(zenith_deg)
    if not math.isfinite(m):
        return np.zeros_like(lam)
    tau = rayleigh_optical_depth(lam, pressure_hpa) + aerosol_beta * (lam / 1000.0) ** -angstrom_alpha
    return extraterrestrial(lam, day_of_year) * np.exp(-m * tau)
