"""Water objects as the engine's water bodies: a closed mesh ('Water Body') or an ocean
surface ('Water Surface': flat, a wave model or a mesh patch, with its roughness and optional
bottom), each with its refractive index and its IOPs (homogeneous: ``export_iops``; a depth
profile or a 3-D grid: ``natural_waters``)."""
from __future__ import annotations

import math

import numpy as np

from . import export_iops
from .export_geometry import mesh_data
from .export_materials import material
from .export_values import ExportError, _obj, blender_float
from .mesh_export import drop_degenerate, transform


def water_iops(ex, obj, level: float, bounds=None):
    """Homogeneous IOPs, a depth profile or a 3-D grid (``natural_waters``). ``level``:
    the height depths are measured from (m); ``bounds``: (lo, hi) of a water body."""
    if obj.original.photic.iop_variation == "NONE":
        return export_iops.iops(ex, obj)
    from . import natural_waters
    return natural_waters.varying_iops(ex, obj, level, bounds)


def water_ior(ex, obj) -> float:
    """The water's refractive index, checked against the engine's range."""
    ior = blender_float(obj.original.photic.ior)
    p = ex.photic.parameters.PARAMETERS["water.ior"]
    if not (math.isfinite(ior) and p.contains(ior)):
        raise ExportError(_obj(obj.name), "Photic > Refractive Index (photic.ior)",
                          f"is {ior}, must be in {p.range_text()}")
    return ior


def add_water_body(ex, obj, key, matrix, index):
    """An instance of a 'Water Body' (``index``: how many instances of it came before)."""
    S = ex.photic.scene
    owner = _obj(obj.name)
    data = mesh_data(ex, obj, key)
    if data is None or len(data[1]) == 0:
        raise ExportError(owner, "Photic > Role (photic.role)",
                          "is 'Water Body' but the object has no faces: a water body must "
                          "be a closed mesh")
    v, t, _, _ = data
    world = transform(v, matrix)
    t = t.astype(np.int64)
    if np.linalg.det(np.asarray(matrix)[:3, :3]) < 0:
        t = t[:, ::-1]
    t, _, dropped = drop_degenerate(world, t)
    if dropped:
        ex.info.warnings.append(f"{owner}: {dropped} zero-area triangle(s) skipped")
    mesh = S.TriangleMesh(world, t)
    try:
        ex.photic.scene.check_closed_mesh(owner, mesh)
    except ex.photic.scene.SceneError as exc:
        raise ExportError(owner, "mesh (a water body must be a closed mesh with outward "
                                 "normals)", exc.message) from None
    name = obj.name if index == 0 else f"{obj.name} #{index + 1}"
    # Depths of a profile count from the top of the body; a grid defaults to its bounds.
    iops = water_iops(ex, obj, float(world[:, 2].max()),
                      bounds=(world.min(axis=0), world.max(axis=0)))
    ex.water.append(S.WaterBody(name, "mesh", iops, ior=water_ior(ex, obj), mesh=mesh))
    ex.info.triangles += len(t)


def add_water_surface(ex, obj, key, matrix):
    """A 'Water Surface': the ocean above (flat, waves or a mesh patch) and its water."""
    S = ex.photic.scene
    p = obj.original.photic
    owner = _obj(obj.name)
    m = np.asarray(matrix, float)
    if p.surface_shape == "FLAT":
        surface = S.OceanSurface("flat", z=float(m[2, 3]))
    elif p.surface_shape == "WAVES":
        from .waves_preview import frame_time, wave_model
        try:
            model = wave_model(ex.photic, obj.original, frame_time(ex.bscene))
        except ValueError as exc:
            raise ExportError(owner, "Photic > Sinusoids (photic.wave_sinusoids)",
                              str(exc)) from None
        surface = S.OceanSurface("waves", z=float(m[2, 3]), waves=model)
    else:
        data = mesh_data(ex, obj, key)
        if data is None or len(data[1]) == 0:
            raise ExportError(owner, "Photic > Surface Shape (photic.surface_shape)",
                              "is 'Mesh Patch' but the object has no faces")
        v, t, _, _ = data
        world = transform(v, matrix)
        extent = world[:, :2].max(axis=0) - world[:, :2].min(axis=0)
        if np.any(extent <= 0):
            raise ExportError(owner, "mesh", "a water surface patch must span an area in "
                                             "x and y")
        surface = S.OceanSurface("patch", mesh=S.TriangleMesh(world, t.astype(np.int64)),
                                 period=(float(extent[0]), float(extent[1])))
    if p.use_roughness:
        surface.roughness = S.SurfaceRoughness(
            blender_float(p.wind_speed), bool(p.roughness_anisotropic),
            blender_float(math.degrees(p.wind_direction)))
    bottom_depth = bottom_material = None
    if p.use_bottom:
        depth = blender_float(p.bottom_depth)
        if not (math.isfinite(depth) and depth > 0):
            raise ExportError(owner, "Photic > Bottom Depth (photic.bottom_depth)",
                              f"is {depth}, must be > 0")
        bottom_depth = depth
        bottom_material = material(ex, p.bottom_material)
    # Depths of a profile count from the mean sea level (a patch's mean height).
    ex.water.append(S.WaterBody(obj.name, "ocean", water_iops(ex, obj, float(surface.z)),
                                ior=water_ior(ex, obj),
                                surface=surface, bottom_depth=bottom_depth,
                                bottom_material=bottom_material))
