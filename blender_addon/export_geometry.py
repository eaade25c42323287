"""Opaque geometry: each distinct evaluated mesh is read once (``mesh_data``), its instances
only add a world matrix (``add_opaque``), and all instances of a mesh that share a material
become one engine mesh (``build_meshes``): a mesh met once is flattened into the world, a mesh
met two or more times (linked duplicates, collection, particle and Geometry Nodes instances)
is kept in its own coordinates with a transform per copy (``MeshObject.instances``: one mesh
and N transforms, traced as a two-level BVH), so the export costs a matrix per copy, not its
triangles. Water and radiometer arrays read their meshes through ``mesh_data`` too."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .export_materials import DEFAULT_MATERIAL, material, uv_of
from .export_values import _obj, non_finite_transform
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


class Instanced(NamedTuple):
    """A group of ``ex.groups`` that is instanced: the slot's mesh once and its copies."""

    vertices: np.ndarray    # (V, 3) float64, the mesh's own coordinates
    triangles: np.ndarray   # (T, 3)
    uv: np.ndarray | None   # (T, 3, 2) float32, unmirrored
    instances: np.ndarray   # (N, 3, 4) float64 rows [R | t]


class Opaque:
    """The copies of one evaluated mesh (one ``mesh_key``) met in the depsgraph: read once,
    each copy only adds its world matrix."""

    __slots__ = ("obj_name", "data", "slot_materials", "notes", "matrices")

    def __init__(self, obj_name, data, slot_materials, notes):
        self.obj_name = obj_name              # the first copy's object (names the engine mesh)
        self.data = data                      # mesh_data(), None: nothing to render
        self.slot_materials = slot_materials  # engine material name per slot
        self.notes = notes                    # the slots' materials' notes (per copy's object)
        self.matrices = []                    # (4, 4) float64 world matrix per copy (then
        #                                       stacked (N, 4, 4) by check_opaque)


def add_opaque(ex, obj, key, matrix):
    """A copy of an opaque object: its world matrix, added to the copies of its mesh (read the
    first time its key is met). ``build_meshes`` makes the engine meshes of them. The matrix
    is checked finite by ``check_opaque`` after the walk."""
    rec = ex.opaque.get(key)
    if rec is None:
        rec = ex.opaque[key] = _opaque(ex, obj, key)
    if rec.data is None:
        return
    rec.matrices.append(matrix)
    if rec.notes:  # (only when a material has notes: on each copy's object's panel)
        name = obj.name
        for note in rec.notes:
            ex.warn(note, ("OBJECT", name))


def _opaque(ex, obj, key) -> Opaque:
    data = mesh_data(ex, obj, key)
    if data is None or len(data[1]) == 0:
        return Opaque(obj.name, None, [], [])
    slot_materials = [material(ex, s) for s in data[3]]
    notes = [note for name in slot_materials for note in ex.material_notes.get(name, ())]
    return Opaque(obj.name, data, slot_materials, notes)


def check_opaque(ex, is_opaque) -> None:
    """Stack each mesh's copies' matrices (N, 4, 4) once and check them finite, else the
    ``ExportError`` of the first object (in the depsgraph's order) whose matrix is not (found
    by walking the depsgraph again: ``is_opaque(instance)`` tells the instances that
    ``add_opaque`` took)."""
    finite = True
    for rec in ex.opaque.values():
        if len(rec.matrices):
            rec.matrices = np.stack(rec.matrices)
            finite = finite and bool(np.isfinite(rec.matrices).all())
    if finite:
        return
    for inst in ex.dg.object_instances:
        if is_opaque(inst) and not np.isfinite(np.array(inst.matrix_world, np.float64)).all():
            raise non_finite_transform(inst.object)


def _flattened(ex, key, rec: Opaque, matrix) -> None:
    """A mesh's only copy: its triangles in the world, per material slot (with their texture
    coordinates where the slot's material is textured), into ``ex.groups``."""
    v, t, m, _ = rec.data
    slot_materials = rec.slot_materials
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
        group[2].append(_slot_uv(ex, rec.obj_name, mat, uvs, sel, flip, len(tris)))
        ex.group_names.setdefault(gkey, rec.obj_name)


def _instanced(ex, key, rec: Opaque) -> int:
    """A mesh's copies (two or more): per material slot the slot's triangles once, in the
    mesh's own coordinates (unmirrored: the engine keeps a mirrored copy's faces outward), and
    the copies' transforms (N, 3, 4), into ``ex.groups``. Returns N (copies of zero size are
    left out)."""
    v, t, m, _ = rec.data
    slot_materials = rec.slot_materials
    matrices = rec.matrices[:, :3, :4]
    r = matrices[:, :, :3]
    scale = np.max(np.linalg.norm(r, axis=1), axis=1)
    flat = ~(np.abs(np.linalg.det(r)) > 1e-9 * scale ** 3)  # (the engine's test)
    if flat.any():  # (a copy scaled to nothing: not drawn by Blender either)
        ex.warn(f"{_obj(rec.obj_name)}: {int(flat.sum())} instance(s) of zero size skipped",
                ("OBJECT", rec.obj_name))
        matrices = matrices[~flat]
        if len(matrices) == 0:
            return 0
    m = np.clip(m, 0, len(slot_materials) - 1)
    uvs = ex.uv_cache.get(key, {})
    v64 = v.astype(np.float64)
    slots = np.unique(m)
    for mat in dict.fromkeys(slot_materials[s] for s in slots):  # (slots sharing a material)
        if len(slot_materials) > 1:
            sel = np.isin(m, [s for s in slots if slot_materials[s] == mat])
        else:
            sel = slice(None)
        tris = t[sel]
        uv = _slot_uv(ex, rec.obj_name, mat, uvs, sel, False, len(tris))
        if uv is not None and not np.all(np.isfinite(uv)):  # (no UV map: its mean colour)
            uv = None
        ex.groups[(key, mat)] = Instanced(v64, tris, uv, matrices)
        ex.group_names.setdefault((key, mat), rec.obj_name)
    return len(matrices)


def _slot_uv(ex, obj_name, mat, uvs, sel, flip, n):
    """(n, 3, 2) texture coordinates of a slot's triangles, or None when its material is not
    textured (or the mesh lacks the UV map, with a note)."""
    spec = uv_of(ex, mat)
    if spec is None:
        return None
    name, affine = spec
    uv = uvs.get(name)
    if uv is None:
        what = f"UV map '{name}'" if name else "UV map"
        ex.warn(f"Object '{obj_name}': has no {what} for the image texture of Material "
                f"'{mat}': rendered with the image's mean colour", ("OBJECT", obj_name),
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
    """The engine meshes of the collected copies: one per (mesh, material). A mesh met once is
    flattened into the world; a mesh met two or more times (linked duplicates, collection,
    particle and Geometry Nodes instances) is one engine mesh in its own coordinates with a
    transform per copy (``MeshObject.instances``)."""
    for key, rec in ex.opaque.items():
        if not len(rec.matrices):
            continue
        ex.info.triangles += len(rec.data[1]) * len(rec.matrices)
        if len(rec.matrices) == 1:
            _flattened(ex, key, rec, rec.matrices[0])
        else:
            copies = _instanced(ex, key, rec)
            ex.info.instanced_meshes += int(copies > 0)
            ex.info.instanced_copies += copies
    S = ex.photic.scene
    meshes = []
    names_used = {}
    per_key = {}
    for key, _ in ex.groups:
        per_key[key] = per_key.get(key, 0) + 1
    for (key, mat), group in ex.groups.items():
        if isinstance(group, Instanced):
            vertices, triangles, uv, instances = group
        else:
            vertices, triangles, uv = _concatenated(group)
            instances = None
        triangles, extra, dropped = drop_degenerate(vertices, triangles, () if uv is None else (uv,))
        if uv is not None:
            uv = extra[0]
        base = ex.group_names[(key, mat)]
        if dropped:
            ex.warn(f"{_obj(base)}: {dropped} zero-area triangle(s) skipped", ("OBJECT", base))
        if len(triangles) == 0:
            continue
        if instances is not None:  # (the vertices the slot's triangles use, once)
            used, inverse = np.unique(triangles, return_inverse=True)
            vertices, triangles = vertices[used], inverse.reshape(-1, 3).astype(np.int64)
        name = base if mat in (DEFAULT_MATERIAL,) or per_key[key] == 1 else f"{base} [{mat}]"
        n = names_used.get(name, 0)
        names_used[name] = n + 1
        if n:
            name = f"{name} #{n + 1}"
        meshes.append(S.MeshObject(name, S.TriangleMesh(vertices, triangles), mat, uv, instances))
    return meshes


def _concatenated(group):
    """One flattened group's (vertices, triangles, uv or None)."""
    vlist, tlist, uvlist = group
    offsets = np.cumsum([0] + [len(v) for v in vlist[:-1]])
    vertices = np.concatenate(vlist)
    triangles = np.concatenate([t.astype(np.int64) + o for t, o in zip(tlist, offsets)])
    uv = None
    if uvlist and all(u is not None for u in uvlist):
        uv = np.concatenate(uvlist)
        if not np.all(np.isfinite(uv)):  # (a mesh without the UV map: its mean colour)
            uv = None
    return vertices, triangles, uv
