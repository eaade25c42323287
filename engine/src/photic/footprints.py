"""Beam footprints: where the refracted sun's beam prisms end, as a triangle mesh.

Below a triangulated water surface (an ocean's height-field patch, the sun-facing faces of a
closed water mesh) the hybrid integrator sends one prism of light per lit (sub)triangle; its
three vertex rays run along the refracted sun directions to the first surface they meet. The
triangle spanned by the three end points is the prism's *footprint* on that surface (the
bottom, an object). Focusing waves shrink footprints and so brighten them: the footprint mesh
shows the caustic pattern.

Each face carries two attributes:

- ``phi``: the flux that enters the water through the prism's source triangle, band 0
  (W, per unit of the band's source spectrum), i.e. after Fresnel transmission but **before**
  attenuation along the prism;
- ``area``: the footprint's area (m^2).

``phi / area`` is therefore *not* the irradiance on the footprint: the beam's attenuation
``exp(-c_beam l)`` along its length ``l`` (and the obliquity of the surface) is left out, since
the core does not expose ``c_beam``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

def footprint_mesh(core):
    """The footprints of the beams currently built in ``core`` (a ``photic._core.Scene`` after
    ``build_beams``) as a ``trimesh.Trimesh``: one triangle per prism, its corners the end
    points ``v + len * d`` of the prism's three vertex rays, with face attributes ``phi`` (flux
    entering the water through the prism, band 0, before attenuation) and ``area`` (m^2).

    Prisms are left out when a vertex ray did not end on a surface (it ran out in open water),
    when an end point is not finite, or when the footprint has no area.
    """
    import trimesh

    v, d, length, phi, hit = core.prism_arrays()
    v, d, length, phi = (np.asarray(a, np.float64) for a in (v, d, length, phi))
    ends = v + length[..., None] * d                                   # (N, 3, 3)
    keep = np.isfinite(ends).all(axis=(1, 2)) & np.isfinite(phi) & np.asarray(hit, bool).all(axis=1)
    with np.errstate(invalid="ignore", over="ignore"):
        area = 0.5 * np.linalg.norm(np.cross(ends[:, 1] - ends[:, 0], ends[:, 2] - ends[:, 0]), axis=1)
    keep &= area > 0
    ends, phi, area = ends[keep], phi[keep], area[keep]
    n = len(ends)
    mesh = trimesh.Trimesh(vertices=ends.reshape(-1, 3), faces=np.arange(3 * n).reshape(n, 3),
                           process=False)
    mesh.merge_vertices()  # corners shared by neighbouring prisms become one vertex; faces keep their order
    mesh.face_attributes["phi"] = phi
    mesh.face_attributes["area"] = area
    return mesh


def write_footprints(path, core) -> Path:
    """Write ``footprint_mesh(core)`` with trimesh; the format follows the
    extension (``.ply``: binary PLY with the face properties ``phi`` and ``area``; ``.obj`` and
    others: geometry only). Returns the path."""
    path = Path(path)
    mesh = footprint_mesh(core)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix.lower() == ".ply":
        mesh.export(str(path), file_type="ply", include_attributes=True)
    else:
        mesh.export(str(path))
    return path


def load_footprints(path):
    """Read a footprint PLY back as a ``trimesh.Trimesh`` with the face attributes ``phi`` and
    ``area`` restored (trimesh keeps custom PLY face properties only in its raw metadata)."""
    import trimesh

    mesh = trimesh.load(str(path), process=False, force="mesh")
    raw = mesh.metadata.get("_ply_raw", {}).get("face", {}).get("data")
    if raw is not None and raw.dtype.names:
        for name in ("phi", "area"):
            if name in raw.dtype.names:
                mesh.face_attributes[name] = np.asarray(raw[name], np.float64)
    return mesh
