"""Beams: flux conservation under focusing waves, agreement with the flat analytic beam,
shadows of objects, and numerically hard cases (grazing sun, foci, TIR from below)."""
import numpy as np
import pytest

from geometry import height_field
from photic._core import fresnel
from photic.colour import trapezoid
from photic.compile import compile_scene
from photic.render import render
from photic.scene import Scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)


def wave_patch(period=1.0, n=32, amp=0.01):
    """A periodic height field z = amp sin(kx) sin(ky): crests focus the sun at ~ n R/(n-1)."""
    k = 2 * np.pi / period
    return height_field(period, n, lambda x, y: amp * np.sin(k * x) * np.sin(k * y))


def wavy_sea(a=0.0, b=0.0, zenith=30.0, diameter=0.53, depth=20.0, amp=0.01, meshes=(), materials=None):
    v, t = wave_patch(amp=amp)
    d = {"photic_scene": 1, "name": "waves",
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]}, **(materials or {})},
         "meshes": list(meshes),
         "water": [{"name": "sea", "type": "ocean",
                    "surface": {"kind": "patch", "vertices": v, "triangles": t, "period": [1.0, 1.0]},
                    "bottom": {"depth": depth, "material": "sand"},
                    "iops": {"absorption": [a], "b": [b], "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": zenith, "azimuth_deg": 30.0, "irradiance": [1.0], "angular_diameter_deg": diameter},
         "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [0.3, 0.2, -5.0]}],
         "settings": {"integrator": "hybrid", "forward_cone_deg": 0, "seed": 2}}
    return Scene.from_dict(d)


def beams_for(scene, blur=True):
    """The scene's beams; blur=False: sharp prisms (no spreading over the sun's disk)."""
    core = compile_scene(scene, hybrid=True, forward_cone_deg=0.0)
    core.beam_sun_blur = blur
    core.build_beams(tuple(scene.sun.direction), 0)
    return core


@pytest.mark.parametrize("z", [-1.0, -4.0, -6.0, -8.0, -12.0, -18.0])
def test_flux_through_planes_equals_beam_flux_under_focusing_waves(z):
    """c = 0: every horizontal plane between surface and bottom carries the summed beam flux
    (to 1e-5), before, near and beyond the foci of the crests (~6 to 10 m down here)."""
    core = beams_for(wavy_sea())
    total = core.beam_total_flux()
    assert core.beam_count >= 2 * 32 * 32
    # Flux entering one period of the surface: E_sun cos(theta) T summed over the patch area.
    assert 0.8 < total < 0.87
    assert core.beam_flux_through_plane(z) == pytest.approx(total, rel=1e-5)


def test_point_queries_integrate_to_the_beam_flux(zscore):
    """Random points over one period at 8 m: the mean of the summed beam irradiance on the
    plane times the period's area equals the beam flux (caustics included)."""
    core = beams_for(wavy_sea())
    rng = np.random.default_rng(4)
    n = 20000
    xy = rng.random((n, 2)) + np.array([3.0, -7.0])  # periodic images are queried too
    vals = np.empty(n)
    for i, (x, y) in enumerate(xy):
        vals[i] = sum(e[0] * -d[2] for d, e in core.beams_at((x, y, -8.0), 0))
    mean, se = vals.mean(), vals.std(ddof=1) / np.sqrt(n)
    assert vals.max() > 3 * mean  # there are caustics
    assert abs(zscore("beam flux by point queries at 8 m", mean, core.beam_total_flux(), se)) < 4


def test_wavy_patch_beams_agree_with_path_tracing_on_average(zscore):
    """Averaged over a period the wavy surface transmits about what a flat one does, and
    the beams' Ed at 2 m (hybrid) matches pure path tracing with a 10 deg sun."""
    rads = [{"name": f"Ed{i}", "quantity": "Ed", "position": [x, y, -2.0]}
            for i, (x, y) in enumerate([(0.1, 0.2), (0.6, 0.3), (0.35, 0.8)])]
    hy_scene = wavy_sea(a=0.1, b=0.2, diameter=10.0, depth=4.0)
    hy_scene.radiometers = Scene.from_dict({"photic_scene": 1, "radiometers": rads}).radiometers
    pt_scene = wavy_sea(a=0.1, b=0.2, diameter=10.0, depth=4.0)
    pt_scene.radiometers = hy_scene.radiometers
    pt_scene.settings.integrator = "path"
    hy = render(hy_scene, radiometer_samples=40_000)
    pt = render(pt_scene, radiometer_samples=400_000)
    for r in hy.radiometers:
        p = pt.radiometer(r.name)
        se = float(np.hypot(r.stderr[0, 0], p.stderr[0, 0]))
        assert abs(zscore(f"waves hybrid vs path {r.name}", r.mean[0, 0], p.mean[0, 0], se)) < 3


def test_object_shadows_the_beam():
    """A plate 1 m below a flat surface: the beam below it is gone, beside it intact."""
    plate = {"name": "plate", "material": "sand",
             "vertices": [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1]], "triangles": [[0, 1, 2], [0, 2, 3]]}
    d = {"photic_scene": 1, "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]}},
         "meshes": [plate],
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0},
                    "iops": {"absorption": [0.1], "b": [0.0], "phase": {"type": "isotropic"}}}],
         "sun": {"zenith_deg": 0.0, "azimuth_deg": 0.0, "irradiance": [1.0]},
         "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [0, 0, -2]}]}
    core = beams_for(Scene.from_dict(d))
    assert core.beams_at((0.0, 0.0, -2.0), 0) == []
    (dd, e), = core.beams_at((3.0, 0.0, -2.0), 0)
    assert e[0] == pytest.approx((1 - 0.0211) * np.exp(-0.2), rel=1e-3)


@pytest.mark.parametrize("zenith", [85.0, 88.0, 89.5])
def test_grazing_sun_gives_finite_beams(zenith):
    scene = wavy_sea(a=0.1, b=0.3, zenith=zenith, diameter=0.53, depth=5.0, amp=0.03)
    res = render(scene, radiometer_samples=1024)
    r = res.radiometer("Ed")
    assert np.isfinite(r.mean).all() and (r.mean >= 0).all() and np.isfinite(r.stderr).all()


def test_radiometer_in_a_caustic_and_deep_hard_water():
    """A radiometer at a focus of the crests (finite sun bounds it), albedo 0.99 and optical
    depth 50: finite, non-negative numbers."""
    scene = wavy_sea(a=0.05, b=4.95, depth=60.0, diameter=0.53)
    scene.radiometers[0].position = np.array([0.25, 0.25, -10.0])
    res = render(scene, radiometer_samples=512)
    for r in res.radiometers:
        assert np.isfinite(r.mean).all() and (r.mean >= 0).all()
    scene = wavy_sea(a=0.0, b=0.0, depth=20.0, diameter=0.53)
    core = beams_for(scene)
    vals = [sum(e[0] for _, e in core.beams_at((x, y, -7.0), 0)) for x in np.linspace(0, 1, 41) for y in np.linspace(0, 1, 41)]
    assert np.isfinite(vals).all() and max(vals) < 1e6


def test_camera_in_a_caustic_and_looking_at_total_internal_reflection():
    """An underwater camera at the crests' focal depth, one half of its view looking up beyond
    the critical angle (total internal reflection from below): finite, non-negative pixels,
    beams present on the bottom."""
    scene = wavy_sea(a=0.05, b=0.1, depth=12.0)
    scene.cameras = Scene.from_dict({"photic_scene": 1, "cameras": [
        {"name": "focus", "type": "perspective", "position": [0.25, 0.25, -8.0], "direction": [1, 0, 0.3],
         "up": [0, 0, 1], "fov_deg": 90, "resolution": [12, 8]}]}).cameras
    res = render(scene, samples=4, radiometer_samples=1024)
    img = res.images["focus"]
    assert np.isfinite(img.mean).all() and (img.mean >= 0).all()
    assert img.components["beam_surface"].max() > 0 or img.components["beam_volume"].max() > 0


def test_lookups_find_exactly_the_prisms_covering_a_point():
    """The beam grid's lookups (cell records, key tests, prefetched rounds) against a brute
    force over all prisms and their periodic images: at random points from just below the
    surface to beyond the crests' foci, beams_at returns one beam per prism whose slice holds
    the point, including at foci where many prisms overlap. (Sharp prisms; the blurred ones'
    lookups are checked against the core's own brute force below.)"""
    core = beams_for(wavy_sea(), blur=False)
    v, d, length = (np.asarray(a) for a in core.prism_arrays()[:3])
    assert (d[:, :, 2] < -0.1).all()  # all sliced horizontally (the brute force below assumes it)
    rng = np.random.default_rng(11)
    pts = np.column_stack([rng.uniform(-1.5, 2.5, 400), rng.uniform(-1.5, 2.5, 400), rng.uniform(-16.0, -0.5, 400)])
    counts = []
    for p in pts:
        t = (v[:, :, 2] - p[2]) / -d[:, :, 2]  # along each vertex ray, to the point's height
        c = v + d * t[:, :, None]              # the slices' corners there (primary period)
        n = 0
        # the periods whose images of the slices can hold the point (rays drift metres sideways)
        for i in range(int(np.ceil(p[0] - c[:, :, 0].max())), int(np.floor(p[0] - c[:, :, 0].min())) + 1):
            for j in range(int(np.ceil(p[1] - c[:, :, 1].max())), int(np.floor(p[1] - c[:, :, 1].min())) + 1):
                y = p - np.array([i * 1.0, j * 1.0, 0.0])
                e0 = (c[:, 1, 0] - y[0]) * (c[:, 2, 1] - y[1]) - (c[:, 2, 0] - y[0]) * (c[:, 1, 1] - y[1])
                e1 = (c[:, 2, 0] - y[0]) * (c[:, 0, 1] - y[1]) - (c[:, 0, 0] - y[0]) * (c[:, 2, 1] - y[1])
                area = (c[:, 1, 0] - c[:, 0, 0]) * (c[:, 2, 1] - c[:, 0, 1]) - (c[:, 2, 0] - c[:, 0, 0]) * (c[:, 1, 1] - c[:, 0, 1])
                with np.errstate(divide="ignore", invalid="ignore"):
                    l0, l1 = e0 / area, e1 / area
                l2 = 1.0 - l0 - l1
                inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0) & (area != 0)
                l_here = l0 * t[:, 0] + l1 * t[:, 1] + l2 * t[:, 2]
                l_end = l0 * length[:, 0] + l1 * length[:, 1] + l2 * length[:, 2]
                n += int(np.count_nonzero(inside & (l_here >= 0) & (l_here <= l_end)))
        got = len(core.beams_at(tuple(map(float, p)), 0))
        assert got == n, (p, got, n)
        counts.append(n)
    assert max(counts) > 6  # cells with more candidates than their records hold


def test_lookup_timing_probe_counts_the_same_beams():
    """time_beam_lookups (the benchmark probe of the lookups' cost) finds the beams beams_at
    finds, and reports a positive time."""
    core = beams_for(wavy_sea())
    pts = np.random.default_rng(5).uniform([-1.0, -1.0, -12.0], [2.0, 2.0, -0.5], (200, 3))
    found, seconds = core.time_beam_lookups(pts, 0, 2)
    # (a lookup lists at most 64 beams, those beyond joining the nearest in direction)
    assert found == 2 * sum(min(64, len(core.beams_at(tuple(map(float, p)), 0))) for p in pts)
    assert seconds > 0.0
    with pytest.raises(ValueError):
        core.time_beam_lookups(pts[:, :2], 0)


@pytest.mark.parametrize("member", ["issue", "small rough fine", "large rough fine"])
def test_passes_share_the_centres_grid_and_find_every_beam(member):
    """Below a wave patch the beam grid is built once, for the sun's centre, and serves every
    pass's direction in the disk (its marks widened by a margin): for directions across the
    disk, its edge included, every pass shares it, and at random points beams_at finds the
    beams that a brute force over all prisms and periods finds, with the same irradiances.
    (Without the sun-disk blur, whose prisms are the centre's in every pass.)"""
    from photic import bench_waves
    from photic.render import sun_direction

    m = next(m for m in bench_waves.WAVE_FAMILY if m.name == member)
    scene = bench_waves.wave_member_scene(m, "waves", 64)
    scene.validate()
    core = compile_scene(scene, hybrid=True, forward_cone_deg=0.0)
    core.beam_sun_blur = False
    rng = np.random.default_rng(7)
    L = m.patch_m
    pts = np.column_stack([rng.uniform(-L, 2 * L, 150), rng.uniform(-L, 2 * L, 150), rng.uniform(-5.0, 0.5, 150)])
    for u in [(0.5, 0.5), (0.0, 0.0), (1.0, 0.5), (0.2, 0.9), (1.0, 1.0)]:
        core.build_beams(tuple(sun_direction(scene, *u)), 2)
        assert core.beam_grid_shared
        count, e0 = core.beams_brute_force(pts, 0)
        got = [core.beams_at(tuple(map(float, p)), 0) for p in pts]
        assert [len(g) for g in got] == list(count)
        np.testing.assert_allclose([sum(b[1][0] for b in g) for g in got], e0, rtol=1e-12, atol=0)
    assert count.sum() > 100


def test_lookups_find_every_beam_beside_the_pool_walls():
    """Where one vertex ray of a prism ends on a wall before the others, the prism's slices
    reach beyond that ray's end (up to the end face): the grid must list the prism there too
    (pieces whose corners were clamped to the rays' ends lost such beams). In the stepped pool,
    at points just before the ends of the prisms' rays (on walls, steps and the floor) and at
    random points, in the water and in the air (reflected prisms), beams_at finds what a brute
    force over all prisms finds, with the same irradiances."""
    from photic.render import sun_direction
    from photic.scenes import stepped_pool

    scene = stepped_pool(resolution=(16, 16), integrator="hybrid")
    scene.validate()
    core = compile_scene(scene, hybrid=True, forward_cone_deg=0.0)
    core.build_beams(tuple(sun_direction(scene, 0.5, 0.5)), 2)
    rng = np.random.default_rng(3)
    # the point where clamped corners lost a beam (a ray of its prism ends on the wall y = -1.5)
    checked = 0
    for air in (False, True):
        v, d, length = (np.asarray(a) for a in core.prism_arrays(air)[:3])
        ends = v + d * length[..., None]
        pick = rng.integers(0, len(v), 300)
        pts = ends[pick, rng.integers(0, 3, 300)] - d[pick, 0] * rng.uniform(0.0, 0.05, (300, 1)) \
            + rng.normal(0.0, 0.02, (300, 3))
        pts = np.vstack([pts, rng.uniform(ends.reshape(-1, 3).min(0), ends.reshape(-1, 3).max(0), (200, 3))])
        if not air:
            pts = np.vstack([pts, [[1.5740595681429581, -1.4999785421769563, -1.1413502807890408]]])
        media = [-1] * len(pts) if air else [core.medium_at(tuple(map(float, p))) for p in pts]
        for m in sorted(set(media) - ({-1} if not air else set())):
            sel = pts[np.asarray(media) == m]
            count, e0 = core.beams_brute_force(sel, int(m))
            got = [core.beams_at(tuple(map(float, p)), int(m)) for p in sel]
            assert [len(g) for g in got] == list(count)
            np.testing.assert_allclose([sum(b[1][0] for b in g) for g in got], e0, rtol=1e-12, atol=0)
            checked += int(count.sum())
    assert checked > 200


def test_a_cancelled_beam_build_leaves_no_beams_and_the_next_build_is_whole():
    """cancel() stops a beam build (a 1024 x 1024 patch's first build takes seconds; the checks
    come per block of vertices, per source triangle and per 4,096 prisms), leaving no beams and
    nothing half-built: after reset_cancel the same build gives what a fresh core gives."""
    from photic import bench_waves
    from photic.render import sun_direction

    m = next(m for m in bench_waves.WAVE_FAMILY if m.name == "issue")
    scene = bench_waves.wave_member_scene(m, "waves", 64)
    d = tuple(sun_direction(scene, 0.5, 0.5))
    core = compile_scene(scene, seed=7, hybrid=True, forward_cone_deg=0.0)
    core.cancel()
    core.build_beams(d, 2)
    assert core.beam_count == 0 and core.beam_total_flux() == 0.0 and not core.beam_grid_shared
    core.reset_cancel()
    core.build_beams(d, 2)
    fresh = compile_scene(scene, seed=7, hybrid=True, forward_cone_deg=0.0)
    fresh.build_beams(d, 2)
    assert core.beam_count == fresh.beam_count > 0 and core.beam_grid_shared == fresh.beam_grid_shared
    assert core.beam_total_flux() == fresh.beam_total_flux()
    x = (3.0, 4.0, -2.0)
    assert [b for b in core.beams_at(x, 0)] == [b for b in fresh.beams_at(x, 0)]


def test_sun_disk_blur_equals_the_average_over_the_disk(zscore):
    """The prisms of the sun's centre, each spread over the disk's image (the default), give at
    every point what the average over directions drawn in the disk gives (1,024 strata, sharp
    prisms: the unbiased estimate the blur replaces), beyond the crests' foci as before them;
    a focus that one direction makes 600 times the mean stays a few times the mean."""
    from photic.render import strata_grid, sun_direction

    scene = wavy_sea()
    blurred = beams_for(scene)
    assert blurred.sun_blur_active
    sharp = compile_scene(scene, hybrid=True, forward_cone_deg=0.0)
    sharp.beam_sun_blur = False
    rng = np.random.default_rng(1)
    for z in (-3.0, -8.0, -12.0):
        pts = np.column_stack([rng.random(200), rng.random(200), np.full(200, z)])

        def irradiance(core):
            return np.array([sum(b[1][0] for b in core.beams_at(tuple(map(float, p)), 0)) for p in pts])

        e_blur = irradiance(blurred)
        n = 1024
        a, b = strata_grid(n)
        draws = []
        for k in range(n):
            sharp.build_beams(tuple(sun_direction(scene, (k % a + rng.random()) / a, (k // a + rng.random()) / b)), 2)
            draws.append(irradiance(sharp))
        draws = np.array(draws)
        mean, se = draws.mean(0), draws.std(0, ddof=1) / np.sqrt(n)
        # Per point within 6 SE (the strata make the plain SE an overestimate) or 0.3 %: the
        # blur is the disk's image to first order in its radius (0.0046 rad); what is left,
        # ~1e-3 where the caustics' pattern changes fast, is far below any measurement's.
        # (Beyond the foci, at 12 m, the draws' values are too heavy-tailed near point foci,
        # 1 / area of a collapsing slice, for their SE to be trusted point by point: there the
        # plane's mean, the flux, is compared.)
        off = np.abs(e_blur - mean) / (6 * se + 0.003 * mean)
        assert z == -12.0 or np.all(off < 1), (z, off.max())
        assert abs(zscore(f"sun-disk blur vs disk average, mean E at {-z:g} m", e_blur.mean(), mean.mean(),
                          np.sqrt(np.sum(se ** 2)) / len(pts))) < 4
        if z == -8.0:
            assert draws.max() > 100 * mean.mean() and e_blur.max() < 40 * mean.mean()


def test_kept_prisms_follow_the_pass_only_in_shadow_rays_and_flat_beams():
    """With the blur every pass's prisms are the sun centre's: keep_prisms keeps them (the same
    beams at every point, no rebuild), while a fresh build for another direction in the disk
    gives the same prisms too."""
    from photic.render import sun_direction

    scene = wavy_sea()
    core = beams_for(scene)
    x = (0.3, 0.7, -6.0)
    before = core.beams_at(x, 0)
    flux = core.beam_total_flux()
    core.build_beams(tuple(sun_direction(scene, 0.9, 0.1)), 2, keep_prisms=True)
    assert core.beams_at(x, 0) == before and core.beam_total_flux() == flux
    core.build_beams(tuple(sun_direction(scene, 0.1, 0.8)), 2)
    assert core.beams_at(x, 0) == before and core.beam_total_flux() == flux
    core.beam_sun_blur = False  # sharp: each build its own direction
    core.build_beams(tuple(sun_direction(scene, 0.1, 0.8)), 2)
    assert core.beam_total_flux() != flux


def test_beams_meet_the_phase_function_averaged_over_the_suns_disk():
    """With the blur the beams' single scattering takes the phase function averaged over the
    refracted sun's disk (a cap of the sun's radius / ior): equal to a direct quadrature of the
    cap mean (to 1 %), bounded at the peak's tip (Petzold's power law there is singular), the
    phase function itself beyond 12 radii, and still normalised; without the blur, the phase
    function itself."""
    from photic.phase import make_core_phase

    scene = wavy_sea(b=0.3)
    core = beams_for(scene)
    a = core.beam_disk_radius
    ci = np.cos(np.radians(30.0))
    assert a == pytest.approx(np.radians(0.53 / 2) / 1.34 * np.sqrt(ci / np.sqrt(1 - (1 - ci * ci) / 1.34 ** 2)), rel=1e-12)
    raw = make_core_phase("petzold")

    def p(psi):
        psi = np.asarray(psi, dtype=float)
        return np.asarray(raw.eval(np.ravel(2 * np.sin(0.5 * psi) ** 2))).reshape(psi.shape)

    # the cap's mean by quadrature on a polar grid about the cap's centre (psi from the tip)
    r = (np.arange(600) + 0.5) / 600 * a
    phi = (np.arange(720) + 0.5) / 720 * 2 * np.pi
    rr, pp = np.meshgrid(r, phi)
    # (where the tip lies at the cap's centre or outside the cap the grid resolves it; inside,
    # off the grid's centre, to a few per cent)
    for psi, tol in ((0.0, 0.01), (0.3 * a, 0.04), (1.5 * a, 0.01), (2 * a, 0.01), (6 * a, 0.01)):
        ang = np.sqrt(psi ** 2 + rr ** 2 + 2 * psi * rr * np.cos(pp))
        mean = np.sum(p(ang) * rr) / np.sum(rr)
        got = core.beam_phase(0, 2 * np.sin(psi / 2) ** 2)
        assert got == pytest.approx(mean, rel=tol), psi
    assert core.beam_phase(0, 0.0) < 3000 < p(1e-6)  # the tip: ~2,200 / sr instead of 10^5+
    for psi in (13 * a, 0.1, 1.0):
        x = 2 * np.sin(psi / 2) ** 2
        assert core.beam_phase(0, x) == p(psi)
    x = np.concatenate([np.linspace(0.0, 1e-3, 20001), np.linspace(1e-3, 2.0, 200001)[1:]])
    vals = np.array([core.beam_phase(0, float(v)) for v in x])
    assert 2 * np.pi * trapezoid(vals, x) == pytest.approx(1.0, abs=2e-3)
    sharp = beams_for(scene, blur=False)
    assert sharp.beam_disk_radius == 0.0 and sharp.beam_phase(0, 1e-8) == raw.eval(np.array([1e-8]))[0]


def test_radiance_caps_smaller_than_the_sun_see_their_share_of_its_disk():
    """A radiance radiometer looking straight at the refracted sun below a level patch (prisms),
    with a cap
    smaller than the sun's refracted disk: with the blur (each sample takes the direct beam at a
    point of the disk's image, a circle of the image's solid angle) it reads the cap's share of
    the disk, cap^2 / (the image's semi-axes' product) of the beam's irradiance over the cap's
    solid angle, as the passes' directions drawn in the disk do without the blur (whose image
    is the true ellipse: 0.93 as wide in the plane of incidence at 30 deg); a cap larger than
    the disk holds all of it."""
    zen = 30.0
    mu_w = np.cos(np.arcsin(np.sin(np.radians(zen)) / 1.34))
    up = [np.sin(np.radians(zen)) / 1.34, 0.0, mu_w]  # towards the refracted sun (azimuth 0)
    ci = np.cos(np.radians(zen))
    a_w = np.radians(0.53 / 2) / 1.34 * np.sqrt(ci / mu_w)  # sqrt(in-plane x across radius)
    results = {}
    v, t = wave_patch(amp=0.0)
    for blur in (True, False):
        d = {"photic_scene": 1, "name": "cap",
             "water": [{"name": "sea", "type": "ocean", "iops": {"absorption": [0.05]},
                        "surface": {"kind": "patch", "vertices": v, "triangles": t, "period": [1.0, 1.0]}}],
             "sun": {"zenith_deg": zen, "azimuth_deg": 0.0, "irradiance": [1.0]},
             "radiometers": [{"name": f"L{h}", "quantity": "radiance", "position": [0, 0, -1.0],
                              "direction": up, "half_angle_deg": h} for h in (0.05, 0.1, 0.5)],
             "settings": {"integrator": "hybrid", "forward_cone_deg": 0, "sun_disk_blur": blur, "seed": 3}}
        res = render(Scene.from_dict(d), radiometer_samples=65536)
        results[blur] = {r.name: r.components["beam_direct"] for r in res.radiometers}
    e_beam = (1 - fresnel(np.cos(np.radians(zen)), 1.0, 1.34)) * np.cos(np.radians(zen)) / mu_w * np.exp(-0.05 / mu_w)
    for h in (0.05, 0.1, 0.5):
        cap = np.radians(h)
        omega = 2 * np.pi * (1 - np.cos(cap))
        expect = e_beam * min(1.0, (cap / a_w) ** 2) / omega
        for blur in (True, False):
            mean, se = (float(np.asarray(v)[0, 0]) for v in results[blur][f"L{h}"])
            assert abs(mean - expect) < 4 * se + 0.01 * expect, (h, blur, mean, expect, se)
            if blur:
                assert se < 0.02 * expect
