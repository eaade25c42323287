"""Scene parameters declared once: name, unit, default, range and meaning.

The engine's validation and the renderer check values against this table
(``check_parameter``); the JSON Schema (``photic/schema/scene.schema.json``), the Blender
add-on's property limits and the docs' tables are checked against it by
``tests/test_parameters.py``, which fails when any of them disagrees. Add a parameter here
first, then where it is used.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Parameter:
    """One parameter: ``key`` is ``<object>.<field>`` as in the scene format (``settings.samples``,
    ``water.ior``); the range is [lo, hi] (open ends where ``lo_open`` / ``hi_open``), None for
    no limit; ``integer`` for whole numbers."""

    key: str
    unit: str
    default: Any
    lo: float | None
    hi: float | None
    description: str
    integer: bool = False
    lo_open: bool = False
    hi_open: bool = False

    @property
    def field(self) -> str:
        return self.key.split(".", 1)[1]

    def contains(self, x: float) -> bool:
        if self.lo is not None and not (x > self.lo if self.lo_open else x >= self.lo):
            return False
        return self.hi is None or (x < self.hi if self.hi_open else x <= self.hi)


PARAMETERS: dict[str, Parameter] = {p.key: p for p in [
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
    Parameter("water.ior", "", 1.34, 1.0, 2.0, "refractive index of the water relative to air"),
    Parameter("band.center_nm", "nm", 550.0, 200.0, 3000.0, "centre wavelength of a band"),
    Parameter("band.width_nm", "nm", 10.0, 0.001, 1000.0, "width of a band"),
]}


def check_parameter(obj: str, key: str, value: Any, field: str | None = None) -> None:
    """SceneError (naming ``obj`` and the field) unless ``value`` is in the range of
    parameter ``key``."""
    from .scene.checks import _check_int, _check_real
    p = PARAMETERS[key]
    fld = field or p.field
    if p.integer:
        _check_int(obj, fld, value, p.lo, p.hi)
    else:
        _check_real(obj, fld, value, p.lo, p.hi, lo_open=p.lo_open, hi_open=p.hi_open)
