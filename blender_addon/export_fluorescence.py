"""A water object's fluorescence (Object > Photic > Inelastic Light) as the engine's
``ChlorophyllFluorescence`` and ``CDOMFluorescence`` (``photic.inelastic``).

The absorption that fluoresces comes from the water's natural-water model where it has one
(its Water Type, an IOP Model, a Chlorophyll Maximum profile): the Case-1 models' phytoplankton
and the models' CDOM, as ``photic.iop_models.fluorescent_absorption`` gives them. For IOPs
given as coefficients (or a layer table) it is the Phytoplankton / CDOM Share of the water's
total absorption in each band (and each layer). A grid's fluorescence is its base's (the
engine's rule: the grid's fields do not fluoresce)."""
from __future__ import annotations

import json

import numpy as np

from . import water_types
from .export_values import ExportError, _obj, blender_float, per_band

#: property prefix -> (fluorescent_absorption's part, the share's UI name, the process's)
PROCESSES = {"chl": ("phytoplankton", "Phytoplankton Share of a", "Chlorophyll Fluorescence"),
             "cdom": ("cdom", "CDOM Share of a", "CDOM Fluorescence")}
ABSORBERS = {"chl": "phytoplankton absorb", "cdom": "CDOM absorbs"}


def from_model(p) -> bool:
    """Whether a water object's fluorescent absorption comes from its IOP model (else from
    the shares of its coefficients' absorption)."""
    if p.iop_variation in ("PROFILE", "PROFILE_GRID"):
        return p.profile_kind == "CHLOROPHYLL"
    return water_types.effective(p) != water_types.CUSTOM or p.iop_source == "MODEL"


def add_fluorescence(ex, obj, water, level: float) -> None:
    """Set ``water``'s ``fluorescence`` and ``cdom_fluorescence`` (an engine ``WaterBody``
    with its IOPs) from the object's Inelastic Light settings; ``level``: the height its
    depth profile counts from, as for its IOPs."""
    p = obj.original.photic
    if not (p.chl_fluorescence or p.cdom_fluorescence):
        return
    S = ex.photic.scene
    owner = _obj(obj.name)
    modelled = model_absorption(ex, obj, level) if from_model(p) else None
    got = {}
    for key in PROCESSES:
        if getattr(p, f"{key}_fluorescence"):
            got[key] = (modelled[PROCESSES[key][0]] if modelled is not None
                        else shared(ex, owner, p, water.iops, key))
            _warn_if_dark(ex, obj, key, got[key], modelled is not None)
    if "chl" in got:
        water.fluorescence = S.ChlorophyllFluorescence(
            got["chl"], blender_float(p.chl_quantum_yield), blender_float(p.chl_emission_peak_nm),
            blender_float(p.chl_emission_fwhm_nm))
    if "cdom" in got:
        water.cdom_fluorescence = S.CDOMFluorescence(got["cdom"],
                                                     blender_float(p.cdom_efficiency_scale))
    if modelled is None and len(got) == 2:  # (each share is at most 1; both, too)
        over = np.atleast_2d(got["chl"] + got["cdom"]) > _layers(water.iops) * (1 + 1e-12)
        if np.any(over):
            band = ex.bands[int(np.nonzero(over.any(axis=0))[0][0])][0]
            raise ExportError(owner, f"Photic > {_share_prop(p, 'chl')} + {_share_prop(p, 'cdom')}",
                              f"add up to more than 1 in band {band} nm: both are parts of the "
                              f"water's absorption, together at most all of it")


def _layers(iops) -> np.ndarray:
    """The water's own absorption per layer (one row for homogeneous water; a grid's base)."""
    base = iops.iops if hasattr(iops, "density") else iops
    layers = base.layers if hasattr(base, "layers") else [base]
    return np.array([np.asarray(x.absorption, float) for x in layers])


def _share_prop(p, key: str) -> str:
    """The share property of ``key`` in use (its per-band list, or its value), as errors name it."""
    name = PROCESSES[key][1]
    return (f"{name} per Band (photic.{key}_fraction_bands)"
            if getattr(p, f"{key}_fraction_bands").strip() else f"{name} (photic.{key}_fraction)")


def shared(ex, owner: str, p, iops, key: str) -> np.ndarray:
    """The share (``<key>_fraction``, per band) of the water's absorption: one spectrum, or
    one per layer of a depth profile."""
    _, name, _ = PROCESSES[key]
    share = per_band(owner, getattr(p, f"{key}_fraction"), getattr(p, f"{key}_fraction_bands"),
                     f"Photic > {name}", f"photic.{key}_fraction", ex.bands, "share", hi=1.0)
    a = share * _layers(iops)
    return a[0] if len(a) == 1 else a


def model_absorption(ex, obj, level: float) -> dict:
    """{"phytoplankton": a_ph, "cdom": a_CDOM} (m^-1 per band; per layer for a Chlorophyll
    Maximum profile, depth-averaged as its IOPs are) of the water's IOP model."""
    S = ex.photic.scene
    from photic.iop_models import fluorescent_absorption
    p = obj.original.photic
    owner = _obj(obj.name)
    bands = [S.Band(*b) for b in ex.bands]
    if p.iop_variation in ("PROFILE", "PROFILE_GRID"):
        from photic.profiles import profile_from_function
        from .natural_waters import chlorophyll_model
        model, tops, _, _ = chlorophyll_model(obj, level)
        nb = len(bands)

        def both(z):  # (both parts as one "absorption", averaged over each layer as the IOPs)
            d = fluorescent_absorption(model(z), bands, obj=owner)
            return S.IOPs(np.concatenate([d["phytoplankton"], d["cdom"]]), [])

        # (the model's errors were met first, by the profile's IOPs)
        rows = np.array([x.absorption for x in profile_from_function(both, tops).layers])
        rows = rows[0] if len(rows) == 1 else rows
        return {"phytoplankton": rows[..., :nb], "cdom": rows[..., nb:]}
    kind = water_types.effective(p)
    if kind != water_types.CUSTOM:
        spec = water_types.model(kind)
        prop = f"Photic > Water Type '{water_types.TYPES[kind][0]}' (photic.water_type)"
    else:
        spec, prop = json.loads(p.iop_model), "Photic > IOP Model (photic.iop_model)"
    try:  # (the IOPs read the same model before: its errors were met there)
        return fluorescent_absorption(spec, bands, obj=owner)
    except S.SceneError as exc:
        raise ExportError(owner, prop, f"field '{exc.field}': {exc.message}") from None


def _warn_if_dark(ex, obj, key: str, a: np.ndarray, modelled: bool) -> None:
    """A process that is on but absorbs nothing adds no light: say why, on the object."""
    if np.any(np.asarray(a) > 0):
        return
    _, share, process = PROCESSES[key]
    if not modelled:
        why = f"its {share} is 0: set Photic > Inelastic Light > {share}"
    elif key == "chl":
        why = ("its IOP model has no phytoplankton: give it a Case-1 model (IOPs 'IOP Model', "
               "\"model\": \"case1\"; or a Chlorophyll Maximum profile) or Coefficients with a "
               "Phytoplankton Share of a")
    else:
        why = ("its IOP model has no CDOM: give it a CDOM or Case-1 model, or Coefficients "
               "with a CDOM Share of a")
    ex.warn(f"{_obj(obj.name)}: {process} is on but the water's {ABSORBERS[key]} nothing in any "
            f"band, so it adds no light; {why}", ("OBJECT", obj.name))
