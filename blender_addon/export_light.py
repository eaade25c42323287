"""The sun: the one sun lamp as the engine's sun (direction, irradiance per band, angular
diameter). Other lamp types are not used, with a warning on the lamp. The sky: ``export_world``."""
from __future__ import annotations

import math

import numpy as np

from . import bands as bandmod
from .export_values import ExportError, _finite_non_negative, blender_float, per_band


def add_light(ex, obj, matrix):
    """A lamp instance: kept when it is a sun (``sun`` then checks there is only one)."""
    light = obj.data
    if light.type != "SUN":
        ex.warn(f"Light '{obj.name}': {light.type.lower()} lights are not used by Photic (only "
                f"sun lamps; an emitting mesh renders as a light)", ("OBJECT", obj.name),
                ("LIGHT", light.name))
        return
    if getattr(light, "use_nodes", False) and getattr(light, "node_tree", None) is not None:
        ex.warn(f"Light '{obj.name}': its shader nodes are not rendered (Strength and Color are)",
                ("OBJECT", obj.name), ("LIGHT", light.name))
    ex.suns.append((obj, np.asarray(matrix, float)))


def sun(ex):
    """The engine's sun from the scene's sun lamp (None without one)."""
    S = ex.photic.scene
    if not ex.suns:
        return None
    if len(ex.suns) > 1:
        names = " and ".join(f"'{o.name}'" for o, _ in ex.suns)
        raise ExportError(f"Light '{ex.suns[1][0].name}'", "type",
                          f"Photic uses one sun lamp; the scene has {names} (hide or delete "
                          f"all but one from the render)")
    obj, m = ex.suns[0]
    owner = f"Light '{obj.name}'"
    towards = m[:3, 2]
    norm = np.linalg.norm(towards)
    if not norm > 0:
        raise ExportError(owner, "Scale", "is zero: the sun has no direction")
    towards = towards / norm
    # Blender keeps rotations in float32 (about 1e-5 degrees): angles are rounded to 1e-4
    # degrees so that a sun set to 30 degrees exports as exactly 30.
    zenith = round(math.degrees(math.acos(max(-1.0, min(1.0, towards[2])))), 4)
    if zenith >= 90.0:
        raise ExportError(owner, "Rotation", f"puts the sun below the horizon (zenith angle "
                                             f"{zenith:.1f} degrees; the lamp shines along "
                                             f"its -Z axis and must point downwards)")
    azimuth = round(math.degrees(math.atan2(towards[1], towards[0])), 4) % 360.0 + 0.0
    light = obj.data
    # (the original ID's: editing a custom property does not always re-evaluate the lamp)
    lp = getattr(getattr(light, "original", None) or light, "photic", None)
    if lp is not None and lp.irradiance_bands.strip():
        irradiance = per_band(owner, 0.0, lp.irradiance_bands, "Irradiance",
                              "data.photic.irradiance", ex.bands, "sun irradiance")
    else:
        strength = blender_float(light.energy)
        if not (math.isfinite(strength) and strength >= 0):
            raise ExportError(owner, "Strength (data.energy)",
                              f"is {strength}, must be a finite irradiance >= 0 W m^-2")
        colour = tuple(blender_float(c) for c in light.color)
        irradiance = strength * bandmod.rgb_to_bands(colour, ex.bands)
        _finite_non_negative(owner, "Color (data.color)", irradiance, "sun irradiance")
    diameter = blender_float(math.degrees(light.angle))
    p = ex.photic.parameters.PARAMETERS["sun.angular_diameter_deg"]
    if not p.contains(diameter):
        raise ExportError(owner, "Angle (data.angle)", f"is {diameter:.3g} degrees; "
                                                       f"Photic's sun disk must be in "
                                                       f"{p.range_text()} degrees (the real "
                                                       f"sun: 0.53)")
    return S.Sun(zenith, azimuth, irradiance, angular_diameter_deg=diameter)
