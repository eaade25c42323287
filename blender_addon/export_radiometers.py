"""Objects with the role 'Radiometer' or 'Radiometer Array' as the engine's radiometers: a
single radiometer at the object looking along its -Z axis, or an array of them at the
object's mesh vertices, along a line or on a grid."""
from __future__ import annotations

import math

import numpy as np

from .export_geometry import GEOMETRY_TYPES, mesh_data
from .export_values import ExportError, _obj, blender_float
from .mesh_export import transform


def add_radiometer(ex, obj, matrix):
    """A 'Radiometer' (``obj``: the original object)."""
    S = ex.photic.scene
    p = obj.original.photic
    m = np.asarray(matrix, float)
    direction = -m[:3, 2]
    if not np.linalg.norm(direction) > 0:
        raise ExportError(_obj(obj.name), "Scale", "is zero: the radiometer has no direction")
    ex.radiometers.append(S.Radiometer(
        obj.name, p.quantity, m[:3, 3].copy(), direction / np.linalg.norm(direction),
        half_angle_deg=blender_float(math.degrees(p.half_angle)), polar_bins=int(p.polar_bins),
        azimuth_bins=int(p.azimuth_bins)))


def add_radiometer_array(ex, obj, key, matrix):
    """A 'Radiometer Array' (its layout: the mesh's vertices, a line or a grid)."""
    S = ex.photic.scene
    p = obj.original.photic
    owner = _obj(obj.name)
    m = np.asarray(matrix, float)
    quantities = [q for q in ex.photic.scene.QUANTITIES if q in p.quantities]
    if not quantities:
        raise ExportError(owner, "Photic > Quantities (photic.quantities)",
                          "none chosen: a radiometer array needs at least one quantity")
    if p.array_layout == "VERTICES":
        data = mesh_data(ex, obj, key) if obj.type in GEOMETRY_TYPES else None
        local = data[0] if data is not None else np.zeros((0, 3), np.float32)
        where = "the object has no mesh vertices"
    else:
        n = int(p.array_count)
        s = float(p.array_spacing)
        k = np.arange(n, dtype=float) * s
        if p.array_layout == "LINE":
            local = np.stack([np.zeros(n), np.zeros(n), -k], axis=1)
        else:
            c = k - k.mean() if n else k
            gx, gy = np.meshgrid(c, c, indexing="ij")
            local = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
        where = "Photic > Count (photic.array_count) is 0"
    if len(local) == 0:
        raise ExportError(owner, "Photic > Layout (photic.array_layout)",
                          f"the radiometer array has no elements: {where}")
    positions = transform(np.asarray(local, np.float64), m)
    if len(np.unique(np.round(positions, 9), axis=0)) < len(positions):
        raise ExportError(owner, "Photic > Spacing (photic.array_spacing)",
                          "two radiometers of the array are at the same place")
    direction = -m[:3, 2]
    direction = direction / np.linalg.norm(direction) if np.linalg.norm(direction) > 0 \
        else np.array([0.0, 0.0, -1.0])
    ex.arrays.append(S.RadiometerArray(obj.name, quantities, positions, direction=direction,
                                       half_angle_deg=blender_float(math.degrees(p.half_angle))))
