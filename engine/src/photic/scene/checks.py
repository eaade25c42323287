"""The scene format's constants and limits, ``SceneError``, and the small checks every part
uses (a finite number in a range, an integer, a choice, a per-band list, a point): each
problem a SceneError naming the object and the field.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np


FORMAT_VERSION = 1

#: Phase function types and the names of their parameters.
PHASE_FUNCTION_PARAMS: dict[str, tuple[str, ...]] = {
    "petzold": (),
    "fournier_forand": ("backscatter_fraction",),
    "henyey_greenstein": ("g",),
    "pure_water": (),
    "isotropic": (),
}

#: Quantities a radiometer can measure.
QUANTITIES = ("Ed", "Eu", "Eo", "Eod", "Eou", "radiance", "radiance_distribution")

WATER_TYPES = ("mesh", "ocean")
MAX_COMPONENTS = 16  # scattering components per water body (the compiled core's limit)
SURFACE_KINDS = ("flat", "patch", "waves")  # scene files also take "plugin" (read as a patch)
SKY_TYPES = ("black", "uniform", "cardioidal", "harrison_coombes", "environment")
CAMERA_TYPES = ("perspective", "orthographic")
FILTER_TYPES = ("box", "gaussian")
INTEGRATORS = ("auto", "path", "hybrid")

# Default filter width per filter type (pixels).
_FILTER_DEFAULT_WIDTH = {"box": 1.0, "gaussian": 1.5}

# A triangle is degenerate when its area is below this times the squared bounding-box diagonal.
_DEGENERATE_AREA_FRACTION = 1e-12


class SceneError(ValueError):
    """An invalid scene: names the object (e.g. ``water 'sea'``) and the field.

    Parameters
    ----------
    obj : str
        The object, e.g. ``"water 'sea'"``, ``"settings"`` or ``"scene"``.
    field : str
        The field path inside the object, e.g. ``"iops.absorption[0]"``.
    message : str
        What is wrong.
    """

    def __init__(self, obj: str, field: str, message: str):
        # args are the constructor arguments so that the error survives pickling.
        super().__init__(obj, field, message)
        self.obj = obj
        self.field = field
        self.message = message

    def __str__(self) -> str:
        return f"{self.obj}: field '{self.field}': {self.message}"


# ----------------------------------------------------------------------------------------
# Small helpers shared by the data classes, the builder and the checks
# ----------------------------------------------------------------------------------------

def _values_equal(a: Any, b: Any) -> bool:
    """Compare nested scene values; numpy arrays compare by shape and value."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        try:
            a, b = np.asarray(a), np.asarray(b)
        except (TypeError, ValueError):
            return False
        return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"
                                                         and b.dtype.kind == "f"))
    if is_dataclass(a) or is_dataclass(b):
        return type(a) is type(b) and all(
            _values_equal(getattr(a, f.name), getattr(b, f.name)) for f in fields(a))
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_values_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_values_equal(a[k], b[k]) for k in a)
    return bool(a == b)


class _ArrayEq:
    """Mixin: ``==`` that works for data classes holding numpy arrays."""

    def __eq__(self, other: object) -> bool:
        return _values_equal(self, other)

    __hash__ = None  # mutable, like the default data class


def _as_floats(x: Any) -> Any:
    """A float64 copy of ``x``, or ``x`` unchanged when it is not numeric (validate reports it)."""
    if x is None:
        return None
    try:
        return np.array(x, dtype=np.float64)
    except (TypeError, ValueError):
        return x


def _unit(v: Any) -> Any:
    """``v / |v|``; ``v`` itself if already unit length (keeps round trips bit-exact) or zero."""
    if not isinstance(v, np.ndarray) or v.shape != (3,):
        return v
    n = float(np.linalg.norm(v))
    if n == 0.0 or not math.isfinite(n) or abs(n - 1.0) <= 4 * np.finfo(np.float64).eps:
        return v
    return v / n


def _show(x: Any) -> str:
    """Short text for a value in an error message."""
    if isinstance(x, bool) or x is None:
        return repr(x)
    if isinstance(x, numbers.Integral):
        return str(int(x))
    if isinstance(x, numbers.Real):
        return repr(float(x))
    if isinstance(x, np.ndarray):
        x = x.tolist()
    text = repr(x)
    return text if len(text) <= 60 else text[:57] + "..."


def _num(x: float) -> str:
    """A bound in an error message: integers without a decimal point."""
    if isinstance(x, numbers.Integral) or (float(x).is_integer() and abs(x) < 1e16):
        return str(int(x))
    return repr(float(x))


def _entries(n: int) -> str:
    return f"{n} entry" if n == 1 else f"{n} entries"


def _range_text(lo=None, hi=None, lo_open=False, hi_open=False, integer=False) -> str:
    """Describe an allowed range, e.g. ``a finite number in (-1, 1)``."""
    kind = "an integer" if integer else "a finite number"
    if lo is not None and hi is not None:
        return f"{kind} in {'(' if lo_open else '['}{_num(lo)}, {_num(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{kind} {'>' if lo_open else '>='} {_num(lo)}"
    if hi is not None:
        return f"{kind} {'<' if hi_open else '<='} {_num(hi)}"
    return kind


def _is_real(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _check_real(obj, fld, x, lo=None, hi=None, *, lo_open=False, hi_open=False) -> None:
    """Require a finite real number in the given range."""
    ok = _is_real(x) and math.isfinite(x)
    if ok and lo is not None:
        ok = x > lo if lo_open else x >= lo
    if ok and hi is not None:
        ok = x < hi if hi_open else x <= hi
    if not ok:
        raise SceneError(obj, fld, f"must be {_range_text(lo, hi, lo_open, hi_open)}, "
                                   f"got {_show(x)}")


def _check_int(obj, fld, x, lo, hi) -> None:
    """Require an integer (an integral float is accepted) in ``[lo, hi]``."""
    ok = (isinstance(x, numbers.Integral) and not isinstance(x, bool)) or (
        _is_real(x) and math.isfinite(x) and float(x).is_integer())
    if not (ok and lo <= x <= hi):
        raise SceneError(obj, fld, f"must be {_range_text(lo, hi, integer=True)}, got {_show(x)}")


def _check_choice(obj, fld, x, choices) -> None:
    if not isinstance(x, str) or x not in choices:
        raise SceneError(obj, fld, f"must be one of {', '.join(map(repr, choices))}, "
                                   f"got {_show(x)}")


def _check_per_band(obj, fld, a, nbands, lo=0.0, hi=None) -> None:
    """Require a float array with one finite value in ``[lo, hi]`` per band."""
    if not isinstance(a, np.ndarray) or a.ndim != 1 or a.dtype.kind not in "fiu":
        raise SceneError(obj, fld, f"must be a list of {nbands} number(s), one per band, "
                                   f"got {_show(a)}")
    if a.shape[0] != nbands:
        raise SceneError(obj, fld, f"has {_entries(a.shape[0])} but the scene has "
                                   f"{nbands} band(s)")
    for i, x in enumerate(a.tolist()):
        _check_real(obj, f"{fld}[{i}]", x, lo, hi)


# Embree traces in single precision: beyond about a thousand kilometres from the origin a
# float32 coordinate is coarser than 6 cm and rays there fail its checks (it aborted the
# process). Positions and sizes are limited to this, in metres (photic.parameters bounds
# heights, depths and sizes with the same number; tests/test_parameters.py compares).
MAX_COORDINATE_M = 1e6
_COORD_TEXT = (f"within +-{MAX_COORDINATE_M:.0e} m of the origin (Embree traces in single "
               f"precision; move the scene nearer the origin)")


def _check_vec3(obj, fld, v, nonzero=False, position=False) -> None:
    """Require a finite 3-vector (not zero if ``nonzero``; within MAX_COORDINATE_M of the
    origin if it is a ``position``)."""
    if (not isinstance(v, np.ndarray) or v.shape != (3,) or v.dtype.kind not in "fiu"
            or not np.all(np.isfinite(v))):
        raise SceneError(obj, fld, f"must be 3 finite numbers [x, y, z], got {_show(v)}")
    if nonzero and not np.any(v):
        raise SceneError(obj, fld, "must not be the zero vector")
    if position and np.max(np.abs(v)) > MAX_COORDINATE_M:
        raise SceneError(obj, fld, f"must be {_COORD_TEXT}, got {_show(v)}")


MAX_DISTRIBUTION_BINS = 1_000_000  # polar x azimuth bins of a radiance distribution
MAX_ARRAY_RADIOMETERS = 1_000_000  # radiometers of one array


def _check_name(kind: str, index: int, name: Any, seen: dict[str, str]) -> str:
    """Require a non-empty, unique name; return the object's label for error messages."""
    label = _label(kind, name, index)
    if not isinstance(name, str) or not name:
        raise SceneError(label, "name", f"must be a non-empty string, got {_show(name)}")
    _check_encodable(label, "name", name)
    if name in seen:
        raise SceneError(label, "name", f"duplicate name: also used by {seen[name]}")
    seen[name] = f"{kind}[{index}]"
    return label


def _label(kind: str, name: Any, index: int) -> str:
    """``water 'sea'``, or ``water[2]`` when the object has no usable name."""
    return f"{kind} '{name}'" if isinstance(name, str) and name and _encodable(name) else f"{kind}[{index}]"


def _encodable(text: str) -> bool:
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _check_encodable(obj: str, fld: str, text: str) -> None:
    """Names go into file names, tables and image headers, all UTF-8: a lone surrogate (JSON's
    "\\ud800") cannot be written, and made the writing fail after the render."""
    if not _encodable(text):
        shown = text.encode("utf-8", "backslashreplace").decode("ascii", "backslashreplace")
        raise SceneError(obj, fld, f"must be text that UTF-8 can hold, got {shown[:60]!r} (a lone "
                                   f"surrogate, half of a character)")


