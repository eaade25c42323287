"""Evaluated meshes of Blender objects as numpy arrays.

``evaluated_mesh`` is the only place an export mesh is created, and it always frees it
(``to_mesh_clear``), also when the export fails or is cancelled. Arrays are read in bulk with
``foreach_get`` into preallocated arrays (float32 positions, uint32 triangle indices), never
vertex by vertex.
"""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np


@contextmanager
def evaluated_mesh(obj):
    """The evaluated mesh of an evaluated object (modifiers applied), freed on exit; None for
    objects without geometry."""
    mesh = None
    try:
        mesh = obj.to_mesh()
    except RuntimeError:
        mesh = None
    try:
        yield mesh
    finally:
        if mesh is not None:
            obj.to_mesh_clear()


def mesh_arrays(mesh):
    """(vertices float32 (N, 3), triangles uint32 (M, 3), material index int32 (M,)) in the
    object's local coordinates."""
    if hasattr(mesh, "calc_loop_triangles"):
        mesh.calc_loop_triangles()
    nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
    v = np.empty(nv * 3, np.float32)
    mesh.vertices.foreach_get("co", v)
    t = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", t)
    m = np.empty(nt, np.int32)
    mesh.loop_triangles.foreach_get("material_index", m)
    return v.reshape(nv, 3), t.view(np.uint32).reshape(nt, 3), m


def transform(vertices: np.ndarray, matrix) -> np.ndarray:
    """float64 world positions of float32 local ones under a 4x4 matrix."""
    m = np.asarray(matrix, dtype=np.float64)
    return vertices.astype(np.float64) @ m[:3, :3].T + m[:3, 3]


def drop_degenerate(vertices: np.ndarray, triangles: np.ndarray, extra=()):
    """Remove zero-area triangles (common in modelled meshes, rejected by the engine).

    Returns the kept triangles, the kept rows of each array in ``extra`` and the number
    dropped. The threshold is the engine's: area < 1e-12 x (bounding-box diagonal)^2."""
    if len(triangles) == 0:
        return triangles, tuple(extra), 0
    t = triangles.astype(np.int64)
    p0, p1, p2 = vertices[t[:, 0]], vertices[t[:, 1]], vertices[t[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    diag2 = float(np.sum((vertices.max(axis=0) - vertices.min(axis=0)) ** 2))
    keep = (area >= 1e-12 * diag2) & (area > 0.0)
    dropped = int(len(keep) - np.count_nonzero(keep))
    if dropped == 0:
        return triangles, tuple(extra), 0
    return triangles[keep], tuple(e[keep] for e in extra), dropped
