"""The evaluated depsgraph as a Photic scene description (``photic.scene.Scene``).

``export_scene`` walks ``depsgraph.object_instances`` once and hands each instance, by its
type and Photic role, to the module of its concept; they collect into one shared
``ExportState``, from which the scene is assembled and validated:

==========================  =================================================================
``export_state``            the shared state (depsgraph, bands, lists being filled), ``ExportInfo``
``export_materials``        Blender materials -> reflectance per band
``export_geometry``         opaque meshes: each distinct mesh evaluated once (modifiers
                            applied) and read in bulk, its instances only add a matrix; a
                            mesh met once is flattened into the world, a mesh met more often
                            is one engine mesh per material with a transform per copy
``export_water``            water bodies and water surfaces (flat, waves, mesh patch, bottom)
``export_iops``             homogeneous IOPs and phase functions (profiles and grids:
                            ``natural_waters``)
``export_radiometers``      radiometers and radiometer arrays
``export_light``            the sun lamp
``export_world``            the world's sky (colour, Environment Texture, Sky Texture)
``export_camera``           the scene's camera or the viewport's ``ViewCamera``
``export_settings``         the render settings
``export_values``           ``ExportError`` and reading property values
==========================  =================================================================

Every problem is an ``ExportError`` naming the Blender data-block and the property, checked
where Blender's names are known; what the engine's own validation finds later is translated
back to the object it came from (``engine_error``).
"""
from __future__ import annotations

import time

import numpy as np

from .export_camera import ViewCamera, camera
from .export_geometry import GEOMETRY_TYPES, add_opaque, build_meshes, check_opaque, mesh_key
from .export_light import add_light, sun
from .export_world import sky
from .export_radiometers import add_radiometer, add_radiometer_array
from .export_settings import settings
from .export_state import ExportInfo, ExportState
from .export_values import ExportCancelled, ExportError, _obj, non_finite_transform
from .export_water import add_water_body, add_water_surface

__all__ = ["ExportCancelled", "ExportError", "ExportInfo", "ViewCamera", "engine_error",
           "export_scene"]

CHECK_EVERY = 1000  # instances between cancel checks and progress reports


def walk(ex: ExportState) -> None:
    """Every instance of the depsgraph to the module of its concept."""
    water_index: dict = {}
    estimate = max(1, len(ex.dg.objects))
    # What an instance is (its role, type and mesh key) is read once per evaluated object and
    # geometry: a Geometry Nodes or particle system's thousands of instances share a few.
    kinds: dict = {}
    for i, inst in enumerate(ex.dg.object_instances):
        if i % CHECK_EVERY == CHECK_EVERY - 1:
            if ex.test_break():
                raise ExportCancelled()
            ex.progress(min(0.99, i / max(estimate, i + 1)), f"exporting: {i + 1} instances")
        obj = inst.object
        is_instance = inst.is_instance
        original = obj.original
        data = obj.data
        which = (original.as_pointer(), 0 if data is None else data.as_pointer(), is_instance)
        kind = kinds.get(which)
        if kind is None:
            kind = kinds[which] = _kind(obj, original, is_instance)
        role, otype, key = kind
        matrix = np.array(inst.matrix_world, dtype=np.float64)
        ex.info.instances += 1
        if role == "NONE" and otype in GEOMETRY_TYPES:
            add_opaque(ex, obj, key, matrix)  # (its matrix is checked by check_opaque)
            continue
        if not np.isfinite(matrix).all() and (otype == "LIGHT" or role != "NONE"):
            raise non_finite_transform(obj)  # (it was dropped as 'zero-area triangles')
        if otype == "LIGHT":
            add_light(ex, obj, matrix)
            continue
        if otype == "CAMERA":
            continue
        if role == "RADIOMETER":
            add_radiometer(ex, original, matrix)
        elif role == "RADIOMETER_ARRAY":
            add_radiometer_array(ex, obj, key, matrix)
        elif role == "WATER_BODY":
            n = water_index.get(original.name_full, 0)
            water_index[original.name_full] = n + 1
            add_water_body(ex, obj, key, matrix, n)
        elif role == "WATER_SURFACE":
            if original.name_full in water_index:
                raise ExportError(_obj(original.name), "Photic > Role (photic.role)",
                                  "a water surface cannot be instanced")
            water_index[original.name_full] = 1
            add_water_surface(ex, obj, key, matrix)

    def is_opaque(inst) -> bool:
        obj = inst.object
        role, otype, _ = _kind(obj, obj.original, inst.is_instance)
        return role == "NONE" and otype in GEOMETRY_TYPES

    check_opaque(ex, is_opaque)


def _kind(obj, original, is_instance: bool) -> tuple:
    """(Photic role, object type, mesh key or None) of an evaluated object."""
    role = original.photic.role if hasattr(original, "photic") else "NONE"
    otype = obj.type
    key = None if otype in ("LIGHT", "CAMERA") else mesh_key(obj, is_instance)
    return role, otype, key


def export_scene(depsgraph, photic, *, view_camera: ViewCamera | None = None,
                 resolution: tuple[int, int] | None = None, progress=None, test_break=None):
    """The Photic scene of an evaluated depsgraph.

    Parameters
    ----------
    depsgraph : bpy.types.Depsgraph
        Evaluated for render (final renders) or for the viewport.
    photic : module
        The ``photic`` engine package (see ``engine_loader``).
    view_camera : ViewCamera, optional
        Render this view instead of the scene's camera (the viewport).
    resolution : (width, height), optional
        Image size; default the scene's render resolution times its percentage.
    progress : callable(fraction, text), optional
    test_break : callable() -> bool, optional
        Polled every thousand instances; True stops the export with ``ExportCancelled``.

    Returns
    -------
    (photic.scene.Scene, ExportInfo)

    Raises
    ------
    ExportError
        Naming the data-block and the property.
    ExportCancelled
    """
    t0 = time.perf_counter()
    S = photic.scene
    bscene = depsgraph.scene_eval
    if resolution is None:
        r = bscene.render
        resolution = (max(1, r.resolution_x * r.resolution_percentage // 100),
                      max(1, r.resolution_y * r.resolution_percentage // 100))
    ex = ExportState(depsgraph, photic, progress, test_break)
    walk(ex)
    scene_owner = f"Scene '{bscene.name}'"
    cam = camera(ex, view_camera, resolution)
    radiometer_count = len(ex.radiometers) + len(ex.arrays)
    if cam is None and radiometer_count == 0:
        raise ExportError(scene_owner, "Camera (scene.camera)",
                          "the scene has no camera and no Photic radiometer: nothing to render")
    meshes = build_meshes(ex)
    the_sun = sun(ex)
    the_sky = sky(ex)
    if not ex.water and not meshes and the_sun is None and the_sky.type == "black":
        raise ExportError(scene_owner, "objects", "the scene is empty for Photic: no water, no "
                                                  "objects, no sun lamp and a black sky")
    scene = S.Scene(name=bscene.name, bands=[S.Band(*b) for b in ex.bands],
                    materials=ex.materials, meshes=meshes, water=ex.water, sun=the_sun,
                    sky=the_sky, cameras=[cam] if cam is not None else [],
                    radiometers=ex.radiometers, radiometer_arrays=ex.arrays,
                    settings=settings(ex))
    try:
        scene.validate()
    except S.SceneError as exc:
        raise engine_error(exc, scene_owner) from None
    ex.info.time_s = time.perf_counter() - t0
    ex.progress(1.0, "exported")
    return scene, ex.info


_ENGINE_KINDS = {"water": "Object", "mesh": "Object", "camera": "Object", "radiometer": "Object",
                 "radiometer array": "Object", "sun": "Light (sun)", "sky": "World",
                 "settings": "Scene", "scene": "Scene"}


def engine_error(exc, scene_owner: str) -> ExportError:
    """An engine ``SceneError`` as an ``ExportError`` on the Blender object it came from."""
    label = getattr(exc, "obj", "") or ""
    fld = getattr(exc, "field", "") or ""
    message = getattr(exc, "message", None) or str(exc)
    kind, _, name = label.partition(" '")
    name = name.rstrip("'").split(" [")[0].split(" #")[0]
    owner = f"{_ENGINE_KINDS.get(kind, kind.title())} '{name}'" if name else \
        (scene_owner if kind in ("settings", "scene", "") else _ENGINE_KINDS.get(kind, kind))
    return ExportError(owner, f"Photic field '{fld}'", message)
