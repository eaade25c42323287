"""A scene as its JSON document (``Scene.to_dict``), meshes inline, and the compact JSON text.
"""
from __future__ import annotations

import json
import numbers
from typing import Any

import numpy as np

from .checks import FORMAT_VERSION
from .model import IOPGrid, IOPProfile, IOPs, PhaseFunction, Scene, TriangleMesh, WaterBody
from .reading import _SINUSOID_KEYS, _WAVE_KEYS


# ----------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------

def _list(a: Any) -> list:
    return np.asarray(a).tolist()


def _mesh_to_dict(mesh: TriangleMesh) -> dict:
    return {"vertices": _list(mesh.vertices), "triangles": _list(mesh.triangles)}


def _material_to_dict(m) -> dict:
    d: dict[str, Any] = {"type": "lambertian", "reflectance": _list(m.reflectance)}
    if m.emission is not None:
        d["emission"] = _list(m.emission)
    if m.texture is not None:
        d["texture"] = {"image": _list(m.texture.image), "wrap": m.texture.wrap,
                        "interpolation": m.texture.interpolation}
    return d


def _phase_to_dict(p: PhaseFunction) -> dict:
    return {"type": p.type, **{k: float(v) for k, v in p.params.items()}}


def _profile_to_dict(p: IOPProfile) -> dict:
    return {"z_top": _list(p.z_top), "layers": [{"iops": _iops_to_dict(x)} for x in p.layers]}


def _iops_to_dict(iops: IOPs) -> dict:
    return {"absorption": _list(iops.absorption),
            "scattering": [{"b": _list(c.b), "phase": _phase_to_dict(c.phase)}
                           for c in iops.scattering]}


def _water_to_dict(w: WaterBody) -> dict:
    d: dict[str, Any] = {"name": w.name, "type": w.type, "ior": float(w.ior)}
    if isinstance(w.iops, IOPProfile):
        d["iop_profile"] = _profile_to_dict(w.iops)
    elif isinstance(w.iops, IOPGrid):
        g = w.iops
        base = ({"iop_profile": _profile_to_dict(g.iops)} if isinstance(g.iops, IOPProfile)
                else {"iops": _iops_to_dict(g.iops)})
        d["iop_grid"] = {"base": base,
                         "unit": {"iops": _iops_to_dict(g.unit)},
                         "origin": _list(g.origin), "size": _list(g.size)}
        if g.file is not None:
            d["iop_grid"]["file"] = g.file
        else:
            d["iop_grid"]["density"] = np.asarray(g.density, dtype=np.float64).tolist()
        if g.extra_fields:
            d["iop_grid"]["fields"] = [
                {"name": f.name, "unit": {"iops": _iops_to_dict(f.unit)},
                 **({"key": f.key} if f.key is not None and g.file is not None
                    else {"density": np.asarray(f.density, dtype=np.float64).tolist()})}
                for f in g.extra_fields]
    else:
        d["iops"] = _iops_to_dict(w.iops)
    if w.type == "mesh":
        d.update(_mesh_to_dict(w.mesh))
        return d
    s = w.surface
    if s.kind == "flat":
        d["surface"] = {"kind": "flat", "z": float(s.z)}
    elif s.kind == "waves":
        d["surface"] = {"kind": "waves", "z": float(s.z), **_wave_model_to_dict(s.waves)}
    elif s.plugin is not None:
        d["surface"] = {"kind": "plugin", **s.plugin}
    else:
        d["surface"] = {"kind": "patch", **_mesh_to_dict(s.mesh),
                        "period": [float(p) for p in s.period]}
    if s.roughness is not None:
        d["surface"]["roughness"] = {"wind_speed": float(s.roughness.wind_speed),
                                     "anisotropic": bool(s.roughness.anisotropic)}
        if s.roughness.wind_direction_deg is not None:
            d["surface"]["roughness"]["wind_direction_deg"] = float(s.roughness.wind_direction_deg)
    d["bottom"] = None if w.bottom_depth is None else {"depth": float(w.bottom_depth),
                                                       "material": w.bottom_material}
    if w.fluorescence is not None:
        f = w.fluorescence
        d["chlorophyll_fluorescence"] = {"absorption": np.asarray(f.absorption, float).tolist(),
                                         "quantum_yield": float(f.quantum_yield), "peak_nm": float(f.peak_nm),
                                         "fwhm_nm": float(f.fwhm_nm)}
    if w.cdom_fluorescence is not None:
        f = w.cdom_fluorescence
        d["cdom_fluorescence"] = {"absorption": np.asarray(f.absorption, float).tolist(),
                                  "efficiency_scale": float(f.efficiency_scale)}
    return d


def _scene_to_dict(s: Scene) -> dict:
    sky: dict[str, Any] = {"type": s.sky.type}
    if s.sky.radiance_scale is not None:
        # L0 itself is written (not an irradiance) so that reading it back is bit-exact.
        sky["radiance"] = _list(s.sky.radiance_scale)
    if s.sky.full_sphere:
        sky["full_sphere"] = True
    if s.sky.cloud_fraction:
        sky["cloud_fraction"] = float(s.sky.cloud_fraction)
    if s.sky.table is not None:
        sky["table"] = _list(s.sky.table)
    arrays = []
    for a in s.radiometer_arrays:
        item: dict[str, Any] = {"name": a.name, "quantities": list(a.quantities),
                                "positions": _list(a.positions)}
        if a.direction is not None:
            item["direction"] = _list(a.direction)
        if a.half_angle_deg is not None:
            item["half_angle_deg"] = float(a.half_angle_deg)
        arrays.append(item)
    return {
        "photic_scene": FORMAT_VERSION,
        "name": s.name,
        "bands": [{"name": b.name, "center_nm": float(b.center_nm), "width_nm": float(b.width_nm)}
                  for b in s.bands],
        "materials": {k: _material_to_dict(m) for k, m in s.materials.items()},
        "meshes": [{"name": m.name, "material": m.material, **_mesh_to_dict(m.mesh),
                    **({} if m.uv is None else {"uv": _list(m.uv)}),
                    **({} if m.instances is None else {"instances": _list(m.instances)})}
                   for m in s.meshes],
        "water": [_water_to_dict(w) for w in s.water],
        "sun": None if s.sun is None else {
            "zenith_deg": float(s.sun.zenith_deg), "azimuth_deg": float(s.sun.azimuth_deg),
            "irradiance": _list(s.sun.irradiance),
            "angular_diameter_deg": float(s.sun.angular_diameter_deg)},
        "sky": sky,
        "cameras": [{"name": c.name, "type": c.type, "position": _list(c.position),
                     "direction": _list(c.direction), "up": _list(c.up),
                     "fov_deg": float(c.fov_deg), "ortho_width": float(c.ortho_width),
                     "resolution": [int(n) for n in c.resolution],
                     "filter": {"type": c.filter_type, "width_px": float(c.filter_width_px)},
                     "shift": [float(x) for x in c.shift], "clip_start": float(c.clip_start)}
                    for c in s.cameras],
        "radiometers": [{"name": r.name, "quantity": r.quantity, "position": _list(r.position),
                         "direction": _list(r.direction),
                         "half_angle_deg": float(r.half_angle_deg),
                         "polar_bins": int(r.polar_bins), "azimuth_bins": int(r.azimuth_bins)}
                        for r in s.radiometers],
        "radiometer_arrays": arrays,
        "settings": {"integrator": s.settings.integrator, "samples": int(s.settings.samples),
                     "radiometer_samples": int(s.settings.radiometer_samples),
                     "seed": int(s.settings.seed), "max_depth": int(s.settings.max_depth),
                     "threads": int(s.settings.threads),
                     "forward_cone_deg": s.settings.forward_cone_deg,
                     "beam_max_level": int(s.settings.beam_max_level),
                     "sun_disk_blur": bool(s.settings.sun_disk_blur),
                     **({"raman": bool(s.settings.raman)} if s.settings.raman != "auto" else {}),
                     **({} if s.settings.target_error is None else
                        {"target_error": float(s.settings.target_error)}),
                     **({} if s.settings.noise_threshold is None else
                        {"noise_threshold": float(s.settings.noise_threshold),
                         "adaptive_min_samples": int(s.settings.adaptive_min_samples)})},
    }


def _dumps(obj: Any, level: int = 0) -> str:
    """JSON text with lists of numbers on one line (so meshes stay one vertex per line)."""
    inner = "  " * (level + 1)
    if isinstance(obj, dict) and obj:
        items = [f"{inner}{json.dumps(k)}: {_dumps(v, level + 1)}" for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + "  " * level + "}"
    if isinstance(obj, list) and any(isinstance(x, (dict, list)) for x in obj):
        return "[\n" + ",\n".join(inner + _dumps(x, level + 1) for x in obj) + "\n" + \
            "  " * level + "]"
    return json.dumps(obj)


def _wave_model_to_dict(model: Any) -> dict:
    d: dict[str, Any] = {}
    for key in _WAVE_KEYS:
        value = getattr(model, key)
        if key == "sinusoids":
            if model.spectrum != "sinusoids":
                continue
            value = [dict(zip(_SINUSOID_KEYS, map(float, c))) for c in value]
        elif key in ("patch_size_m",):
            value = [float(x) for x in value]
        elif key == "resolution":
            value = [int(x) for x in value]
        elif key in ("seed", "mesh_refinement"):
            value = int(value)
        elif key in ("fetch_m", "water_depth_m") and value is None:
            continue
        elif isinstance(value, numbers.Real) and not isinstance(value, bool):
            value = float(value)
        d[key] = value
    return d
