"""Opaque geometry: each distinct evaluated mesh is read once (``mesh_data``), its instances
only add a world matrix, and all instances of a mesh that share a material become one engine
mesh (``build_meshes``). Water and radiometer arrays read their meshes through ``mesh_data``
too."""
from __future__ import annotations

import numpy as np

from .export_materials import DEFAULT_MATERIAL, material
from .export_values import _obj
from .mesh_export import drop_degenerate, evaluated_mesh, mesh_arrays, transform

GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD"}


def mesh_key(obj) -> tuple:
    """The key an evaluated object's mesh is read and grouped under."""
    # Geometry is keyed by the mesh data when the object has no modifiers, so linked
    # duplicates share one evaluated mesh; otherwise by the object.
    original = obj.original
    data = getattr(original, "data", None)
    if data is not None and not getattr(original, "modifiers", None) and obj.type == "MESH":
        return ("mesh", data.name_full)
    return ("object", original.name_full)


def mesh_data(ex, obj, key):
    """Local arrays and slot materials (Blender materials or None) of an object's evaluated
    mesh, read once per key."""
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
    ex.info.meshes_evaluated += 1
    ex.mesh_cache[key] = data
    return data


def add_opaque(ex, obj, key, matrix):
    """An instance of an opaque object: its triangles in the world, per material slot."""
    data = mesh_data(ex, obj, key)
    if data is None or len(data[1]) == 0:
        return
    v, t, m, slots = data
    slot_materials = [material(ex, s) for s in slots]
    world = transform(v, matrix)
    if np.linalg.det(np.asarray(matrix)[:3, :3]) < 0:  # mirrored: keep normals outward
        t = t[:, ::-1]
    m = np.clip(m, 0, len(slot_materials) - 1)
    for slot in np.unique(m):
        tris = t[m == slot] if len(slot_materials) > 1 else t
        gkey = (key, slot_materials[slot])
        group = ex.groups.setdefault(gkey, [[], []])
        group[0].append(world)
        group[1].append(tris)
        ex.group_names.setdefault(gkey, obj.name)
    ex.info.triangles += len(t)


def build_meshes(ex):
    """The engine meshes of the collected groups: one per (mesh, material)."""
    S = ex.photic.scene
    meshes = []
    names_used = {}
    for (key, mat), (vlist, tlist) in ex.groups.items():
        offsets = np.cumsum([0] + [len(v) for v in vlist[:-1]])
        vertices = np.concatenate(vlist)
        triangles = np.concatenate([t.astype(np.int64) + o for t, o in zip(tlist, offsets)])
        triangles, _, dropped = drop_degenerate(vertices, triangles)
        base = ex.group_names[(key, mat)]
        if dropped:
            ex.info.warnings.append(f"{_obj(base)}: {dropped} zero-area triangle(s) "
                                    f"skipped")
        if len(triangles) == 0:
            continue
        name = base if mat in (DEFAULT_MATERIAL,) or len(
            [k for k in ex.groups if k[0] == key]) == 1 else f"{base} [{mat}]"
        n = names_used.get(name, 0)
        names_used[name] = n + 1
        if n:
            name = f"{name} #{n + 1}"
        meshes.append(S.MeshObject(name, S.TriangleMesh(vertices, triangles), mat))
    return meshes
