"""Photic scene description: data classes, JSON loader and validator (format version 1).

The format is specified in ``docs/scene-format.md``; its JSON Schema is
``photic/schema/scene.schema.json``. A scene is checked in two stages:

1. ``Scene.from_dict`` checks the JSON structure against the schema (types, ranges, unknown
   keys) and builds the objects, broadcasting single numbers to all bands;
2. ``Scene.validate`` runs every semantic check on the objects (per-band lengths, closed
   meshes, references, unique names, ...), so a scene built in Python is checked the same way.

Every problem is reported as a ``SceneError`` naming the object and the field.

Conventions: lengths in m, angles in degrees, coefficients in m^-1; right-handed coordinates
with z up.

The package, one concept per module, none importing another in a circle:

- ``checks``: constants and limits, ``SceneError``, the small shared checks;
- ``model``: the data classes;
- ``validation``: the semantic checks (``Scene.validate``) and ``scene_warnings``;
- ``schema_errors``: the JSON Schema check with its errors as SceneErrors;
- ``reading``: building the objects from a document (``Scene.from_dict``);
- ``writing``: a scene as its document (``Scene.to_dict``);
- ``files``: ``load_scene`` and ``save_scene``.

The data classes import none of the others; the three methods of ``Scene`` that need them are
attached here. Every name of the former single module stays importable from ``photic.scene``.
"""
from __future__ import annotations

from pathlib import Path

from . import checks, files, model, reading, schema_errors, validation, writing
from .checks import FORMAT_VERSION, PHASE_FUNCTION_PARAMS, QUANTITIES, SceneError
from .files import load_scene, save_scene
from .model import (
    Band, Camera, CDOMFluorescence, ChlorophyllFluorescence, GridField, IOPGrid, IOPProfile, IOPs, Material, MaterialTexture,
    MeshObject, OceanSurface,
    PhaseFunction, Radiometer, RadiometerArray, ScatteringComponent, Scene, Settings, Sky, Sun,
    SurfaceRoughness, TriangleMesh, WaterBody,
)
from .reading import scene_from_dict
from .schema_errors import scene_schema
from .validation import _validate_scene, check_closed_mesh, scene_warnings
from .writing import _scene_to_dict

__all__ = [
    "FORMAT_VERSION", "PHASE_FUNCTION_PARAMS", "QUANTITIES", "SceneError", "Band", "Material", "MaterialTexture",
    "PhaseFunction", "ScatteringComponent", "IOPs", "IOPProfile", "IOPGrid", "GridField", "TriangleMesh", "MeshObject",
    "OceanSurface", "SurfaceRoughness", "WaterBody", "Sun", "Sky", "Camera", "Radiometer", "RadiometerArray",
    "Settings", "Scene", "ChlorophyllFluorescence", "CDOMFluorescence", "check_closed_mesh", "load_scene", "save_scene", "scene_schema", "scene_warnings",
]


def _validate(self: Scene) -> None:
    """Run every semantic check on the scene.

    Raises
    ------
    SceneError
        For the first problem found, naming the object and the field.
    """
    _validate_scene(self)


def _to_dict(self: Scene) -> dict:
    """The scene as a JSON-serialisable dict (meshes inline, per-band values as lists)."""
    return _scene_to_dict(self)


def _from_dict(cls, d: dict, base_dir: str | Path | None = None) -> Scene:
    return scene_from_dict(cls, d, base_dir)


_from_dict.__doc__ = scene_from_dict.__doc__
Scene.validate = _validate
Scene.to_dict = _to_dict
Scene.from_dict = classmethod(_from_dict)

# The former single module's other names, private ones included (tests and tools use some).
for _module in (checks, model, validation, schema_errors, reading, writing, files):
    for _name, _value in vars(_module).items():
        if not _name.startswith("__") and _name not in globals():
            globals()[_name] = _value
del _module, _name, _value
