"""A water object's inherent optical properties (IOPs) where they are the same everywhere:
from coefficients per band (with pure water added for 'Pure Water + Additions') or from a
model description in JSON, with the object's phase function. Depth profiles and 3-D grids
(``natural_waters``) build their layers and unit IOPs from these functions."""
from __future__ import annotations

import math

import numpy as np

from . import water_types
from .export_values import ExportError, _obj, blender_float, per_band


def iops(ex, obj):
    """The water's IOPs from its Water Type, or for 'Custom' from its IOP source (the base
    IOPs of a grid)."""
    p = obj.original.photic
    owner = _obj(obj.name)
    kind = water_types.effective(p)
    if kind != water_types.CUSTOM:
        return model_iops(ex, owner, water_types.model_json(kind),
                          f"Photic > Water Type '{water_types.TYPES[kind][0]}' (photic.water_type)")
    if p.iop_source == "MODEL":
        return model_iops(ex, owner, p.iop_model, "Photic > IOP Model (photic.iop_model)")
    a = per_band(owner, p.absorption, p.absorption_bands, "Photic > Absorption",
                 "photic.absorption", ex.bands, "absorption coefficient")
    b = per_band(owner, p.scattering, p.scattering_bands, "Photic > Scattering",
                 "photic.scattering", ex.bands, "scattering coefficient")
    return coefficient_iops(ex, owner, p, a, b)


def model_iops(ex, owner: str, text: str, prop: str, defaults: dict | None = None):
    """IOPs from a model description in JSON (``defaults`` fill top-level fields it lacks)."""
    import json
    S = ex.photic.scene
    try:
        spec = json.loads(text)
    except ValueError as exc:
        raise ExportError(owner, prop, f"is not valid JSON: {exc}") from None
    except RecursionError:  # (it was 'internal error: RecursionError')
        raise ExportError(owner, prop, "is nested too deeply (lists or objects inside one "
                                       "another hundreds of levels deep): a model description "
                                       "is a few levels at most") from None
    if not isinstance(spec, dict):
        raise ExportError(owner, prop, "must be a JSON object such as "
                                       "{\"model\": \"cdom\", \"a_ref\": 0.1}")
    spec = {**(defaults or {}), **spec}
    from photic.iop_models import iops_from_model
    try:
        return iops_from_model(spec, [S.Band(*b) for b in ex.bands], obj=owner)
    except S.SceneError as exc:
        raise ExportError(owner, prop, f"field '{exc.field}': {exc.message}") from None
    except RecursionError:
        raise ExportError(owner, prop, "is nested too deeply: a model description is a few "
                                       "levels at most") from None


def phase_function(ex, owner: str, kind: str, g: float, backscatter: float,
                   prefix: str = "Photic > "):
    """A phase function from the enum and its parameter properties."""
    S = ex.photic.scene
    params = {}
    if kind == "henyey_greenstein":
        params = {"g": blender_float(g)}
    elif kind == "fournier_forand":
        params = {"backscatter_fraction": blender_float(backscatter)}
    for pname, value in params.items():
        if not math.isfinite(value):
            raise ExportError(owner, f"{prefix}phase function parameter {pname}",
                              f"is {value}")
    return S.PhaseFunction(kind, params)


def coefficient_iops(ex, owner: str, p, a, b):
    """IOPs from coefficients per band with the object's phase function; pure water added
    for the source 'Pure Water + Additions'."""
    S = ex.photic.scene
    phase = phase_function(ex, owner, p.phase_function, p.hg_g, p.ff_backscatter)
    scattering = [S.ScatteringComponent(b, phase)] if np.any(b > 0) else []
    if p.iop_source == "PURE_WATER":
        models = ex.photic.iop_models
        bands = [(c, w) for _, c, w in ex.bands]
        try:
            a = a + models.pure_water_absorption(bands)
        except ValueError as exc:
            raise ExportError(owner, "Photic > IOPs (photic.iop_source)",
                              f"pure water: {exc}; choose bands within it or give the "
                              f"coefficients") from None
        b_w = models.pure_seawater_scattering(bands)
        scattering.insert(0, S.ScatteringComponent(b_w, S.PhaseFunction("pure_water")))
    return S.IOPs(a, scattering)
