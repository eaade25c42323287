"""Blender materials as the engine's materials: a reflectance per band, from the material's
Photic override or its base colour (Principled BSDF, else Diffuse BSDF, else the viewport
colour). Objects without a material get one default grey."""
from __future__ import annotations

import numpy as np

from . import bands as bandmod
from .export_values import ExportError, per_band
from .nodes import find_node

DEFAULT_MATERIAL = "photic_default_grey"
DEFAULT_REFLECTANCE = 0.5


def material(ex, mat) -> str:
    """Engine material name of a Blender material (None: the default grey), added to
    ``ex.materials`` the first time."""
    S = ex.photic.scene
    if mat is None:
        if DEFAULT_MATERIAL not in ex.materials:
            ex.materials[DEFAULT_MATERIAL] = S.Material(
                DEFAULT_MATERIAL, np.full(len(ex.bands), DEFAULT_REFLECTANCE))
        return DEFAULT_MATERIAL
    name = mat.name_full if hasattr(mat, "name_full") else mat.name
    if name in ex.materials:
        return name
    owner = f"Material '{mat.name}'"
    p = getattr(getattr(mat, "original", mat), "photic", None)
    if p is not None and p.use_override:
        refl = per_band(owner, p.reflectance, p.reflectance_bands, "Reflectance",
                        "photic.reflectance", ex.bands, "reflectance", hi=1.0)
    else:
        rgb = base_colour(mat)
        refl = bandmod.rgb_to_bands(rgb, ex.bands)
        if not np.all(np.isfinite(refl)):
            raise ExportError(owner, "Base Color", f"is not finite: {list(rgb)}")
        refl = np.clip(refl, 0.0, 1.0)
    ex.materials[name] = S.Material(name, refl)
    return name


def base_colour(mat):
    """Base colour of the material's Principled BSDF, else its viewport colour."""
    node = find_node(mat, "BSDF_PRINCIPLED")
    if node is not None:
        return tuple(node.inputs["Base Color"].default_value)[:3]
    node = find_node(mat, "BSDF_DIFFUSE")
    if node is not None:
        return tuple(node.inputs["Color"].default_value)[:3]
    return tuple(mat.diffuse_color)[:3]
