"""Blender materials as the engine's materials: a matte (Lambertian) reflectance per band, from
the material's Photic override or its shader nodes (``material_nodes``: the diffuse colour, an
Image Texture on UV coordinates, emission), with a note for what is not rendered. Objects
without a material get one default grey."""
from __future__ import annotations

import numpy as np

from . import bands as bandmod
from . import material_nodes
from .export_textures import ImageProblem, linear_rgb, to_bands
from .export_values import ExportError, per_band

DEFAULT_MATERIAL = "photic_default_grey"
DEFAULT_REFLECTANCE = 0.5


def material(ex, mat) -> str:
    """Engine material name of a Blender material (None: the default grey), added to
    ``ex.materials`` the first time. A textured material's UV map and Mapping transform go to
    ``ex.textured``, what it does not render to ``ex.material_notes`` (and ``ex.warn``)."""
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
    notes = ex.material_notes.setdefault(name, [])
    p = getattr(getattr(mat, "original", mat), "photic", None)
    sh = material_nodes.analyse(mat)
    texture = None
    if p is not None and p.use_override:
        refl = per_band(owner, p.reflectance, p.reflectance_bands, "Reflectance",
                        "photic.reflectance", ex.bands, "reflectance", hi=1.0)
        if sh.image is not None:
            notes.append(f"{owner}: Photic Reflectance overrides Image Texture '{sh.image_node}'")
    else:
        refl = _colour(owner, sh.colour, ex.bands)
        if sh.image is not None:
            texture, refl = _texture(ex, owner, sh, notes, refl)
            if texture is not None:
                ex.textured[name] = (sh.uv_map, sh.uv_affine)
    notes.extend(sh.notes)
    emission = None
    if sh.emission is not None:
        emission = bandmod.rgb_to_bands(sh.emission, ex.bands)
        if not np.all(np.isfinite(emission)):
            raise ExportError(owner, "Emission", f"is not finite: {list(sh.emission)}")
    for note in notes:
        ex.warn(note, ("MATERIAL", mat.name))
    ex.materials[name] = S.Material(name, refl, emission, texture)
    return name


def _colour(owner: str, rgb, bands) -> np.ndarray:
    refl = bandmod.rgb_to_bands(rgb, bands)
    if not np.all(np.isfinite(refl)):
        raise ExportError(owner, "Base Color", f"is not finite: {list(rgb)}")
    return np.clip(refl, 0.0, 1.0)


def _texture(ex, owner, sh, notes, refl):
    """(MaterialTexture, mean reflectance) of a material's image, or (None, refl) with a note."""
    S = ex.photic.scene
    try:
        rgb, note = linear_rgb(sh.image)
    except ImageProblem as exc:
        notes.append(f"{owner}, node '{sh.image_node}': {exc}: the colour is the Base Color's own "
                     f"value")
        return None, refl
    if note:
        notes.append(f"{owner}, node '{sh.image_node}': {note}")
    img = to_bands(rgb, ex.bands)
    if np.any(img > 1.0):
        notes.append(f"{owner}, node '{sh.image_node}': image values above 1 are taken as 1 (a "
                     f"reflectance)")
    img = np.clip(np.nan_to_num(img, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return (S.MaterialTexture(img, "clamp" if sh.clamp else "repeat", "closest" if sh.closest else "linear"),
            img.reshape(-1, img.shape[2]).mean(axis=0))


def uv_of(ex, mat_name: str):
    """(UV map name, affine) of a textured engine material, or None."""
    return ex.textured.get(mat_name)
