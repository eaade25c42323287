"""Scene parameters declared once: name, unit, default, range and meaning.

The engine's validation and the renderer check values against this table
(``check_parameter``, ``check_per_band_parameter``); the JSON Schema
(``photic/schema/scene.schema.json``), the Blender add-on's property limits and the docs'
tables are checked against it by ``tests/test_parameters.py``, which fails when any of them
disagrees. Add a parameter here first, then where it is used.

A key is ``<object>.<field>``: the object is the scene format's (its ``$defs`` name in the
schema: ``settings``, ``water``, ``sun``, ``phase``, ``surface`` ...), the field its path
within it (``surface.roughness.wind_speed``, ``camera.filter.width_px``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

# Embree traces in single precision: beyond about a thousand kilometres from the origin a
# float32 coordinate is coarser than 6 cm. Heights and depths are limited to this, in metres,
# sizes to twice it: photic.scene.checks.MAX_COORDINATE_M, which bounds positions (this module
# imports nothing of the scene's at load time; tests/test_parameters.py compares the two).
MAX_COORDINATE_M = 1e6
# Sun irradiance and sky radiance per band: far beyond any sun (about 2 W m^-2 nm^-1; photon
# units need micromol, not quanta), and the image (float32) stays finite: a pixel's variance is
# about its radiance squared, and float32 ends at 3.4e38 (1e20 gave inf variances). With the
# smallest sun disk (MIN_SUN_DIAMETER_DEG) the disk's radiance is at most 4.2e17, its square
# 1.8e35 (issue 49).
MAX_SOURCE = 1e8
# The smallest sun disk (degrees): the disk's radiance E / (pi sin^2 alpha) must stay finite
# and its square fit a float32 image (1e-300 made every pixel NaN).
MIN_SUN_DIAMETER_DEG = 0.001
# The narrowest radiance meter (half-angle, degrees): its cap's solid angle 2 pi (1 - cos)
# keeps 8 digits in double precision (1e-9 gave 0, and NaN values marked trusted).
MIN_HALF_ANGLE_DEG = 0.01
# |g| of Henyey-Greenstein: nearer 1 its sampling loses all precision (NaN in the hybrid).
MAX_HG_G = 0.9999

SCALAR, PER_BAND, PAIR = "scalar", "per band", "pair"


@dataclass(frozen=True)
class Parameter:
    """One parameter: ``key`` is ``<object>.<field>`` as in the scene format (``settings.samples``,
    ``water.ior``); the range is [lo, hi] (open ends where ``lo_open`` / ``hi_open``), None for
    no limit; ``integer`` for whole numbers; ``shape`` says whether the value is one number,
    one per band (a list, or one number for every band) or a pair [x, y] each in the range;
    ``default`` None where the field is required or absent by default."""

    key: str
    unit: str
    default: Any
    lo: float | None
    hi: float | None
    description: str
    integer: bool = False
    lo_open: bool = False
    hi_open: bool = False
    shape: str = SCALAR

    @property
    def object(self) -> str:
        return self.key.split(".", 1)[0]

    @property
    def field(self) -> str:
        return self.key.split(".", 1)[1]

    @property
    def name(self) -> str:
        """The last part of the field (``wind_speed`` of ``surface.roughness.wind_speed``)."""
        return self.key.rsplit(".", 1)[1]

    def contains(self, x: float) -> bool:
        if self.lo is not None and not (x > self.lo if self.lo_open else x >= self.lo):
            return False
        return self.hi is None or (x < self.hi if self.hi_open else x <= self.hi)

    def range_text(self) -> str:
        """The range as the docs write it: ``[0.0001, 0.15]``, ``(0, 90]``, ``>= 0``."""
        lo, hi = (None if x is None else _short(x) for x in (self.lo, self.hi))
        if lo is not None and hi is not None:
            return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}"
        if lo is not None:
            return f"{'>' if self.lo_open else '>='} {lo}"
        return "any" if hi is None else f"{'<' if self.hi_open else '<='} {hi}"


def _short(x: float) -> str:
    """``0.15``, ``90``, ``1e6``: a bound as the docs write it."""
    return f"{x:g}".replace("e+0", "e").replace("e+", "e")


_XY = 2 * MAX_COORDINATE_M  # largest size (m): from -MAX_COORDINATE_M to +MAX_COORDINATE_M

PARAMETERS: dict[str, Parameter] = {p.key: p for p in [
    # settings
    Parameter("settings.samples", "samples per pixel", 16, 1, 1_000_000,
       "camera samples per pixel (with noise_threshold: the most a pixel takes)", integer=True),
    Parameter("settings.radiometer_samples", "samples", 65536, 1, 10**10,
       "samples per radiometer (with target_error: the most one may take)", integer=True),
    Parameter("settings.seed", "", 0, 0, 2**63 - 1, "random seed: the same seed gives the same numbers "
       "on any number of threads", integer=True),
    Parameter("settings.threads", "", 0, 0, 1024, "CPU threads, 0 = all cores", integer=True),
    Parameter("settings.max_depth", "events", 256, 1, 100_000, "largest number of scattering or "
       "reflection events of a path", integer=True),
    Parameter("settings.beam_max_level", "levels", 5, 0, 10, "levels of adaptive subdivision of a "
       "surface triangle's beam", integer=True),
    Parameter("settings.adaptive_min_samples", "samples per pixel", 16, 1, 1_000_000,
       "samples per pixel before a pixel may stop at the noise threshold", integer=True),
    Parameter("settings.forward_cone_deg", "deg", "auto", 0.0, 30.0,
       "half-angle of the forward-scattering cone kept in the beams, or auto"),
    Parameter("settings.target_error", "relative", None, 0.0, 1.0,
       "relative standard error at which a radiometer stops", lo_open=True, hi_open=True),
    Parameter("settings.noise_threshold", "relative", None, 0.0, 1.0,
       "relative standard error at which a pixel stops", lo_open=True, hi_open=True),
    # bands and materials
    Parameter("band.center_nm", "nm", 550.0, 200.0, 3000.0, "centre wavelength of a band"),
    Parameter("band.width_nm", "nm", 10.0, 0.001, 1000.0, "width of a band"),
    Parameter("material.reflectance", "", None, 0.0, 1.0, "Lambertian reflectance (albedo)",
       shape=PER_BAND),
    Parameter("material.emission", "W m^-2 sr^-1 (per nm)", None, 0.0, MAX_SOURCE,
       "radiance a surface emits", shape=PER_BAND),
    # water and its optical properties
    Parameter("water.ior", "", 1.34, 1.0, 2.0, "refractive index of the water relative to air"),
    Parameter("iops.absorption", "m^-1", None, 0.0, None, "absorption coefficient a",
       shape=PER_BAND),
    Parameter("scattering_component.b", "m^-1", None, 0.0, None,
       "scattering coefficient b of one component", shape=PER_BAND),
    Parameter("phase.g", "", None, -MAX_HG_G, MAX_HG_G,
       "asymmetry parameter (mean cosine) of Henyey-Greenstein"),
    # (the range of Mobley et al. 2002's parameterisation of Fournier-Forand)
    Parameter("phase.backscatter_fraction", "", None, 1e-4, 0.15,
       "backscatter fraction bb/b of Fournier-Forand"),
    Parameter("bottom.depth", "m", None, 0.0, MAX_COORDINATE_M,
       "depth of the flat bottom below the mean surface height", lo_open=True),
    # the sea surface
    Parameter("surface.z", "m", 0.0, -MAX_COORDINATE_M, MAX_COORDINATE_M,
       "height of a flat surface, or the mean water level of the waves"),
    Parameter("surface.period", "m", None, 1e-3, _XY, "period [Lx, Ly] of a surface patch",
       shape=PAIR),
    Parameter("surface.roughness.wind_speed", "m/s", None, 0.0, 50.0,
       "wind speed of the Cox-Munk slope variance (its fit covers 0 to 50 m/s)"),
    # (wave models: beyond these the spectra's formulas overflow, issue 49)
    Parameter("surface.wind_speed", "m/s", 5.0, 0.0, 100.0,
       "wind speed U10 of a wave model (> 0 for the wind spectra; at most 100, beyond any storm)"),
    Parameter("surface.patch_size_m", "m", [50.0, 50.0], 1e-3, _XY,
       "period [Lx, Ly] of a wave patch", shape=PAIR),
    Parameter("surface.resolution", "grid points", [64, 64], 2, 4096,
       "grid points [Nx, Ny] of a wave patch", integer=True, shape=PAIR),
    Parameter("surface.seed", "", 0, 0, 2**63 - 1, "seed of the random wave amplitudes",
       integer=True),
    Parameter("surface.choppiness", "", 0.0, 0.0, None,
       "horizontal displacement factor lambda of the waves; must not fold the surface"),
    Parameter("surface.water_depth_m", "m", None, 1e-3, None,
       "water depth of the waves' dispersion relation (at least 1 mm); absent for deep water"),
    Parameter("surface.fetch_m", "m", None, 0.0, None, "fetch of a JONSWAP sea", lo_open=True),
    Parameter("surface.gamma", "", 3.3, 1.0, 20.0, "JONSWAP peak enhancement (1: Pierson-Moskowitz; "
       "measured 1 to 7)"),
    Parameter("surface.spreading_s", "", 10.0, 0.0, 1000.0, "exponent s of cos2s spreading",
       lo_open=True),
    Parameter("surface.mesh_refinement", "", 1, 1, 16, "triangles of a wave patch this many times finer "
       "than its grid (the same waves)", integer=True),
    # light
    Parameter("sun.zenith_deg", "deg", None, 0.0, 90.0,
       "solar zenith angle: the sun must be above the horizon", hi_open=True),
    Parameter("sun.irradiance", "W m^-2 (per nm)", None, 0.0, MAX_SOURCE,
       "solar irradiance normal to the sun's direction", shape=PER_BAND),
    Parameter("sun.angular_diameter_deg", "deg", 0.53, MIN_SUN_DIAMETER_DEG, 20.0,
       "angular diameter of the solar disk (the real sun's is 0.53; larger for verification)"),
    Parameter("sky.radiance", "W m^-2 sr^-1 (per nm)", None, 0.0, MAX_SOURCE,
       "sky radiance L0", shape=PER_BAND),
    Parameter("sky.cloud_fraction", "", 0.0, 0.0, 1.0, "cloud fraction of harrison_coombes"),
    # sensors
    Parameter("camera.fov_deg", "deg", 40.0, 0.0, 180.0, "horizontal field of view (perspective)",
       lo_open=True, hi_open=True),
    Parameter("camera.ortho_width", "m", 2.0, 0.0, _XY, "width of the imaged area (orthographic)",
       lo_open=True),
    Parameter("camera.clip_start", "m", 0.0, 0.0, MAX_COORDINATE_M,
       "near clipping distance along the viewing direction"),
    Parameter("camera.shift", "image widths", None, -10.0, 10.0, "lens shift [x, y]", shape=PAIR),
    Parameter("camera.resolution", "pixels", [64, 64], 1, 16384, "image size [width, height]",
       integer=True, shape=PAIR),
    Parameter("camera.filter.width_px", "pixels", None, 0.0, None,
       "width of the pixel filter (default 1 for box, 1.5 for gaussian)", lo_open=True),
    Parameter("radiometer.half_angle_deg", "deg", 12.9, MIN_HALF_ANGLE_DEG, 90.0,
       "half-angle of a radiance meter's viewing cap"),
    Parameter("radiometer.polar_bins", "bins", 18, 1, 1_000_000,
       "polar-angle bins of a radiance distribution", integer=True),
    Parameter("radiometer.azimuth_bins", "bins", 24, 1, 1_000_000,
       "azimuth bins of a radiance distribution", integer=True),
]}


def check_parameter(obj: str, key: str, value: Any, field: str | None = None) -> None:
    """SceneError (naming ``obj`` and the field, ``field`` or the parameter's) unless ``value``
    is in the range of parameter ``key``."""
    from .scene.checks import _check_int, _check_real
    p = PARAMETERS[key]
    fld = field or p.field
    if p.integer:
        _check_int(obj, fld, value, p.lo, p.hi)
    else:
        _check_real(obj, fld, value, p.lo, p.hi, lo_open=p.lo_open, hi_open=p.hi_open)


def check_per_band_parameter(obj: str, key: str, values: Any, nbands: int,
                             field: str | None = None) -> None:
    """SceneError unless ``values`` holds one number per band, each in the range of ``key``."""
    from .scene.checks import _check_per_band
    p = PARAMETERS[key]
    assert p.shape == PER_BAND and not (p.lo_open or p.hi_open), p
    _check_per_band(obj, field or p.field, values, nbands, p.lo, p.hi)
