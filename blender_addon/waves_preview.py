"""Wave-model water surfaces in Blender: the model of an object, and its mesh as a preview.

The render never uses the preview mesh: the export rebuilds the surface from the model at the
frame's time, with the model's exact normals. The preview is regenerated when a wave setting
changes and on every frame change (so the animation plays in the viewport).
"""
from __future__ import annotations

import math

import bpy
from bpy.app.handlers import persistent

from .engine_loader import load_engine


def frame_time(scene) -> float:
    """Seconds of the current frame (the waves' time)."""
    fps = scene.render.fps / scene.render.fps_base
    return scene.frame_current / fps


def parse_sinusoids(text: str) -> tuple:
    """'a:lambda:dir:phase, ...' as ((amplitude m, wavelength m, direction deg, phase rad), ...);
    ValueError naming the bad item."""
    waves = []
    for i, item in enumerate(t.strip() for t in text.split(",") if t.strip()):
        parts = item.split(":")
        try:
            values = [float(x) for x in parts]
        except ValueError:
            values = []
        if not 2 <= len(values) <= 4:
            raise ValueError(f"wave {i + 1} ({item!r}) must be "
                             f"'amplitude_m:wavelength_m[:direction_deg[:phase_rad]]'")
        waves.append(tuple(values + [0.0] * (4 - len(values))))
    if not waves:
        raise ValueError("is empty: list at least one wave")
    return tuple(waves)


def wave_model(photic, obj, time_s: float):
    """The ``photic.waves.WaveModel`` of an object with surface shape 'Wave Model' (ValueError
    for a bad 'Sinusoids' list)."""
    p = obj.photic
    n = int(p.wave_resolution)
    size = float(f"{p.wave_patch_size:.7g}")
    return photic.waves.WaveModel(
        spectrum=p.wave_spectrum, wind_speed=float(f"{p.wind_speed:.7g}"),
        wind_direction_deg=float(f"{math.degrees(p.wind_direction):.7g}"),
        patch_size_m=(size, size), resolution=(n, n), seed=int(p.wave_seed), time_s=time_s,
        choppiness=float(f"{p.choppiness:.7g}"),
        water_depth_m=float(p.wave_depth) if p.wave_depth > 0 else None,
        fetch_m=float(p.fetch) if p.wave_spectrum == "jonswap" else None,
        sinusoids=parse_sinusoids(p.wave_sinusoids) if p.wave_spectrum == "sinusoids" else (),
        mesh_refinement=int(p.wave_mesh_refinement))


def restore_mesh(obj) -> None:
    """Give an object back the mesh it had before a Wave Model preview stood in for it (the
    preview mesh is removed when nothing else uses it)."""
    p = obj.photic
    own = p.flat_mesh
    if own is None:
        return
    preview = obj.data
    obj.data = own
    own.use_fake_user = False
    p.flat_mesh = None
    if preview is not None and preview is not own and preview.users == 0:
        bpy.data.meshes.remove(preview)


def _preview_mesh(obj):
    """The mesh that shows an object's wave patch: a mesh of its own, so that the object's
    mesh is kept (in ``photic.flat_mesh``, with a fake user) and given back by restore_mesh."""
    p = obj.photic
    if p.flat_mesh is not None and obj.data is not p.flat_mesh:
        return obj.data
    own = obj.data
    own.use_fake_user = True
    p.flat_mesh = own
    preview = bpy.data.meshes.new(f"{obj.name} Waves")
    for m in own.materials:
        preview.materials.append(m)
    obj.data = preview
    return preview


def update_object(obj, scene=None) -> str | None:
    """Show the wave patch of an object's model as its mesh (a preview mesh of its own), or,
    when its Surface Shape is no longer Wave Model, give it back its mesh; returns an error or
    None."""
    if obj is None or obj.type != "MESH" or obj.photic.role != "WATER_SURFACE":
        return None
    if obj.photic.surface_shape != "WAVES":
        restore_mesh(obj)
        return None
    photic = load_engine()
    if photic is None:
        return "the Photic engine is unavailable"
    scene = scene or bpy.context.scene
    try:
        model = wave_model(photic, obj, frame_time(scene))
        # (the grid's mesh: a refined one is the same surface, r^2 times heavier to draw)
        vertices, triangles, _ = photic.waves.surface_patch(model.replace(mesh_refinement=1), 0.0)
    except (ValueError, photic.scene.SceneError) as exc:
        return str(exc)
    mesh = _preview_mesh(obj)
    mesh.clear_geometry()
    mesh.vertices.add(len(vertices))
    mesh.vertices.foreach_set("co", vertices.astype("float32").ravel())
    nt = len(triangles)
    mesh.loops.add(3 * nt)
    mesh.loops.foreach_set("vertex_index", triangles.astype("int32").ravel())
    mesh.polygons.add(nt)
    import numpy as np
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * nt, 3, dtype=np.int32))
    if bpy.app.version < (4, 0, 0):
        mesh.polygons.foreach_set("loop_total", np.full(nt, 3, np.int32))
    mesh.update()
    return None


@persistent
def on_frame_change(scene, depsgraph=None):
    for obj in scene.objects:
        if obj.type == "MESH" and obj.photic.role == "WATER_SURFACE" and \
                obj.photic.surface_shape == "WAVES":
            update_object(obj, scene)


def register():
    if on_frame_change not in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.append(on_frame_change)


def unregister():
    if on_frame_change in bpy.app.handlers.frame_change_post:
        bpy.app.handlers.frame_change_post.remove(on_frame_change)
