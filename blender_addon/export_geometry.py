"""Opaque geometry: each distinct evaluated mesh is read once (``mesh_data``), its instances
only add a world matrix, and all instances of a mesh that share a material become one engine
mesh (``build_meshes``). Water and radiometer arrays read their meshes through ``mesh_data``
too."""
from __future__ import annotations

import numpy as np

from .export_materials import DEFAULT_MATERIAL, material, uv_of
from .export_values import _obj
from .mesh_export import drop_degenerate, evaluated_mesh, mesh_arrays, transform

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD"}


def mesh_key(obj, is_instance: bool = False) -> tuple:
    """The key an evaluated object's mesh is read and grouped under."""
    # Geometry is keyed by the mesh data when the object has no modifiers, so linked
    # duplicates share one evaluated mesh; otherwise by the object. An instance (a collection
    # or geometry-nodes instance) is keyed by its own evaluated geometry too: the instances a
    # Geometry Nodes modifier makes share the instancer as their original object, but each
    # has the geometry it instances (a sphere on a seabed plane is not the plane).
    original = obj.original
    data = getattr(original, "data", None)
    if is_instance:
        geometry = getattr(obj, "data", None)
        return ("instance", original.name_full, geometry.as_pointer() if geometry is not None else 0)
    if data is not None and not getattr(original, "modifiers", None) and obj.type == "MESH":
        return ("mesh", data.name_full)
    return ("object", original.name_full)


def mesh_data(ex, obj, key):
    """Local arrays and slot materials (Blender materials or None) of an object's evaluated
    mesh, read once per key: (vertices, triangles, material index per triangle, slots). The
    texture coordinates the slots' textured materials need go to ``ex.uv_cache[key]`` (UV map
    name -> (triangles, 3, 2) float32)."""
    if key in ex.mesh_cache:
        return ex.mesh_cache[key]
    with evaluated_mesh(obj) as mesh:
        if mesh is None:
            data = None
        else:
            v, t, m = mesh_arrays(mesh)
            slots = [s.material for s in obj.material_slots] if obj.material_slots else []
            if not slots and len(mesh.materials):
                slots = list(mesh.materials)
            data = (v, t, m, slots or [None])
            maps = {uv_of(ex, material(ex, s))[0] for s in slots
                    if s is not None and uv_of(ex, material(ex, s)) is not None}
            if maps:
                ex.uv_cache[key] = {name: uv for name in maps
                                    if (uv := corner_uvs(mesh, name)) is not None}
    ex.info.meshes_evaluated += 1
    ex.mesh_cache[key] = data
    return data


def add_opaque(ex, obj, key, matrix):
    """An instance of an opaque object: its triangles in the world, per material slot (with
    their texture coordinates where the slot's material is textured)."""
    data = mesh_data(ex, obj, key)
    if data is None or len(data[1]) == 0:
        return
    v, t, m, slots = data
    slot_materials = [material(ex, s) for s in slots]
    for name, s in zip(slot_materials, slots):
        for note in ex.material_notes.get(name, ()):
            ex.warn(note, ("OBJECT", obj.name))
    world = transform(v, matrix)
    if np.linalg.det(np.asarray(matrix)[:3, :3]) < 0:  # mirrored: keep normals outward
        t = t[:, ::-1]
        flip = True
    else:
        flip = False
    m = np.clip(m, 0, len(slot_materials) - 1)
    uvs = ex.uv_cache.get(key, {})
    for slot in np.unique(m):
        mat = slot_materials[slot]
        sel = (m == slot) if len(slot_materials) > 1 else slice(None)
        tris = t[sel]
        gkey = (key, mat)
        group = ex.groups.setdefault(gkey, [[], [], []])
        group[0].append(world)
        group[1].append(tris)
        group[2].append(_slot_uv(ex, obj, mat, uvs, sel, flip, len(tris)))
        ex.group_names.setdefault(gkey, obj.name)
    ex.info.triangles += len(t)


def _slot_uv(ex, obj, mat, uvs, sel, flip, n):
    """(n, 3, 2) texture coordinates of a slot's triangles, or None when its material is not
    textured (or the mesh lacks the UV map, with a note)."""
    spec = uv_of(ex, mat)
    if spec is None:
        return None
    name, affine = spec
    uv = uvs.get(name)
    if uv is None:
        what = f"UV map '{name}'" if name else "UV map"
        ex.warn(f"Object '{obj.name}': has no {what} for the image texture of Material "
                f"'{mat}': rendered with the image's mean colour", ("OBJECT", obj.name),
                ("MATERIAL", mat))
        return np.full((n, 3, 2), np.nan, np.float32)
    uv = uv[sel]
    if flip:
        uv = uv[:, ::-1]
    if affine is not None:
        uv = (uv @ affine[:, :2].T + affine[:, 2]).astype(np.float32)
    return uv


def corner_uvs(mesh, name: str = ""):
    """(triangles, 3, 2) float32 texture coordinates of a mesh's loop triangles from the UV map
    ``name`` (""; the active render one), or None when the mesh has no such map."""
    layers = mesh.uv_layers
    if name:
        layer = layers.get(name)
    else:
        layer = next((l for l in layers if l.active_render), None) or layers.active
    if layer is None:
        return None
    nl, nt = len(mesh.loops), len(mesh.loop_triangles)
    uv = np.empty(nl * 2, np.float32)
    layer.data.foreach_get("uv", uv)
    loops = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    return uv.reshape(nl, 2)[loops].reshape(nt, 3, 2)


def build_meshes(ex):
    """The engine meshes of the collected groups: one per (mesh, material)."""
    S = ex.photic.scene
    meshes = []
    names_used = {}
    for (key, mat), (vlist, tlist, uvlist) in ex.groups.items():
        offsets = np.cumsum([0] + [len(v) for v in vlist[:-1]])
        vertices = np.concatenate(vlist)
        triangles = np.concatenate([t.astype(np.int64) + o for t, o in zip(tlist, offsets)])
        uv = None
        if uvlist and all(u is not None for u in uvlist):
            uv = np.concatenate(uvlist)
            if not np.all(np.isfinite(uv)):  # (a mesh without the UV map: its mean colour)
                uv = None
        triangles, extra, dropped = drop_degenerate(vertices, triangles, () if uv is None else (uv,))
        if uv is not None:
            uv = extra[0]
        base = ex.group_names[(key, mat)]
        if dropped:
            ex.warn(f"{_obj(base)}: {dropped} zero-area triangle(s) skipped", ("OBJECT", base))
        if len(triangles) == 0:
            continue
        name = base if mat in (DEFAULT_MATERIAL,) or len(
            [k for k in ex.groups if k[0] == key]) == 1 else f"{base} [{mat}]"
        n = names_used.get(name, 0)
        names_used[name] = n + 1
        if n:
            name = f"{name} #{n + 1}"
        meshes.append(S.MeshObject(name, S.TriangleMesh(vertices, triangles), mat, uv))
    return meshes
