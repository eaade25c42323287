"""Turns a validated scene description into the compiled core's scene.

This is the only place that knows both sides: the description (photic.scene, plain Python)
and the core's builder calls (photic._core). Large band lists are split into groups of at
most ``_core.MAX_BANDS`` bands; each group is a separate compiled scene sharing the geometry.
"""
from __future__ import annotations

import numpy as np

from . import _core
from .phase import make_core_phase
from .scene import IOPGrid, IOPProfile, Scene, SceneError

QUANTITY_CODES = {"Ed": 0, "Eu": 1, "Eo": 2, "Eod": 3, "Eou": 4,
                  "radiance": 5, "radiance_distribution": 6}
SKY_CODES = {"black": 0, "uniform": 1, "cardioidal": 2, "harrison_coombes": 3, "environment": 4}
MAX_BANDS = int(_core.MAX_BANDS)


def band_groups(nbands: int) -> list[slice]:
    """Slices of at most MAX_BANDS bands covering all bands."""
    return [slice(i, min(i + MAX_BANDS, nbands)) for i in range(0, nbands, MAX_BANDS)]


BAND_SPLIT_RATIO = 100.0  # bands whose scattering differs more than this render apart


def _iops_scattering(iops) -> np.ndarray:
    """Largest total scattering b (1/m) per band of homogeneous IOPs, a profile's layers or a
    grid (base plus the fields' units at their largest densities)."""
    from .scene import IOPGrid, IOPProfile
    if isinstance(iops, IOPGrid):
        b = _iops_scattering(iops.iops)
        fields = [(iops.unit, iops.density)] + [(f.unit, f.density) for f in iops.extra_fields]
        for unit, rho in fields:
            b = b + float(np.max(rho)) * _iops_scattering(unit)
        return b
    if isinstance(iops, IOPProfile):
        return np.max([_iops_scattering(layer) for layer in iops.layers], axis=0)
    return np.asarray(iops.total_scattering, float)


def scene_band_groups(scene) -> list[slice]:
    """The band groups a scene renders in: runs of consecutive bands, at most MAX_BANDS each,
    whose largest scattering (over the water bodies, with a floor of 1 per m) differ by at most
    BAND_SPLIT_RATIO. A path carries all the bands of its group and its free flights follow the
    group's largest scattering: one band of b = 1e5 per m made a band of 0.1 take 1e5 null
    collisions per metre (45 s instead of 0.1 s). Scenes without such contrasts keep
    band_groups(n) exactly (the same numbers)."""
    nb = len(scene.bands)
    try:
        b = np.ones(nb)
        for w in scene.water:
            b = np.maximum(b, _iops_scattering(w.iops))
    except (AttributeError, TypeError, ValueError):
        return band_groups(nb)
    groups, start, lo, hi = [], 0, b[0] if nb else 1.0, b[0] if nb else 1.0
    for k in range(1, nb):
        nlo, nhi = min(lo, b[k]), max(hi, b[k])
        if k - start >= MAX_BANDS or nhi > BAND_SPLIT_RATIO * nlo:
            groups.append(slice(start, k))
            start, nlo, nhi = k, b[k], b[k]
        lo, hi = nlo, nhi
    if nb:
        groups.append(slice(start, nb))
    return groups


def inelastic_group_warnings(scene) -> list[str]:
    """The bands that lose inelastic light (Raman, fluorescence) to the band groups (a path
    carries only its group's bands; scene_band_groups)."""
    from .inelastic import KIND_NAMES, water_processes
    groups = scene_band_groups(scene)
    if len(groups) < 2:
        return []
    group_of = np.empty(len(scene.bands), int)
    for g, sl in enumerate(groups):
        group_of[sl] = g
    processes = [(k, c) for w in scene.water for k, c, _ in water_processes(scene, w)]
    out = []
    for kind in sorted({k for k, _ in processes}):
        coupling = sum(np.asarray(c).reshape(-1, *np.shape(c)[-2:]).sum(axis=0)
                       for k, c in processes if k == kind)
        apart = coupling * (group_of[:, None] != group_of[None, :])
        lost = [scene.bands[j].name for j in range(len(scene.bands)) if apart[j].sum() > 0.01 * coupling[j].sum()]
        if lost:
            out.append(f"the bands render in {len(groups)} groups (at most 16 bands, and bands whose scattering "
                       f"differs a hundredfold, render apart) and {KIND_NAMES[kind]} light does not cross groups: bands "
                       f"{', '.join(repr(n) for n in lost)} lose what comes from another group")
    return out


def set_ocean_patch(core, wi: int, w) -> None:
    """Water ``wi``'s ocean patch (given, or generated from its wave model) into ``core``."""
    from .waves import SurfaceFoldsError, WaveNumbersError
    try:
        mesh, period, normals = w.surface.patch()
    except (SurfaceFoldsError, WaveNumbersError) as exc:
        raise SceneError(f"water '{w.name}'", "surface", str(exc)) from None
    v = np.asarray(mesh.vertices, np.float64)
    tri = _oriented_up(v, np.asarray(mesh.triangles, np.int64))
    core.set_ocean_patch(wi, v.astype(np.float32), tri.astype(np.uint32), float(v[:, 0].min()),
                         float(v[:, 1].min()), float(period[0]), float(period[1]), float(w.surface.z),
                         None if normals is None else normals.astype(np.float32))


def _oriented_up(vertices: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Triangles of a height-field patch wound so their normals point up (air side).

    Only the z component of each normal is needed: it is computed from the x and y columns
    in blocks, so a patch of millions of triangles needs no (M, 3, 3) temporary."""
    x, y = vertices[:, 0], vertices[:, 1]
    tri = triangles.copy()
    block = 1 << 18
    for start in range(0, len(tri), block):
        t = tri[start:start + block]  # a view: flipped in place
        x0, y0 = x[t[:, 0]], y[t[:, 0]]
        nz = (x[t[:, 1]] - x0) * (y[t[:, 2]] - y0) - (y[t[:, 1]] - y0) * (x[t[:, 2]] - x0)
        flip = nz < 0
        t[flip] = t[flip][:, [0, 2, 1]]
    return tri


def compile_scene(scene: Scene, bands: slice | None = None, seed: int | None = None,
                  max_depth: int | None = None, hybrid: bool = False,
                  forward_cone_deg: float = 0.0, threads: int | None = None) -> _core.Scene:
    """Build and commit the core scene for one group of bands.

    ``hybrid`` selects the hybrid integrator (beams must then be built for each pass with
    ``core.build_beams``); ``forward_cone_deg`` is the forward-scattering cone's half-angle;
    ``threads`` (default: the scene's setting; 0 = all cores) build its grids.
    """
    bands = bands or slice(0, len(scene.bands))
    nb = len(range(*bands.indices(len(scene.bands))))
    if not 1 <= nb <= MAX_BANDS:
        raise ValueError(f"a band group must hold 1..{MAX_BANDS} bands, got {nb}")
    sel = lambda arr: np.ascontiguousarray(np.asarray(arr, dtype=np.float64)[bands])

    core = _core.Scene()
    core.nbands = nb
    core.seed = int(scene.settings.seed if seed is None else seed) & ((1 << 64) - 1)
    core.max_depth = int(scene.settings.max_depth if max_depth is None else max_depth)
    core.hybrid = bool(hybrid)
    core.beam_max_level = int(scene.settings.beam_max_level)
    core.beam_sun_blur = bool(scene.settings.sun_disk_blur)

    mat_index = {}
    for name, mat in scene.materials.items():
        mi = mat_index[name] = core.add_material(sel(mat.reflectance))
        if mat.emission is not None:
            core.set_material_emission(mi, sel(mat.emission))
        if mat.texture is not None:
            img = np.asarray(mat.texture.image, np.float32)[:, :, bands]
            core.set_material_texture(mi, np.ascontiguousarray(img), mat.texture.wrap == "clamp",
                                      mat.texture.interpolation == "closest")

    # Inelastic processes (photic.inelastic): Raman scattering (settings.raman) takes b_R from
    # each band (added to its absorption; fluorescence's loss, the phytoplankton's absorption,
    # is in the water's already), and light comes back in the bands it shifts to (the
    # couplings), only between the bands of this group (render warns when groups part them).
    from .inelastic import raman_active, raman_b, water_processes
    b_raman = None
    if raman_active(scene):
        b_raman = sel(raman_b(np.array([b.center_nm for b in scene.bands], float)))
    loss = (lambda a: sel(a) + b_raman) if b_raman is not None else sel

    water_index = {}
    for w in scene.water:
        # Stratified water: the first layer makes the water body, the others go below it
        # (every layer has the same components: phase functions, in the same order).
        # A grid adds density x unit IOPs to its base: homogeneous IOPs or a depth profile.
        grid = w.iops if isinstance(w.iops, IOPGrid) else None
        base = grid.iops if grid is not None else w.iops
        layers = base.layers if isinstance(base, IOPProfile) else [base]
        comps = []
        for comp in layers[0].scattering:
            pid = core.add_phase(make_core_phase(comp.phase.type, comp.phase.params))
            comps.append((pid, sel(comp.b)))
        if not comps:  # no scattering component: a purely absorbing body
            comps.append((core.add_phase(make_core_phase("isotropic")), np.zeros(nb)))
        wi = core.add_water(float(w.ior), loss(layers[0].absorption), comps)
        for z_top, layer in zip(np.asarray(base.z_top)[1:] if len(layers) > 1 else [], layers[1:]):
            b = [sel(c.b) for c in layer.scattering] or [np.zeros(nb)]
            core.add_water_layer(wi, float(z_top), loss(layer.absorption), b)
        for kind, coupling, rho in water_processes(scene, w):  # (in the base, whatever a grid adds)
            core.set_water_inelastic(wi, kind, np.ascontiguousarray(coupling[..., bands, bands]), rho)
        if grid is not None:  # 3-D IOPs: base + each field's density x its unit over the box
            origin = np.asarray(grid.origin, dtype=np.float64)
            units = grid.units()
            # each field as it is (float32 C-ordered: read in place, no copy of a large field)
            rho = [np.ascontiguousarray(d, dtype=np.float32) for d in grid.densities()]
            core.set_water_grid(wi, origin.tolist(), (origin + grid.size).tolist(), rho,
                                [sel(u.absorption) for u in units],
                                [[sel(c.b) for c in u.scattering] or [np.zeros(nb)] for u in units],
                                threads=int(scene.settings.threads if threads is None else threads))
        water_index[w.name] = wi

    for m in scene.meshes:
        gi = core.add_mesh(np.asarray(m.mesh.vertices, np.float32), np.asarray(m.mesh.triangles, np.uint32),
                           0, mat_index[m.material])
        if m.uv is not None and scene.materials[m.material].texture is not None:
            core.set_mesh_uv(gi, np.ascontiguousarray(m.uv, np.float32))
        if m.instances is not None:
            core.set_mesh_instances(gi, np.ascontiguousarray(m.instances, np.float32))

    for w in scene.water:
        wi = water_index[w.name]
        if w.type == "mesh":
            core.add_mesh(np.asarray(w.mesh.vertices, np.float32),
                          np.asarray(w.mesh.triangles, np.uint32), 1, wi)
        else:
            surf = w.surface
            if surf.kind == "flat":
                core.set_ocean_flat(wi, float(surf.z))
                zmean = float(surf.z)
            else:  # a patch, given or generated from a wave model
                set_ocean_patch(core, wi, w)
                zmean = float(surf.z)
            if surf.roughness is not None:
                core.set_ocean_roughness(*surf.slope_variances(float(w.ior)))
            if w.bottom_depth is not None:
                core.set_bottom(zmean - float(w.bottom_depth), mat_index[w.bottom_material])

    if scene.sun is not None:
        alpha = np.radians(scene.sun.angular_diameter_deg) / 2.0
        # Uniform disk: irradiance normal to the beam = L * pi * sin^2(alpha).
        radiance = sel(scene.sun.irradiance) / (np.pi * np.sin(alpha) ** 2)
        core.set_sun(tuple(float(c) for c in scene.sun.direction), radiance, float(np.cos(alpha)))

    sky = scene.sky
    l0 = sel(sky.radiance_scale) if sky.radiance_scale is not None else np.zeros(nb)
    core.set_sky(SKY_CODES[sky.type], l0, bool(getattr(sky, "full_sphere", False)))
    if sky.type == "environment":
        core.set_sky_table_bands(np.ascontiguousarray(np.asarray(sky.table, np.float64)[:, :, bands]))
    if sky.type == "harrison_coombes":
        from .sky import sky_table
        core.set_sky_table(sky_table(scene.sun.zenith_deg, scene.sun.azimuth_deg, sky.cloud_fraction))

    for cam in scene.cameras:
        core.add_camera(cam.type == "orthographic", tuple(map(float, cam.position)),
                        tuple(map(float, cam.direction)), tuple(map(float, cam.up)),
                        float(cam.fov_deg), float(cam.ortho_width),
                        int(cam.resolution[0]), int(cam.resolution[1]),
                        1 if cam.filter_type == "gaussian" else 0, float(cam.filter_width_px),
                        tuple(float(x) for x in cam.shift), float(cam.clip_start))

    for r in scene.all_radiometers():
        core.add_radiometer(QUANTITY_CODES[r.quantity], tuple(map(float, r.position)),
                            tuple(map(float, r.direction)), float(r.half_angle_deg),
                            int(r.polar_bins), int(r.azimuth_bins))
    core.set_forward_cone(float(np.radians(forward_cone_deg)))
    core.commit()
    return core
