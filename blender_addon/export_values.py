"""Values read from Blender properties, and the errors that name the data-block and the
property when one is wrong: shared by the export of the scene (``export``) and of natural
waters' varying IOPs (``natural_waters``), which import it and not each other."""
from __future__ import annotations

import math

import numpy as np

from . import bands as bandmod


class ExportError(Exception):
    """A problem in the Blender scene: the data-block (``owner``, e.g. ``Object 'Sea'``), the
    property (its UI name and its Python path) and what is wrong."""

    def __init__(self, owner: str, prop: str, message: str):
        super().__init__(owner, prop, message)
        self.owner, self.prop, self.message = owner, prop, message

    def __str__(self) -> str:
        return f"{self.owner}, {self.prop}: {self.message}"


class ExportCancelled(Exception):
    """The user stopped the export."""


def blender_float(x: float) -> float:
    """A Blender float property as the decimal number the user typed.

    Blender stores properties in float32 (about 7 significant digits): 1.34 comes back as
    1.3400000334. Keeping 7 significant digits recovers 1.34, so a scene made in Blender and
    the same scene written as a file are identical."""
    return float(f"{float(x):.7g}")


def _obj(name: str) -> str:
    return f"Object '{name}'"


def _finite_non_negative(owner: str, prop: str, values: np.ndarray, what: str) -> None:
    for i, x in enumerate(values):
        if not math.isfinite(x):
            raise ExportError(owner, prop, f"{what} in band {i + 1} is {x} (must be a finite number)")
        if x < 0:
            raise ExportError(owner, prop, f"{what} in band {i + 1} is {x:g} (must be >= 0)")


def per_band(owner: str, single: float, text: str, name: str, path: str, bands,
             what: str, hi: float | None = None) -> np.ndarray:
    """A per-band value from a single-number property and its optional per-band text."""
    nb = len(bands)
    if text.strip():
        prop = f"{name} per Band ({path}_bands)"
        try:
            values = bandmod.parse_number_list(text, f"'{name} per Band'")
        except ValueError as exc:
            raise ExportError(owner, prop, str(exc)) from None
        if len(values) == 1:
            values = values * nb
        if len(values) != nb:
            raise ExportError(owner, prop, f"has {len(values)} values but the scene has {nb} "
                                           f"bands ({', '.join(b[0] for b in bands)} nm)")
        arr = np.array(values, float)
    else:
        prop = f"{name} ({path})"
        arr = np.full(nb, blender_float(single))
    _finite_non_negative(owner, prop, arr, what)
    if hi is not None and np.any(arr > hi):
        raise ExportError(owner, prop, f"{what} {arr.max():g} is above {hi:g}")
    return arr


def _transform_parts(obj) -> list[str]:
    """The fields of an object's transform (Object Properties > Transform, and Delta
    Transform) that hold a NaN or an infinity."""
    import math
    mode = getattr(obj, "rotation_mode", "XYZ")
    rotation = ("rotation_quaternion" if mode == "QUATERNION" else
                "rotation_axis_angle" if mode == "AXIS_ANGLE" else "rotation_euler")
    parts = []
    for label, attr in (("Location", "location"), ("Rotation", rotation), ("Scale", "scale"),
                        ("Delta Location", "delta_location"),
                        ("Delta Rotation", "delta_" + rotation if rotation != "rotation_axis_angle"
                         else "delta_rotation_euler"), ("Delta Scale", "delta_scale")):
        values = getattr(obj, attr, None)
        if values is not None and not all(math.isfinite(float(x)) for x in values):
            parts.append(f"{label} ({attr})")
    return parts


def non_finite_transform(obj) -> ExportError:
    """The error for an object whose world matrix holds a NaN or an infinity, naming the
    transform field that does (or its parent or constraints)."""
    original = getattr(obj, "original", obj)
    owner = f"Light '{original.name}'" if getattr(original, "type", "") == "LIGHT" else _obj(original.name)
    parts = _transform_parts(original)
    if not parts and getattr(original, "parent", None) is not None:
        parent_parts = _transform_parts(original.parent)
        if parent_parts:
            return ExportError(owner, "Parent", f"'{original.parent.name}' has a transform that is "
                                                f"not a finite number ({', '.join(parent_parts)})")
    field = ", ".join(parts) if parts else "Transform (its parent, a constraint or a driver)"
    return ExportError(owner, field, "is not a finite number (NaN or infinite): the object has "
                                     "no place, direction or size in the scene")
