"""Water objects as the engine's water bodies: a closed mesh ('Water Body') or an ocean
surface ('Water Surface': flat, a wave model or a mesh patch, with its roughness and optional
bottom), each with its refractive index, its IOPs (homogeneous: ``export_iops``; a depth
profile or a 3-D grid: ``natural_waters``) and its fluorescence (``export_fluorescence``)."""
from __future__ import annotations

import math

import numpy as np

from . import export_iops, surface_modifiers
from .export_geometry import mesh_data
from .export_fluorescence import add_fluorescence
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
        ex.warn(f"{owner}: {dropped} zero-area triangle(s) skipped", ("OBJECT", obj.name))
    mesh = S.TriangleMesh(world, t)
    try:
        ex.photic.scene.check_closed_mesh(owner, mesh)
    except ex.photic.scene.SceneError as exc:
        raise ExportError(owner, "mesh (a water body must be a closed mesh with outward "
                                 "normals)", exc.message) from None
    name = obj.name if index == 0 else f"{obj.name} #{index + 1}"
    # Depths of a profile count from the top of the body; a grid defaults to its bounds.
    level = float(world[:, 2].max())
    iops = water_iops(ex, obj, level, bounds=(world.min(axis=0), world.max(axis=0)))
    water = S.WaterBody(name, "mesh", iops, ior=water_ior(ex, obj), mesh=mesh)
    add_fluorescence(ex, obj, water, level)
    ex.water.append(water)
    ex.info.triangles += len(t)


def _note_unrendered_mesh(ex, obj, key, matrix, shape: str) -> None:
    """A Flat surface renders a plane: name the modifiers and mesh shape it leaves out."""
    mods = [md for md in surface_modifiers.render_modifiers(obj)
            if md.type not in surface_modifiers.FLAT_SAFE]
    data = mesh_data(ex, obj, key) if mods or obj.type == "MESH" else None
    span = 0.0
    if data is not None and len(data[0]):
        z = transform(data[0], matrix)[:, 2]
        span = float(z.max() - z.min())
    if span <= 1e-4 and not any(md.type == "OCEAN" for md in mods):
        return
    what = (f"its modifier(s) {', '.join(repr(md.name) for md in mods)}" if mods
            else "its mesh's shape")
    ex.warn(f"Object '{obj.name}': Surface Shape is {shape}, so {what} (heights spanning "
            f"{span:.3g} m) are not rendered: a flat sea at z = {float(np.asarray(matrix)[2, 3]):.3g} m "
            f"is; set Photic > Surface Shape to Mesh Patch to render the "
            f"{'Ocean modifier' if any(md.type == 'OCEAN' for md in mods) else 'mesh'} as the sea "
            f"surface", ("OBJECT", obj.name))


def _mesh_patch(ex, obj, key, matrix, owner):
    """The evaluated mesh as the periodic sea surface: with an Ocean modifier, resampled over
    exactly one of its periods; otherwise repeated with its own extent."""
    S = ex.photic.scene
    data = mesh_data(ex, obj, key)
    if data is None or len(data[1]) == 0:
        raise ExportError(owner, "Photic > Surface Shape (photic.surface_shape)",
                          "is 'Mesh Patch' but the object has no faces")
    v, t, _, _ = data
    world = transform(v, matrix)
    ocean = surface_modifiers.ocean_modifier(obj)
    if ocean is not None:
        try:
            period = surface_modifiers.ocean_period(ocean, matrix)
        except ValueError as exc:
            raise ExportError(owner, "Rotation", f"with the Ocean modifier '{ocean.name}': {exc}") from None
        others = [md.name for md in surface_modifiers.render_modifiers(obj) if md != ocean]
        if others:
            ex.warn(f"{owner}: modifier(s) {', '.join(repr(n) for n in others)} beside the Ocean "
                    f"modifier '{ocean.name}' are rendered as evaluated, repeated with the ocean's "
                    f"period ({period[0]:.4g} x {period[1]:.4g} m): they must keep it for the "
                    f"tiles to join", ("OBJECT", obj.name))
        cells = surface_modifiers.cells_per_period(world, len(t), period)
        pv, pt, stats = surface_modifiers.resample_periodic(world, t, period, cells)
        if stats["uncovered"] > 0.01 * stats["nodes"]:
            raise ExportError(owner, f"modifier '{ocean.name}'",
                              f"the mesh covers only part of one period of the ocean "
                              f"({period[0]:.4g} x {period[1]:.4g} m: Spatial Size x Size); "
                              f"{100 * stats['uncovered'] / stats['nodes']:.0f} % of it is missing: "
                              f"use Geometry 'Generate', or a plane at least one period wide")
        if stats["folded"]:
            ex.warn(f"{owner}, modifier '{ocean.name}': its Choppiness folds the surface over in "
                    f"{stats['folded']} triangle(s) (crests curling over): rendered as the height "
                    f"field beneath; lower Choppiness", ("OBJECT", obj.name))
        ex.info.triangles += len(pt)
        return S.OceanSurface("patch", mesh=S.TriangleMesh(pv, pt), period=period)
    extent = world[:, :2].max(axis=0) - world[:, :2].min(axis=0)
    if np.any(extent <= 0):
        raise ExportError(owner, "mesh", "a water surface patch must span an area in "
                                         "x and y")
    mismatch = surface_modifiers.edge_mismatch(world)
    if mismatch is None or mismatch > 1e-4 * max(1.0, float(np.ptp(world[:, 2]))):
        why = ("its edge vertices do not pair up across the patch" if mismatch is None
               else f"its heights on opposite edges differ by up to {mismatch:.3g} m")
        ex.warn(f"{owner}: the Mesh Patch repeats every {extent[0]:.4g} x {extent[1]:.4g} m (its "
                f"extent) but does not tile: {why}, so the sea shows seams (use a wave model, an "
                f"Ocean modifier, or a mesh whose edges match)", ("OBJECT", obj.name))
    return S.OceanSurface("patch", mesh=S.TriangleMesh(world, t.astype(np.int64)),
                          period=(float(extent[0]), float(extent[1])))


def add_water_surface(ex, obj, key, matrix):
    """A 'Water Surface': the ocean above (flat, waves or a mesh patch) and its water."""
    S = ex.photic.scene
    p = obj.original.photic
    owner = _obj(obj.name)
    m = np.asarray(matrix, float)
    ex.has_ocean = True
    if p.surface_shape == "FLAT":
        surface = S.OceanSurface("flat", z=float(m[2, 3]))
        _note_unrendered_mesh(ex, obj, key, matrix, "Flat")
    elif p.surface_shape == "WAVES":
        from .waves_preview import frame_time, wave_model
        try:
            model = wave_model(ex.photic, obj.original, frame_time(ex.bscene))
        except ValueError as exc:
            raise ExportError(owner, "Photic > Sinusoids (photic.wave_sinusoids)",
                              str(exc)) from None
        surface = S.OceanSurface("waves", z=float(m[2, 3]), waves=model)
        mods = [md.name for md in surface_modifiers.render_modifiers(obj)]
        if mods:
            ex.warn(f"{owner}: Surface Shape is Wave Model, so its modifier(s) "
                    f"{', '.join(repr(n) for n in mods)} are not rendered (the wave model is; "
                    f"choose Mesh Patch to render the modifiers' surface)", ("OBJECT", obj.name))
    else:
        surface = _mesh_patch(ex, obj, key, matrix, owner)
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
        for note in ex.material_notes.get(bottom_material, ()):
            ex.warn(note, ("OBJECT", obj.name))
        if bottom_material in ex.textured:
            ex.warn(f"{owner}: the Bottom Material '{p.bottom_material.name}' has an image texture: "
                    f"the flat bottom renders its mean colour (model the sea floor as a mesh with "
                    f"UVs to render the texture)", ("OBJECT", obj.name), ("MATERIAL", p.bottom_material.name))
    # Depths of a profile count from the mean sea level (a patch's mean height).
    level = float(surface.z)
    water = S.WaterBody(obj.name, "ocean", water_iops(ex, obj, level), ior=water_ior(ex, obj),
                        surface=surface, bottom_depth=bottom_depth,
                        bottom_material=bottom_material)
    add_fluorescence(ex, obj, water, level)
    ex.water.append(water)
