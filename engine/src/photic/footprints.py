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

# Rays whose length matches the core's attenuation cap to this relative tolerance are taken as
# having hit nothing.
CAP_RTOL = 1e-6


def beam_cap_lengths(scene, bands: slice | None = None, forward_cone_deg: float = 0.0) -> list[float]:
    """The lengths at which the core stops a beam's vertex ray that meets no surface, one per
    water body: ``min(30 / min_k c_beam, 100 * extent)`` as in the core's ``build_beams``
    (``c_beam = a + b`` for ``forward_cone_deg = 0``; extent = diagonal of the box around the
    geometry, sensors, ocean surface and bottom, computed as the core does when it commits).
    """
    from .phase import make_core_phase

    nb = len(scene.bands)
    bands = bands or slice(0, nb)
    pts = []
    for m in scene.meshes:
        pts.append(np.asarray(m.mesh.vertices, np.float32).astype(np.float64))
    for w in scene.water:
        if w.type == "mesh":
            pts.append(np.asarray(w.mesh.vertices, np.float32).astype(np.float64))
    for c in scene.cameras:
        pts.append(np.asarray(c.position, float)[None])
    for r in scene.all_radiometers():
        pts.append(np.asarray(r.position, float)[None])
    patch = None
    for w in scene.water:
        if w.type != "ocean":
            continue
        zmean = float(w.surface.z)
        pts.append(np.array([[0.0, 0.0, zmean]]))
        if w.bottom_depth is not None:
            pts.append(np.array([[0.0, 0.0, zmean - float(w.bottom_depth)]]))
        if w.surface.kind != "flat":
            v = np.asarray(w.surface.mesh.vertices, np.float64)
            z32 = v[:, 2].astype(np.float32).astype(np.float64)
            x0, y0 = float(v[:, 0].min()), float(v[:, 1].min())
            lx, ly = map(float, w.surface.period)
            patch = np.array([[x0, y0, z32.min()], [x0 + lx, y0 + ly, z32.max()]])
    # As the core's commit: the box of everything but the patch, then grown by the patch's box.
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    if pts:
        p = np.concatenate(pts)
        lo, hi = p.min(axis=0), p.max(axis=0)
    extent = max(1e-3, float(np.linalg.norm(hi - lo))) if lo[0] <= hi[0] else 1.0
    if patch is not None:
        lo, hi = np.minimum(lo, patch[0]), np.maximum(hi, patch[1])
        extent = max(1e-3, float(np.linalg.norm(hi - lo)))

    xc = 1.0 - np.cos(np.radians(forward_cone_deg))
    caps = []
    for w in scene.water:
        c = np.asarray(w.iops.absorption, float)[bands].copy()
        for comp in w.iops.scattering:
            f = float(make_core_phase(comp.phase.type, comp.phase.params).cdf(np.array([xc]))[0]) \
                if forward_cone_deg > 0 else 0.0
            c = c + np.asarray(comp.b, float)[bands] * (1.0 - f)
        cmin = float(c.min())
        caps.append(min(30.0 / cmin if cmin > 0 else np.inf, 100.0 * extent))
    return caps


def footprint_mesh(core, cap_lengths=None):
    """The footprints of the beams currently built in ``core`` (a ``photic._core.Scene`` after
    ``build_beams``) as a ``trimesh.Trimesh``: one triangle per prism, its corners the end
    points ``v + len * d`` of the prism's three vertex rays, with face attributes ``phi`` (flux
    entering the water through the prism, band 0, before attenuation) and ``area`` (m^2).

    Prisms are left out when a vertex ray did not end on a surface (its length equals one of
    ``cap_lengths``, see ``beam_cap_lengths``; without them every prism is kept), when an end
    point is not finite, or when the footprint has no area.
    """
    import trimesh

    v, d, length, phi = core.prism_arrays()
    v, d, length, phi = (np.asarray(a, np.float64) for a in (v, d, length, phi))
    ends = v + length[..., None] * d                                   # (N, 3, 3)
    keep = np.isfinite(ends).all(axis=(1, 2)) & np.isfinite(phi)
    if cap_lengths is not None:
        for cap in cap_lengths:
            if np.isfinite(cap):
                keep &= ~(np.abs(length - cap) <= CAP_RTOL * cap).any(axis=1)
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


def write_footprints(path, core, cap_lengths=None) -> Path:
    """Write ``footprint_mesh(core, cap_lengths)`` with trimesh; the format follows the
    extension (``.ply``: binary PLY with the face properties ``phi`` and ``area``; ``.obj`` and
    others: geometry only). Returns the path."""
    path = Path(path)
    mesh = footprint_mesh(core, cap_lengths)
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
