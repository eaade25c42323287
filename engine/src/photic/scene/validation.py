"""Semantic checks of a scene, one function per kind of object (``Scene.validate``): per-band
lengths, closed meshes, references, unique names, limits; and the warnings that do not stop
a render (``scene_warnings``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..parameters import check_parameter, check_per_band_parameter
from .checks import (
    CAMERA_TYPES, FILTER_TYPES, INTEGRATORS, MAX_ARRAY_RADIOMETERS, MAX_COMPONENTS,
    MAX_COORDINATE_M, MAX_DISTRIBUTION_BINS, PHASE_FUNCTION_PARAMS,
    QUANTITIES, SKY_TYPES, SURFACE_KINDS, SceneError, WATER_TYPES, _COORD_TEXT,
    _DEGENERATE_AREA_FRACTION, _check_choice, _check_encodable, _check_name,
    _check_real, _check_vec3, _entries, _label, _num, _show,
)
from .model import (
    Band, Camera, GridField, IOPGrid, IOPProfile, IOPs, MAX_GRID_FIELDS, Material, MaterialTexture, MeshObject,
    OceanSurface, PhaseFunction, Radiometer, RadiometerArray, ScatteringComponent, Scene,
    Settings, Sky, Sun, SurfaceRoughness, TriangleMesh, WaterBody,
)


# ----------------------------------------------------------------------------------------
# Semantic checks: one function per kind of object
# ----------------------------------------------------------------------------------------

def _validate_scene(s: Scene) -> None:
    if not isinstance(s.name, str):
        raise SceneError("scene", "name", f"must be a string, got {_show(s.name)}")
    _check_encodable("scene", "name", s.name)
    if not isinstance(s.bands, list) or not s.bands:
        raise SceneError("scene", "bands", "at least one band is required")
    seen: dict[str, str] = {}
    for i, band in enumerate(s.bands):
        _validate_band(_check_name("band", i, band.name, seen), band)
    nbands = len(s.bands)

    for key, material in s.materials.items():
        _validate_material(key, material, nbands)

    seen = {}
    for i, obj in enumerate(s.meshes):
        label = _check_name("mesh", i, obj.name, seen)
        _check_mesh(label, "", obj.mesh)
        _check_material_ref(label, "material", obj.material, s.materials)
        if obj.uv is not None:
            _check_uv(label, obj)
        if obj.instances is not None:
            _check_instances(label, obj)

    seen = {}
    ocean = None
    for i, water in enumerate(s.water):
        label = _check_name("water", i, water.name, seen)
        _validate_water(label, water, nbands, s.materials)
        if water.type == "ocean":
            if ocean is not None:
                raise SceneError(label, "type", f"at most one ocean is allowed, {ocean} is "
                                                f"already one")
            ocean = label

    if s.sun is not None:
        _validate_sun(s.sun, nbands)
    _validate_sky(s.sky, nbands)
    if isinstance(s.sky, Sky) and s.sky.type == "harrison_coombes" and s.sun is None:
        raise SceneError("sky", "type", "a 'harrison_coombes' sky is shaped by the sun: the "
                                        "scene needs a sun")

    seen = {}
    for i, camera in enumerate(s.cameras):
        _validate_camera(_check_name("camera", i, camera.name, seen), camera)

    seen = {}
    for i, radiometer in enumerate(s.radiometers):
        _validate_radiometer(_check_name("radiometer", i, radiometer.name, seen), radiometer)
    arrays_seen: dict[str, str] = {}
    for i, array in enumerate(s.radiometer_arrays):
        label = _check_name("radiometer_array", i, array.name, arrays_seen)
        _validate_radiometer_array(label, array)
        # Expanded names share the radiometers' namespace (outputs are keyed by them).
        for radiometer in array.radiometers():
            if radiometer.name in seen:
                raise SceneError(label, "name", f"expands to radiometer '{radiometer.name}', "
                                                f"which is also {seen[radiometer.name]}")
            seen[radiometer.name] = f"{label} (expanded)"

    _validate_settings(s.settings)

    if not s.cameras and not seen:
        raise SceneError("scene", "cameras", "missing sensor: the scene needs at least one "
                                             "camera or radiometer")
    _check_water_overlap(s)


_OVERLAP_SAMPLE = 2000  # vertices of a water mesh tested against each other one


def _check_water_overlap(s: Scene) -> None:
    """Water meshes must not overlap (a point lies in one water body at most; the medium of
    the overlap would depend on the order of the list). A body whose boxes meet another's is
    tested by its vertices, moved a millionth of its size towards its own centre (so that bodies
    that only touch pass), being inside the other (ray parity, trimesh)."""
    meshes = [(i, w) for i, w in enumerate(s.water) if w.type == "mesh" and w.mesh is not None]
    if len(meshes) < 2:
        return
    boxes = {i: (np.asarray(w.mesh.vertices).min(0), np.asarray(w.mesh.vertices).max(0)) for i, w in meshes}
    built: dict = {}

    def solid(i, w):
        if i not in built:
            import trimesh
            built[i] = trimesh.Trimesh(np.asarray(w.mesh.vertices, float), np.asarray(w.mesh.triangles),
                                       process=False)
        return built[i]

    for a, wa in meshes:
        for b, wb in meshes:
            if a == b:
                continue
            (alo, ahi), (blo, bhi) = boxes[a], boxes[b]
            if np.any(alo > bhi) or np.any(blo > ahi):
                continue
            v = np.asarray(wa.mesh.vertices, float)
            if len(v) > _OVERLAP_SAMPLE:
                v = v[np.linspace(0, len(v) - 1, _OVERLAP_SAMPLE).astype(np.int64)]
            centre = 0.5 * (alo + ahi)
            v = v + (centre - v) * 1e-6
            inside = solid(b, wb).contains(v)
            if np.any(inside):
                raise SceneError(_label("water", wb.name, b), "vertices",
                                 f"overlaps water '{wa.name}' ({int(np.count_nonzero(inside))} of its "
                                 f"{len(v)} tested vertices lie inside it): a point can be in one "
                                 f"water body only; separate them, or join them into one body")


def scene_warnings(s: Scene) -> list[str]:
    """Problems that do not stop a render but make its numbers useless where the user may not
    expect it (the renderer adds those it needs geometry for: sensors inside opaque objects)."""
    out = []
    if s.sun is not None and not np.any(np.asarray(s.sun.irradiance, float) > 0):
        out.append("sun: its irradiance is 0 in every band: it adds no light")
    ocean = next((w for w in s.water if w.type == "ocean"), None)
    if ocean is not None and ocean.bottom_depth is not None:
        floor = float(ocean.surface.z) - float(ocean.bottom_depth)
        for r in s.all_radiometers():
            if float(r.position[2]) < floor:
                out.append(f"radiometer '{r.name}': position z = {float(r.position[2]):g} m is below "
                           f"the sea floor (z = {floor:g} m): no light reaches it, it reads 0")
        for c in s.cameras:
            if float(c.position[2]) < floor:
                out.append(f"camera '{c.name}': position z = {float(c.position[2]):g} m is below the "
                           f"sea floor (z = {floor:g} m): it sees nothing")
    from ..inelastic import cdom_coupling, cdom_coverage, chlorophyll_coverage, raman_active
    if raman_active(s):
        out += _raman_warnings(s)
    for w in s.water:
        f = w.fluorescence
        if f is not None:
            seen = chlorophyll_coverage(s.bands, f.peak_nm, f.fwhm_nm)
            if seen < 0.9:
                out.append(f"water '{w.name}': its chlorophyll fluoresces around {f.peak_nm:g} nm (full width "
                           f"{f.fwhm_nm:g} nm); the scene's bands hold {100 * seen:.0f} % of that light (add a "
                           f"band there to see it)")
        g = w.cdom_fluorescence
        if g is not None:
            seen = cdom_coverage(s.bands, g.absorption)
            if seen < 0.9:
                out.append(f"water '{w.name}': its CDOM fluoresces broadly red of the light it absorbs (310-550 nm); "
                           f"the scene's bands hold {100 * seen:.0f} % of that light (bands from 400 to 700 nm "
                           f"hold most of it)")
            if not np.any(cdom_coupling(s.bands, g.absorption)):
                out.append(f"water '{w.name}': cdom_fluorescence: no band between 310 and 550 nm with CDOM "
                           f"absorption excites it: it adds nothing")
        if isinstance(w.iops, IOPGrid) and (f is not None or g is not None):
            out.append(f"water '{w.name}': fluorescence comes from its base IOPs' phytoplankton and CDOM "
                       f"(the absorption given), not from its grid's fields")
    return out


def _raman_warnings(s: Scene) -> list[str]:
    """What Raman scattering (settings.raman) cannot give this scene: excitation outside the
    bands."""
    from ..inelastic import RAMAN_SHIFT_RANGE_CM, raman_coupling, raman_coverage
    out = []
    coupling = raman_coupling(s.bands)
    coverage = raman_coverage(s.bands)
    if s.settings.raman == "auto":  # (on by default: one line, not one per band)
        short = [f"'{b.name}' {'none' if not coupling[j].any() else f'{100 * coverage[j]:.0f} %'}"
                 for j, b in enumerate(s.bands) if coverage[j] < 0.9]
        if short:
            out.append(f"settings.raman (auto: on): Raman light comes from excitation 60-100 nm bluer than each "
                       f"band; the scene's bands hold this share of it: {', '.join(short)} (add bands there "
                       f"to see all of it, or set settings.raman to false for purely elastic light)")
        return out
    for j, b in enumerate(s.bands):
        lo = 1e7 / (1e7 / (b.center_nm - 0.5 * b.width_nm) + RAMAN_SHIFT_RANGE_CM[1])
        hi = 1e7 / (1e7 / (b.center_nm + 0.5 * b.width_nm) + RAMAN_SHIFT_RANGE_CM[0])
        if coverage[j] < 0.9:
            got = "none" if not coupling[j].any() else f"{100 * coverage[j]:.0f} %"
            out.append(f"band '{b.name}': its Raman light is excited at about {lo:.0f}-{hi:.0f} nm, of "
                       f"which the scene's bands hold {got}: it gets that share of its Raman light "
                       f"(add bands there to see all of it)")
    return out


def _validate_band(label: str, band: Band) -> None:
    check_parameter(label, "band.center_nm", band.center_nm)
    check_parameter(label, "band.width_nm", band.width_nm)


def _validate_material(key: Any, material: Material, nbands: int) -> None:
    label = f"material '{key}'"
    if not isinstance(key, str) or not key:
        raise SceneError(label, "name", "must be a non-empty string")
    if not isinstance(material, Material):
        raise SceneError(label, "type", "must be a Material")
    if material.name != key:
        raise SceneError(label, "name", f"is {_show(material.name)} but the material is stored "
                                        f"under the key '{key}'")
    check_per_band_parameter(label, "material.reflectance", material.reflectance, nbands)
    if material.emission is not None:
        check_per_band_parameter(label, "material.emission", material.emission, nbands, "emission")
    tex = material.texture
    if tex is not None:
        if not isinstance(tex, MaterialTexture):
            raise SceneError(label, "texture", "must be a MaterialTexture")
        img = tex.image
        if not isinstance(img, np.ndarray) or img.ndim != 3 or img.shape[2] != nbands or \
                img.shape[0] < 1 or img.shape[1] < 1:
            raise SceneError(label, "texture.image", f"must be an array (height, width, {nbands}) of "
                                                     f"reflectances, one per band, got "
                                                     f"{getattr(img, 'shape', _show(img))}")
        if not np.all(np.isfinite(img)) or img.min() < 0 or img.max() > 1:
            raise SceneError(label, "texture.image", "reflectances must be finite and in [0, 1]")
        _check_choice(label, "texture.wrap", tex.wrap, ("repeat", "clamp"))
        _check_choice(label, "texture.interpolation", tex.interpolation, ("linear", "closest"))


def _check_uv(label: str, obj: MeshObject) -> None:
    uv = obj.uv
    ntri = len(obj.mesh.triangles) if hasattr(obj.mesh.triangles, "__len__") else -1
    if not isinstance(uv, np.ndarray) or uv.shape != (ntri, 3, 2):
        raise SceneError(label, "uv", f"must be an array (triangles = {ntri}, 3, 2) of texture "
                                      f"coordinates, got {getattr(uv, 'shape', _show(uv))}")
    if not np.all(np.isfinite(uv)):
        raise SceneError(label, "uv", "texture coordinates must be finite")


MAX_INSTANCES = 1 << 26  # copies of one mesh (Embree's instance ids are 32-bit; 64 M x 48 B)


def _check_instances(label: str, obj: MeshObject) -> None:
    """An instanced mesh's transforms: (N, 3, 4) finite affine rows [R | t], 1 <= N <=
    MAX_INSTANCES, none singular or so thin that its copy is degenerate, every copy within
    the coordinate limit."""
    m = obj.instances
    if not isinstance(m, np.ndarray) or m.ndim != 3 or m.shape[1:] != (3, 4) or m.dtype.kind != "f":
        raise SceneError(label, "instances", f"must be an array (N, 3, 4) (or (N, 4, 4) with last "
                                             f"rows [0, 0, 0, 1]) of affine transforms [R | t], "
                                             f"got {getattr(m, 'shape', _show(m))}")
    if not 1 <= len(m) <= MAX_INSTANCES:
        raise SceneError(label, "instances", f"must hold 1 to {MAX_INSTANCES} transforms, got {len(m)}")
    finite = np.all(np.isfinite(m), axis=(1, 2))
    if not finite.all():
        k = int(np.flatnonzero(~finite)[0])
        raise SceneError(label, f"instances[{k}]", f"must contain only finite numbers, got {m[k].tolist()}")
    r = m[:, :, :3]
    det = np.linalg.det(r)
    scale = np.max(np.linalg.norm(r, axis=1), axis=1)  # the largest row: the copy's stretch
    thin = ~(np.abs(det) > 1e-9 * scale ** 3)
    if thin.any():
        k = int(np.flatnonzero(thin)[0])
        raise SceneError(label, f"instances[{k}]", f"is singular or degenerate (determinant "
                                                   f"{det[k]:.3g}): a copy would be flat, got {m[k].tolist()}")
    v = np.asarray(obj.mesh.vertices, np.float64)
    lo, hi = v.min(0), v.max(0)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    reach = np.max(np.abs(np.einsum("nij,cj->nci", r, corners) + m[:, None, :, 3]), axis=(1, 2))
    far = reach > MAX_COORDINATE_M
    if far.any():
        k = int(np.flatnonzero(far)[0])
        raise SceneError(label, f"instances[{k}]", f"places the mesh beyond the coordinate limit: "
                                                   f"its copy must be {_COORD_TEXT}")


def _check_material_ref(label: str, fld: str, name: Any, materials: dict) -> None:
    if name not in materials:
        known = ", ".join(repr(k) for k in materials) or "none"
        raise SceneError(label, fld, f"unknown material {_show(name)} (defined: {known})")


def _check_mesh(label: str, prefix: str, mesh: Any) -> None:
    """Check a mesh: shapes, finite vertices, indices in range, no zero-area triangles.

    ``prefix`` is prepended to the field names (``"surface."`` for an ocean patch).
    """
    if not isinstance(mesh, TriangleMesh):
        raise SceneError(label, f"{prefix}mesh", f"a TriangleMesh is required, got "
                                                 f"{_show(mesh)}")
    v, t = mesh.vertices, mesh.triangles
    if not isinstance(v, np.ndarray) or v.ndim != 2 or v.shape[1] != 3 or v.dtype.kind not in "fiu":
        raise SceneError(label, f"{prefix}vertices", "must be an (N, 3) array of numbers")
    if not isinstance(t, np.ndarray) or t.ndim != 2 or t.shape[1] != 3 or t.dtype.kind not in "iu":
        raise SceneError(label, f"{prefix}triangles", "must be an (M, 3) array of integer "
                                                      "vertex indices")
    if len(t) == 0 or len(v) == 0:
        raise SceneError(label, f"{prefix}triangles", "empty mesh: at least one triangle is "
                                                      "required")
    # Large meshes (millions of triangles) are checked in blocks, so the temporaries stay a
    # few tens of MB whatever the size; the whole-array reductions come first as fast paths.
    if not np.isfinite(v).all():
        bad = np.flatnonzero(~np.all(np.isfinite(v), axis=1))
        raise SceneError(label, f"{prefix}vertices[{bad[0]}]", f"must be finite, got "
                                                              f"{v[bad[0]].tolist()}")
    far = np.max(np.abs(v), axis=1) > MAX_COORDINATE_M
    if far.any():
        bad = int(np.flatnonzero(far)[0])
        raise SceneError(label, f"{prefix}vertices[{bad}]", f"must be {_COORD_TEXT}, got "
                                                            f"{v[bad].tolist()}")
    if t.min() < 0 or t.max() >= len(v):
        bad = np.flatnonzero(np.any((t < 0) | (t >= len(v)), axis=1))
        raise SceneError(label, f"{prefix}triangles[{bad[0]}]",
                         f"vertex index out of range 0..{len(v) - 1}: {t[bad[0]].tolist()}")
    diagonal2 = float(np.sum((v.max(axis=0) - v.min(axis=0)) ** 2))
    limit = _DEGENERATE_AREA_FRACTION * diagonal2
    for start in range(0, len(t), _MESH_CHECK_BLOCK):
        area = _triangle_areas(v, t[start:start + _MESH_CHECK_BLOCK])
        bad = np.flatnonzero((area < limit) | (area == 0.0))
        if len(bad):
            i = start + int(bad[0])
            raise SceneError(label, f"{prefix}triangles[{i}]",
                             f"zero-area (degenerate) triangle {t[i].tolist()}: area "
                             f"{area[bad[0]]:.3g} m^2 < 1e-12 x (bounding-box diagonal)^2")


_MESH_CHECK_BLOCK = 1 << 18  # triangles per block of the mesh checks


def _triangle_areas(v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Areas (float64) of the triangles ``t`` (M, 3) over the vertices ``v``."""
    p0 = v[t[:, 0]].astype(np.float64, copy=False)
    e1 = v[t[:, 1]] - p0
    e2 = v[t[:, 2]] - p0
    cx = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    cy = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    cz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)


def check_closed_mesh(label: str, mesh: TriangleMesh) -> None:
    """Check a water mesh on its own (as ``Scene.validate`` does): valid, closed, outward.

    Raises
    ------
    SceneError
        Naming ``label`` and the field."""
    _check_mesh(label, "", mesh)
    _check_closed(label, mesh)


def _check_closed(label: str, mesh: TriangleMesh) -> None:
    """Require a watertight, consistently wound mesh with outward normals.

    The same rules as trimesh's ``merge_vertices``, ``is_watertight``, ``is_winding_consistent``
    and ``volume`` (tests/test_large_scenes.py compares them), in O(M log M) time and about
    40 bytes per triangle of temporaries (trimesh needs ~470), so that meshes of millions of
    triangles are checked in seconds:

    - closedness is geometric: vertices at the same position (to 1e-8 m) are joined first;
    - every edge must belong to exactly two triangles, which traverse it in opposite
      directions (consistent winding);
    - the enclosed volume (divergence theorem) must be positive (outward normals).
    """
    v = np.asarray(mesh.vertices, dtype=np.float64)
    ids, n = _merged_vertex_ids(v)
    tri = mesh.triangles
    m = len(tri)
    if n >= 1 << 31:  # edge keys would overflow int64: not reachable in memory anyway
        raise SceneError(label, "triangles", f"water mesh has too many vertices ({n})")
    # One int64 key per directed edge: 2 (lo n + hi) + (a > b); sorted, the two uses of an
    # edge are then neighbours, the lower key traversing it from lo to hi.
    keys = np.empty(3 * m, np.int64)
    for j in range(3):
        a, b = ids[tri[:, j]], ids[tri[:, (j + 1) % 3]]
        k = keys[j * m:(j + 1) * m]
        np.minimum(a, b, out=k)
        k *= n
        k += np.maximum(a, b)
        k *= 2
        k += a > b
        del a, b
    keys.sort()
    edge = keys >> 1
    first, second = edge[0::2], edge[1::2]
    closed = len(keys) % 2 == 0 and bool(np.array_equal(first, second)) and bool(
        np.all(first[1:] != second[:-1]))
    if not closed:
        _, counts = np.unique(edge, return_counts=True)
        open_edges, shared = int(np.count_nonzero(counts == 1)), int(np.count_nonzero(counts > 2))
        if open_edges == 0 and shared > 0:  # closed, but parts touch along edges
            raise SceneError(label, "triangles", f"water mesh is not a single closed surface: "
                                                 f"{shared} edge(s) belong to more than two "
                                                 f"triangles (parts touching along an edge, e.g. "
                                                 f"two boxes sharing one: join them into one "
                                                 f"body or move them apart)")
        raise SceneError(label, "triangles", f"water mesh is not closed (watertight): "
                                             f"{open_edges} edge(s) belong to only one triangle"
                                             + (f" and {shared} to more than two" if shared else ""))
    del edge, first, second
    # Opposite directions: flags 0 then 1 in each pair (an edge from a vertex to itself, in
    # a triangle whose corners were joined, counts as consistent, as in trimesh).
    k0, k1 = keys[0::2], keys[1::2]
    ok = ((k0 & 1) == 0) & ((k1 & 1) == 1)
    if not ok.all():
        lo_hi = k0[~ok] >> 1
        if not np.all(lo_hi // n == lo_hi % n):
            raise SceneError(label, "triangles", "water mesh winding is inconsistent: "
                                                 "neighbouring triangles have opposite "
                                                 "orientations")
    del keys, k0, k1, ok
    volume = 0.0
    for start in range(0, m, _MESH_CHECK_BLOCK):
        t = tri[start:start + _MESH_CHECK_BLOCK]
        p0, p1, p2 = v[t[:, 0]], v[t[:, 1]], v[t[:, 2]]
        cx = (p1[:, 1] - p0[:, 1]) * (p2[:, 2] - p0[:, 2]) - (p1[:, 2] - p0[:, 2]) * (p2[:, 1] - p0[:, 1])
        volume += float(np.dot(cx, p0[:, 0] + p1[:, 0] + p2[:, 0]))
    volume /= 6.0
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = float(np.max(hi - lo))
    if abs(volume) <= 1e-9 * max(size, 1e-300) ** 3:  # flat: no height, width or depth
        thin = "xyz"[int(np.argmin(hi - lo))]
        raise SceneError(label, "triangles", f"water mesh encloses no volume ({volume:.3g} m^3): "
                                             f"it is flat (extent {float(np.min(hi - lo)):.3g} m "
                                             f"in {thin}); a water body needs a height")
    if not volume > 0:
        raise SceneError(label, "triangles", f"water mesh normals point inwards (enclosed volume "
                                             f"{volume:.6g} m^3 <= 0); reverse the winding "
                                             f"of every triangle")


def _merged_vertex_ids(v: np.ndarray) -> tuple[np.ndarray, int]:
    """(id per vertex, number of ids): vertices whose coordinates agree when rounded to 1e-8
    (trimesh's ``tol.merge``) share an id."""
    q = np.round(v * 1e8).astype(np.int64)
    order = np.lexsort((q[:, 2], q[:, 1], q[:, 0]))
    qs = q[order]
    del q
    new = np.empty(len(v), bool)
    new[:1] = True
    np.any(qs[1:] != qs[:-1], axis=1, out=new[1:])
    del qs
    ids = np.empty(len(v), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids, int(np.count_nonzero(new))


def _validate_phase(label: str, prefix: str, phase: Any) -> None:
    if not isinstance(phase, PhaseFunction):
        raise SceneError(label, f"{prefix}type", "a PhaseFunction is required")
    _check_choice(label, f"{prefix}type", phase.type, tuple(PHASE_FUNCTION_PARAMS))
    expected = PHASE_FUNCTION_PARAMS[phase.type]
    for key in phase.params:
        if key not in expected:
            raise SceneError(label, f"{prefix}{key}", f"is not a parameter of phase function "
                                                      f"'{phase.type}'")
    for key in expected:
        if key not in phase.params:
            raise SceneError(label, f"{prefix}{key}", f"required by phase function "
                                                      f"'{phase.type}'")
    if phase.type == "henyey_greenstein":
        check_parameter(label, "phase.g", phase.params["g"], f"{prefix}g")
    elif phase.type == "fournier_forand":
        check_parameter(label, "phase.backscatter_fraction", phase.params["backscatter_fraction"],
                        f"{prefix}backscatter_fraction")


def _validate_iops(label: str, iops: Any, nbands: int, fld: str = "iops") -> None:
    if not isinstance(iops, IOPs):
        raise SceneError(label, fld, "an IOPs or an IOPProfile is required" if fld == "iops"
                         else "an IOPs is required")
    check_per_band_parameter(label, "iops.absorption", iops.absorption, nbands, f"{fld}.absorption")
    if not isinstance(iops.scattering, list):
        raise SceneError(label, f"{fld}.scattering", f"must be a list of ScatteringComponent, "
                                                     f"got {_show(iops.scattering)}")
    if len(iops.scattering) > MAX_COMPONENTS:
        raise SceneError(label, f"{fld}.scattering", f"has {len(iops.scattering)} components; "
                                                     f"at most {MAX_COMPONENTS} are supported")
    for i, component in enumerate(iops.scattering):
        prefix = f"{fld}.scattering[{i}]"
        if not isinstance(component, ScatteringComponent):
            raise SceneError(label, prefix, f"must be a ScatteringComponent, got {_show(component)}")
        check_per_band_parameter(label, "scattering_component.b", component.b, nbands, f"{prefix}.b")
        _validate_phase(label, f"{prefix}.phase.", component.phase)


def _validate_profile(label: str, profile: IOPProfile, nbands: int,
                      prefix: str = "iop_profile") -> None:
    """Layer tops finite and strictly descending, one valid IOPs per layer, and the same
    phase functions (in the same order) in every layer."""
    z = profile.z_top
    if not isinstance(z, np.ndarray) or z.ndim != 1 or z.dtype.kind not in "fiu" or z.size == 0:
        raise SceneError(label, f"{prefix}.z_top", f"must be a non-empty list of layer tops "
                                                     f"(m), got {_show(z)}")
    for i, x in enumerate(z.tolist()):
        _check_real(label, f"{prefix}.z_top[{i}]", x)
        if i > 0 and not x < z[i - 1]:
            raise SceneError(label, f"{prefix}.z_top[{i}]",
                             f"must be below z_top[{i - 1}] = {_num(z[i - 1])} m (layer tops "
                             f"run strictly downwards), got {_show(x)}")
    layers = profile.layers
    if not isinstance(layers, list) or len(layers) != z.size:
        count = _entries(len(layers)) if isinstance(layers, list) else _show(layers)
        raise SceneError(label, f"{prefix}.layers", f"needs one IOPs per layer top: z_top has "
                                                      f"{_entries(z.size)}, layers has {count}")
    for i, layer in enumerate(layers):
        _validate_iops(label, layer, nbands, f"{prefix}.layers[{i}].iops")
    first = layers[0].scattering
    for i, layer in enumerate(layers[1:], start=1):
        fld = f"{prefix}.layers[{i}].iops.scattering"
        if len(layer.scattering) != len(first):
            raise SceneError(label, fld, f"has {len(layer.scattering)} component(s) but layer 0 "
                                         f"has {len(first)}: every layer needs the same "
                                         f"components (phase functions), with b = 0 where absent")
        for j, (mine, ref) in enumerate(zip(layer.scattering, first)):
            if mine.phase != ref.phase:
                raise SceneError(label, f"{fld}[{j}].phase",
                                 f"is {_phase_text(mine.phase)} but layer 0's component {j} is "
                                 f"{_phase_text(ref.phase)}: layers may differ only in a and b")


def _validate_grid(label: str, grid: IOPGrid, nbands: int) -> None:
    """Base and unit IOPs with the same components, unit coefficients >= 0, a finite box of
    positive size, and 3-D arrays of finite densities >= 0 (every field's of one shape)."""
    if isinstance(grid.iops, IOPProfile):  # a depth profile under the grid
        _validate_profile(label, grid.iops, nbands, "iop_grid.base.iop_profile")
        ref_iops, ref_name = grid.iops.layers[0], "iop_grid.base.iop_profile.layers[0].iops"
    else:
        _validate_iops(label, grid.iops, nbands, "iop_grid.base.iops")
        ref_iops, ref_name = grid.iops, "iop_grid.base.iops"
    extra = grid.extra_fields
    if not isinstance(extra, list) or not all(isinstance(f, GridField) for f in extra):
        raise SceneError(label, "iop_grid.fields", f"must be a list of GridField, got {_show(extra)}")
    if len(extra) > MAX_GRID_FIELDS - 1:
        raise SceneError(label, "iop_grid.fields", f"has {len(extra)} fields: a grid holds at most "
                                                   f"{MAX_GRID_FIELDS - 1} beside its 'density'")
    names = [f.name for f in extra]
    for i, f in enumerate(extra):
        if not isinstance(f.name, str) or not f.name or f.name in names[:i]:
            raise SceneError(label, f"iop_grid.fields[{i}].name",
                             f"must be a non-empty name of its own, got {f.name!r}")
    units = [("iop_grid.unit.iops", grid.unit)] + [(f"iop_grid.fields[{i}].unit.iops", f.unit)
                                                   for i, f in enumerate(extra)]
    for prefix, unit in units:
        _validate_iops(label, unit, nbands, prefix)
        fld = f"{prefix}.scattering"
        if len(unit.scattering) != len(ref_iops.scattering):
            raise SceneError(label, fld, f"has {len(unit.scattering)} component(s) but "
                                         f"{ref_name} has {len(ref_iops.scattering)}: the unit "
                                         f"IOPs need the same components (phase functions), with "
                                         f"b = 0 where absent")
        for j, (mine, ref) in enumerate(zip(unit.scattering, ref_iops.scattering)):
            if mine.phase != ref.phase:
                raise SceneError(label, f"{fld}[{j}].phase",
                                 f"is {_phase_text(mine.phase)} but {ref_name} component {j} is "
                                 f"{_phase_text(ref.phase)}")
            if np.any(np.asarray(mine.b) < 0):
                raise SceneError(label, f"{fld}[{j}].b", f"must be >= 0 in every band, got "
                                                         f"{_show(mine.b)}")
        if np.any(np.asarray(unit.absorption) < 0):
            raise SceneError(label, f"{prefix}.absorption", f"must be >= 0 in every band, got "
                                                            f"{_show(unit.absorption)}")
    for fld, v in (("origin", grid.origin), ("size", grid.size)):
        if (not isinstance(v, np.ndarray) or v.shape != (3,) or v.dtype.kind not in "fiu"
                or not np.all(np.isfinite(v))):
            raise SceneError(label, f"iop_grid.{fld}", f"must be 3 finite numbers [x, y, z] "
                                                      f"(m), got {_show(v)}")
    if not np.all(grid.size > 0):
        raise SceneError(label, "iop_grid.size", f"must be > 0 along every axis, got "
                                                 f"{_show(grid.size)}")
    far = np.maximum(np.abs(grid.origin), np.abs(grid.origin + grid.size))
    if np.any(far > MAX_COORDINATE_M):
        raise SceneError(label, "iop_grid.size" if np.all(np.abs(grid.origin) <= MAX_COORDINATE_M)
                         else "iop_grid.origin", f"the box [origin, origin + size] must lie "
                                                 f"{_COORD_TEXT}, got origin {_show(grid.origin)}, "
                                                 f"size {_show(grid.size)}")
    # The core keeps the box in single precision: a size below about 1e-6 of the corner's
    # distance from the origin gave corners that coincide (a ValueError from the core, issue 49).
    small = grid.size < 1e-6 * np.maximum(1.0, far)
    if np.any(small):
        axis = int(np.flatnonzero(small)[0])
        raise SceneError(label, f"iop_grid.size[{axis}]",
                         f"must be at least {1e-6 * max(1.0, float(far[axis])):.3g} m (1e-6 of the "
                         f"box's distance from the origin, at least 1 um: the box is kept in single "
                         f"precision), got {_num(float(grid.size[axis]))}")
    for fld, d in [("iop_grid.density", grid.density)] + [(f"iop_grid.fields[{i}].density", f.density)
                                                          for i, f in enumerate(extra)]:
        if not isinstance(d, np.ndarray) or d.ndim != 3 or d.dtype.kind not in "fiu" or 0 in d.shape:
            shape = f"shape {d.shape}" if isinstance(d, np.ndarray) else _show(d)
            raise SceneError(label, fld, f"must be a non-empty 3-D array of numbers "
                                         f"(nx, ny, nz), got {shape}")
        if d.shape != grid.density.shape:
            raise SceneError(label, fld, f"has shape {d.shape} but iop_grid.density has "
                                         f"{grid.density.shape}: the fields share the grid's voxels")
        # min and max pass over the array without temporaries (a NaN makes both NaN); only a
        # bad array is searched for its first bad voxel
        if d.size and not (d.min() >= 0 and np.isfinite(d.max())):
            i = tuple(int(x) for x in np.argwhere(~(np.isfinite(d) & (d >= 0)))[0])
            raise SceneError(label, f"{fld}{list(i)}", f"must be finite and >= 0, got "
                                                       f"{_num(float(d[i]))}")


def _phase_text(p: PhaseFunction) -> str:
    params = ", ".join(f"{k}={_num(v)}" for k, v in p.params.items())
    return f"{p.type!r}" + (f" ({params})" if params else "")


def _validate_water(label: str, w: WaterBody, nbands: int, materials: dict) -> None:
    _check_choice(label, "type", w.type, WATER_TYPES)
    check_parameter(label, "water.ior", w.ior)
    if isinstance(w.iops, IOPProfile):
        _validate_profile(label, w.iops, nbands)
    elif isinstance(w.iops, IOPGrid):
        _validate_grid(label, w.iops, nbands)
    else:
        _validate_iops(label, w.iops, nbands)
    if w.fluorescence is not None or w.cdom_fluorescence is not None:
        _validate_fluorescence(label, w, nbands)
    if w.type == "mesh":
        for attr in ("surface", "bottom_depth", "bottom_material"):
            if getattr(w, attr) is not None:
                raise SceneError(label, attr, "only allowed for water of type 'ocean'")
        _check_mesh(label, "", w.mesh)
        _check_closed(label, w.mesh)
        return
    if w.mesh is not None:
        raise SceneError(label, "mesh", "only allowed for water of type 'mesh'")
    _validate_surface(label, w.surface)
    if w.bottom_depth is not None or w.bottom_material is not None:
        check_parameter(label, "bottom.depth", w.bottom_depth, "bottom_depth")
        _check_material_ref(label, "bottom_material", w.bottom_material, materials)


def _base_absorptions(w: WaterBody) -> list[np.ndarray]:
    """The water's own absorption per band, per layer of its base (a grid's fields aside)."""
    base = w.iops.iops if isinstance(w.iops, IOPGrid) else w.iops
    layers = base.layers if isinstance(base, IOPProfile) else [base]
    return [np.asarray(x.absorption, float) for x in layers]


def _validate_fluorescence(label: str, w: WaterBody, nbands: int) -> None:
    from .model import CDOMFluorescence, ChlorophyllFluorescence
    layers = _base_absorptions(w)
    parts = []  # (field, what, its absorption per layer)
    for fld, cls, what in (("chlorophyll_fluorescence", ChlorophyllFluorescence, "phytoplankton's"),
                           ("cdom_fluorescence", CDOMFluorescence, "CDOM's")):
        f = w.fluorescence if cls is ChlorophyllFluorescence else w.cdom_fluorescence
        if f is None:
            continue
        if not isinstance(f, cls):
            raise SceneError(label, fld, f"must be a {cls.__name__}, got {_show(f)}")
        a = np.asarray(f.absorption)
        if a.dtype == object or not (a.shape == (nbands,) or (len(layers) > 1 and a.shape == (len(layers), nbands))):
            per_layer = f", or one list per layer ({len(layers)} x {nbands})" if len(layers) > 1 else ""
            raise SceneError(label, f"{fld}.absorption", f"must hold one value per band ({nbands}){per_layer}, "
                                                         f"got shape {_show(list(np.shape(a)))}")
        a = a.astype(float)
        if not np.all(np.isfinite(a)) or np.any(a < 0):
            raise SceneError(label, f"{fld}.absorption", f"must be finite numbers >= 0 (m^-1), got {_show(a.tolist())}")
        parts.append((fld, what, a if a.ndim == 2 else [a] * len(layers)))
        if cls is ChlorophyllFluorescence:
            _check_real(label, f"{fld}.quantum_yield", f.quantum_yield, 0.0, 1.0)
            _check_real(label, f"{fld}.peak_nm", f.peak_nm, 300.0, 1000.0)
            _check_real(label, f"{fld}.fwhm_nm", f.fwhm_nm, 0.0, 200.0, lo_open=True)
        else:  # (Hawes' yield is at most 1.9 %: 50 x makes it about 1)
            _check_real(label, f"{fld}.efficiency_scale", f.efficiency_scale, 0.0, 50.0)
    # each, and both together, are parts of the water's absorption
    for li, total in enumerate(layers):
        where = f" in layer {li}" if len(layers) > 1 else ""
        summed = np.zeros(nbands)
        for fld, what, rows in parts:
            summed = summed + rows[li]
            over = np.nonzero(rows[li] > total * (1.0 + 1e-12))[0]
            if over.size:
                k = int(over[0])
                raise SceneError(label, f"{fld}.absorption", f"is the {what} part of the water's absorption, so at "
                                                             f"most it: band {k}{where} has {rows[li][k]:g} m^-1 "
                                                             f"against the water's {total[k]:g}")
        over = np.nonzero(summed > total * (1.0 + 1e-12))[0]
        if len(parts) == 2 and over.size:
            k = int(over[0])
            raise SceneError(label, "cdom_fluorescence.absorption",
                             f"with chlorophyll_fluorescence.absorption is more than the water's absorption: band {k}"
                             f"{where} has {summed[k]:g} m^-1 of phytoplankton and CDOM against the water's {total[k]:g}")


def _validate_surface(label: str, surface: Any) -> None:
    if not isinstance(surface, OceanSurface):
        raise SceneError(label, "surface", "an ocean needs a surface (OceanSurface)")
    _check_choice(label, "surface.kind", surface.kind, SURFACE_KINDS)
    check_parameter(label, "surface.z", surface.z, "surface.z")
    if surface.kind != "waves" and surface.waves is not None:
        raise SceneError(label, "surface.waves", "only allowed for surface kind 'waves'")
    r = surface.roughness
    if r is not None:
        if not isinstance(r, SurfaceRoughness):
            raise SceneError(label, "surface.roughness", f"must be a SurfaceRoughness, got {_show(r)}")
        check_parameter(label, "surface.roughness.wind_speed", r.wind_speed, "surface.roughness.wind_speed")
        if not isinstance(r.anisotropic, bool):
            raise SceneError(label, "surface.roughness.anisotropic", f"must be true or false, got {_show(r.anisotropic)}")
        if r.wind_direction_deg is not None:
            _check_real(label, "surface.roughness.wind_direction_deg", r.wind_direction_deg)
    if surface.kind in ("flat", "waves"):
        for attr in ("mesh", "period"):
            if getattr(surface, attr) is not None:
                raise SceneError(label, f"surface.{attr}", "only allowed for surface kind "
                                                           "'patch'")
    if surface.kind == "waves":
        from ..waves import SurfaceFoldsError, WaveModel, WaveNumbersError

        if not isinstance(surface.waves, WaveModel):
            raise SceneError(label, "surface.waves", f"a photic.waves.WaveModel is required, "
                                                     f"got {_show(surface.waves)}")
        surface.waves.validate(label, "surface.")
        nx, ny = surface.waves.resolution
        # A choppy surface can fold over, and any may overflow: generated now when choppy or
        # small (22 s at 4096 x 4096, 0.1 s at 256 x 256; a render builds it anyway, cached),
        # else checked when the render builds it (photic.compile).
        if surface.waves.choppiness > 0 or nx * ny <= 256 * 256:
            try:
                surface.patch()
            except SurfaceFoldsError as exc:
                raise SceneError(label, "surface.choppiness", str(exc)) from None
            except WaveNumbersError as exc:
                raise SceneError(label, "surface", str(exc)) from None
        return
    if surface.kind == "flat":
        return
    _check_mesh(label, "surface.", surface.mesh)
    if surface.normals is not None:
        nrm = surface.normals
        if not isinstance(nrm, np.ndarray) or nrm.shape != surface.mesh.vertices.shape or \
                not np.all(np.isfinite(nrm)) or np.any(nrm[:, 2] <= 0):
            raise SceneError(label, "surface.normals", "must be finite (N, 3) vertex normals "
                                                       "pointing up, one per vertex")
    period = surface.period
    if not isinstance(period, tuple) or len(period) != 2:
        raise SceneError(label, "surface.period", f"must be [Lx, Ly], got {_show(period)}")
    for i, p in enumerate(period):
        check_parameter(label, "surface.period", p, f"surface.period[{i}]")
    v, t = surface.mesh.vertices, surface.mesh.triangles
    # The patch tiles the plane, so its xy extent must be exactly one period.
    extent = v[:, :2].max(axis=0) - v[:, :2].min(axis=0)
    for i, axis in enumerate("xy"):
        if abs(extent[i] - period[i]) > 1e-6 * period[i]:
            raise SceneError(label, f"surface.period[{i}]",
                             f"is {_num(period[i])} but the patch vertices span "
                             f"{extent[i]:.9g} m in {axis}")
    # A height field with water below: every triangle must face upwards.
    normal_z = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2]
    bad = np.flatnonzero(normal_z <= 0)
    if len(bad):
        raise SceneError(label, f"surface.triangles[{bad[0]}]",
                         "must face upwards (normal z > 0): the patch is a height field with "
                         "the water below it")
    _check_patch_covers_period_once(label, v, t, period)
    mean_z = float(np.mean(v[:, 2]))
    if abs(surface.z - mean_z) > 1e-9 * max(1.0, abs(mean_z)):
        raise SceneError(label, "surface.z", f"is {surface.z!r} but must equal the mean height "
                                             f"of the patch vertices, {mean_z!r}")


_PATCH_AREA_TOLERANCE = 1e-6  # relative: of the period's area, and of its size for edges


def _check_patch_covers_period_once(label: str, v: np.ndarray, t: np.ndarray, period) -> None:
    """A patch must be a single-valued height field z(x, y) over exactly one period: its
    (upward) triangles' areas projected on the xy plane sum to Lx Ly, and an edge that belongs
    to one triangle only lies on the period's border. A hole (less area, or an open edge
    inside) or a second sheet (twice the area) rendered with exit 0 and Ed 49 % / 26 % of the
    right value (issue 49)."""
    lx, ly = float(period[0]), float(period[1])
    lo = v[:, :2].min(axis=0)
    area = 0.0
    for start in range(0, len(t), _MESH_CHECK_BLOCK):
        tb = t[start:start + _MESH_CHECK_BLOCK]
        p0, p1, p2 = v[tb[:, 0], :2], v[tb[:, 1], :2], v[tb[:, 2], :2]
        area += 0.5 * float(np.sum((p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1])
                                   - (p1[:, 1] - p0[:, 1]) * (p2[:, 0] - p0[:, 0])))
    cover = area / (lx * ly)
    if abs(cover - 1.0) > _PATCH_AREA_TOLERANCE:
        why = ("more than one sheet, or triangles that overlap in x, y" if cover > 1 else
               "a hole: part of the period has no surface")
        raise SceneError(label, "surface.triangles",
                         f"the patch covers its period {cover:.6g} times (its triangles' area "
                         f"seen from above is {area:.6g} m^2, the period's {lx * ly:.6g} m^2): "
                         f"{why}; a patch must be a single-valued height field covering "
                         f"[{_num(lo[0])}, {_num(lo[0] + lx)}] x [{_num(lo[1])}, {_num(lo[1] + ly)}] "
                         f"m once")
    # Open edges only on the border (a hole balanced by an overlap elsewhere has the area).
    ids, n = _merged_vertex_ids(np.asarray(v, np.float64))
    a = np.concatenate([ids[t[:, 0]], ids[t[:, 1]], ids[t[:, 2]]])
    b = np.concatenate([ids[t[:, 1]], ids[t[:, 2]], ids[t[:, 0]]])
    keys = np.minimum(a, b) * n + np.maximum(a, b)
    uniq, first, counts = np.unique(keys, return_index=True, return_counts=True)
    if np.any(counts > 2):
        raise SceneError(label, "surface.triangles",
                         f"{int(np.count_nonzero(counts > 2))} edge(s) belong to more than two "
                         f"triangles: the patch is not a single-valued height field (stacked "
                         f"or folded sheets)")
    open_ = first[counts == 1] % len(a)  # position of each open edge in (a, b)
    ends = np.concatenate([a[open_], b[open_]])
    # (the merged ids' vertices: any vertex of an id has the same position to 1e-8 m)
    rep = np.empty(n, np.int64)
    rep[ids] = np.arange(len(ids))
    xy = v[rep[ends], :2] - lo
    tol = _PATCH_AREA_TOLERANCE * np.array([lx, ly])
    half = len(open_)
    on_side = [np.abs(xy[:, 0]) <= tol[0], np.abs(xy[:, 0] - lx) <= tol[0],
               np.abs(xy[:, 1]) <= tol[1], np.abs(xy[:, 1] - ly) <= tol[1]]
    along = np.zeros(half, bool)  # both ends on one side of the period's rectangle
    for side in on_side:
        along |= side[:half] & side[half:]
    inside = ~along
    if np.any(inside):
        i = int(np.flatnonzero(inside)[0])
        raise SceneError(label, "surface.triangles",
                         f"{int(np.count_nonzero(inside))} edge(s) inside the period belong to "
                         f"one triangle only (e.g. from {np.round(xy[i] + lo, 9).tolist()} to "
                         f"{np.round(xy[half + i] + lo, 9).tolist()} m): a hole in the patch")


def _validate_sun(sun: Sun, nbands: int) -> None:
    check_parameter("sun", "sun.zenith_deg", sun.zenith_deg)
    _check_real("sun", "azimuth_deg", sun.azimuth_deg)
    check_per_band_parameter("sun", "sun.irradiance", sun.irradiance, nbands)
    check_parameter("sun", "sun.angular_diameter_deg", sun.angular_diameter_deg)


def _validate_sky(sky: Any, nbands: int) -> None:
    if not isinstance(sky, Sky):
        raise SceneError("sky", "type", "a Sky is required (Sky('black') for none)")
    _check_choice("sky", "type", sky.type, SKY_TYPES)
    if sky.type == "black":
        if sky.radiance_scale is not None:
            raise SceneError("sky", "radiance_scale", "must be None for a black sky")
        return
    check_per_band_parameter("sky", "sky.radiance", sky.radiance_scale, nbands, "radiance_scale")
    if (sky.table is not None) != (sky.type == "environment"):
        raise SceneError("sky", "table", "an 'environment' sky needs a table, and only it has one")
    if sky.type == "environment":
        t = sky.table
        if not isinstance(t, np.ndarray) or t.ndim != 3 or t.shape[0] < 2 or t.shape[1] < 1 or \
                t.shape[2] != nbands:
            raise SceneError("sky", "table", f"must be an array (n_theta >= 2, n_phi >= 1, {nbands}) "
                                             f"of relative radiances, got {getattr(t, 'shape', _show(t))}")
        if not np.all(np.isfinite(t)) or t.min() < 0:
            raise SceneError("sky", "table", "relative radiances must be finite and >= 0")
    check_parameter("sky", "sky.cloud_fraction", sky.cloud_fraction)
    if sky.cloud_fraction and sky.type != "harrison_coombes":
        raise SceneError("sky", "cloud_fraction", "only for sky type 'harrison_coombes'")
    if sky.full_sphere and sky.type != "uniform":
        raise SceneError("sky", "full_sphere", f"only a uniform sky can cover the full sphere, not '{sky.type}'")


def _validate_camera(label: str, c: Camera) -> None:
    _check_choice(label, "type", c.type, CAMERA_TYPES)
    _check_vec3(label, "position", c.position, position=True)
    _check_vec3(label, "direction", c.direction, nonzero=True)
    _check_vec3(label, "up", c.up, nonzero=True)
    d = c.direction / np.linalg.norm(c.direction)
    u = c.up / np.linalg.norm(c.up)
    if np.linalg.norm(np.cross(d, u)) < 1e-6:
        raise SceneError(label, "up", f"is parallel to the viewing direction {d.tolist()}")
    check_parameter(label, "camera.fov_deg", c.fov_deg)
    check_parameter(label, "camera.ortho_width", c.ortho_width)
    if not isinstance(c.resolution, tuple) or len(c.resolution) != 2:
        raise SceneError(label, "resolution", f"must be [width, height], got "
                                              f"{_show(c.resolution)}")
    for i, n in enumerate(c.resolution):
        check_parameter(label, "camera.resolution", n, f"resolution[{i}]")
    _check_choice(label, "filter.type", c.filter_type, FILTER_TYPES)
    check_parameter(label, "camera.filter.width_px", c.filter_width_px)
    if not isinstance(c.shift, tuple) or len(c.shift) != 2:
        raise SceneError(label, "shift", f"must be [x, y], got {_show(c.shift)}")
    for i, x in enumerate(c.shift):
        check_parameter(label, "camera.shift", x, f"shift[{i}]")
    check_parameter(label, "camera.clip_start", c.clip_start)


def _validate_radiometer(label: str, r: Radiometer) -> None:
    _check_choice(label, "quantity", r.quantity, QUANTITIES)
    _check_vec3(label, "position", r.position, position=True)
    _check_vec3(label, "direction", r.direction, nonzero=True)
    check_parameter(label, "radiometer.half_angle_deg", r.half_angle_deg)
    check_parameter(label, "radiometer.polar_bins", r.polar_bins)
    check_parameter(label, "radiometer.azimuth_bins", r.azimuth_bins)
    if r.quantity == "radiance_distribution" and r.polar_bins * r.azimuth_bins > MAX_DISTRIBUTION_BINS:
        raise SceneError(label, "azimuth_bins", f"polar_bins x azimuth_bins must be at most "
                                                f"{MAX_DISTRIBUTION_BINS:,}, got {r.polar_bins:,} x "
                                                f"{r.azimuth_bins:,} = {r.polar_bins * r.azimuth_bins:,}")


def _validate_radiometer_array(label: str, a: RadiometerArray) -> None:
    if not isinstance(a.quantities, (list, tuple)) or not a.quantities:
        raise SceneError(label, "quantities", "at least one quantity is required")
    for i, q in enumerate(a.quantities):
        _check_choice(label, f"quantities[{i}]", q, QUANTITIES)
    p = a.positions
    if not isinstance(p, np.ndarray) or p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise SceneError(label, "positions", "must be a non-empty (N, 3) array of points")
    if len(p) > MAX_ARRAY_RADIOMETERS:
        raise SceneError(label, "positions", f"at most {MAX_ARRAY_RADIOMETERS:,} radiometers per "
                                             f"array, got {len(p):,}")
    for i, point in enumerate(p):
        _check_vec3(label, f"positions[{i}]", point, position=True)
    if a.direction is not None:
        _check_vec3(label, "direction", a.direction, nonzero=True)
    if a.half_angle_deg is not None:
        check_parameter(label, "radiometer.half_angle_deg", a.half_angle_deg)


def _validate_settings(s: Settings) -> None:
    _check_choice("settings", "integrator", s.integrator, INTEGRATORS)
    for key in ("samples", "radiometer_samples", "seed", "max_depth", "threads", "beam_max_level",
                "adaptive_min_samples"):
        check_parameter("settings", f"settings.{key}", getattr(s, key))
    if s.forward_cone_deg != "auto":
        check_parameter("settings", "settings.forward_cone_deg", s.forward_cone_deg)
    if not isinstance(s.sun_disk_blur, (bool, np.bool_)):
        raise SceneError("settings", "sun_disk_blur", f"must be true or false, got {_show(s.sun_disk_blur)}")
    if not (isinstance(s.raman, (bool, np.bool_)) or s.raman == "auto"):
        raise SceneError("settings", "raman", f"must be true, false or \"auto\", got {_show(s.raman)}")
    for key in ("target_error", "noise_threshold"):
        if getattr(s, key) is not None:
            check_parameter("settings", f"settings.{key}", getattr(s, key))


