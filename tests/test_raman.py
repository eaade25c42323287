"""Raman scattering by water (issue 42, first process): the spectral model against its own
closed forms, and the hybrid integrator's Raman light against the closed form of single
inelastic scattering of a collimated beam in water that does not scatter elastically."""
import math

import numpy as np
import pytest

from photic import inelastic
from photic.render import render
from photic.scene import Band, Scene, SceneError, scene_warnings

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

IOR = 1.34


def test_raman_phase_function_is_normalised():
    mu = np.linspace(-1.0, 1.0, 200_001)
    integral = 2 * np.pi * np.trapz(inelastic.raman_phase(mu), mu)
    assert abs(integral - 1.0) < 1e-9
    assert inelastic.raman_phase(1.0) / inelastic.raman_phase(0.0) == pytest.approx(1.55)


def test_raman_coefficient_and_shift():
    assert inelastic.raman_b(488.0) == pytest.approx(2.7e-4)
    assert inelastic.raman_b(400.0) / inelastic.raman_b(500.0) == pytest.approx(1.25 ** 5.5)
    # the mean shift, 3,383.75 cm^-1, below 488 nm's 20,492 cm^-1: 584.5 nm
    assert inelastic.RAMAN_SHIFT_CM == pytest.approx(3383.75)
    assert inelastic.excitation_nm(1e7 / (1e7 / 488.0 - inelastic.RAMAN_SHIFT_CM)) == pytest.approx(488.0, abs=1e-9)
    assert inelastic.excitation_nm(584.52) == pytest.approx(488.0, abs=0.01)
    lam = np.linspace(450.0, 750.0, 30_001)
    for ex in (420.0, 488.0, 550.0):  # the emission density integrates to 1 over wavelength
        assert np.trapz(inelastic.emission_density(ex, lam), lam) == pytest.approx(1.0, abs=1e-6)


def test_the_shift_is_walrafens_four_gaussians():
    """In wavenumber, the emission is Walrafen's four Gaussians (weights 0.41, 0.39, 0.10, 0.10
    at 3,250, 3,425, 3,530, 3,625 cm^-1, full widths 210, 175, 140, 140): its mean and its
    value at each centre against the sum written out."""
    ex = 488.0
    shift = np.linspace(2000.0, 5000.0, 300_001)
    lam = 1e7 / (1e7 / ex - shift)
    per_cm = inelastic.emission_density(ex, lam) * lam ** 2 / 1e7  # per nm -> per cm^-1
    assert np.trapz(per_cm, shift) == pytest.approx(1.0, abs=1e-9)
    assert np.trapz(per_cm * shift, shift) == pytest.approx(3383.75, abs=1e-6)

    def walrafen(k):
        w, c, f = [0.41, 0.39, 0.10, 0.10], [3250, 3425, 3530, 3625], [210, 175, 140, 140]
        return sum(wi * 2 * math.sqrt(math.log(2) / math.pi) / fi * math.exp(-4 * math.log(2) * ((k - ci) / fi) ** 2)
                   for wi, ci, fi in zip(w, c, f))
    for k in (3250.0, 3425.0, 3530.0, 3625.0, 3000.0):
        x = 1e7 / (1e7 / ex - k)
        assert float(inelastic.emission_density(ex, x)) * x ** 2 / 1e7 == pytest.approx(walrafen(k), rel=1e-12)


def test_the_coupling_keeps_the_energy_raman_scattering_takes():
    """Contiguous 10 nm bands from 400 to 800 nm: what band i loses at b_R (integrated over
    the band) all lands in the bands above it (the emission of 400-560 nm stays below 800)."""
    bands = [Band(f"{c}", float(c), 10.0) for c in range(405, 800, 10)]
    m = inelastic.raman_coupling(bands)
    widths = np.full(len(bands), 10.0)
    for i, b in enumerate(bands):
        if b.center_nm > 560:
            continue
        lam = np.linspace(b.center_nm - 5, b.center_nm + 5, 2001)
        lost = np.trapz(inelastic.raman_b(lam), lam)
        assert (m[:, i] * widths).sum() == pytest.approx(lost, rel=2e-3), b.name
        assert m[: i + 1, i].max() < 1e-3 * m[:, i].max()  # nothing goes to shorter wavelengths
    assert np.all(inelastic.raman_coverage(bands)[np.array([b.center_nm for b in bands]) > 500] > 0.999)


def _sea(bands, absorption, sun, quantity, direction=None, half_angle=None, depth=1.0, raman=True,
         integrator="hybrid", zenith=0.0):
    rad = {"name": "r", "quantity": quantity, "position": [0.0, 0.0, -depth]}
    if direction is not None:
        rad["direction"] = direction
    if half_angle is not None:
        rad["half_angle_deg"] = half_angle
    return Scene.from_dict({
        "photic_scene": 1, "name": "raman",
        "bands": [{"name": b.name, "center_nm": b.center_nm, "width_nm": b.width_nm} for b in bands],
        "water": [{"name": "sea", "type": "ocean", "ior": IOR, "surface": {"kind": "flat", "z": 0.0},
                   "iops": {"absorption": absorption, "b": [0.0] * len(bands), "phase": {"type": "isotropic"}}}],
        "sun": {"zenith_deg": zenith, "azimuth_deg": 0.0, "irradiance": sun},
        "radiometers": [rad],
        "settings": {"integrator": integrator, "raman": raman, "seed": 3, "forward_cone_deg": 0}})


BANDS = [Band("450", 450.0, 20.0), Band("531", 531.0, 20.0)]  # 450 nm shifts to 531 nm
A = [0.02, 0.05]
T = 1.0 - ((IOR - 1.0) / (IOR + 1.0)) ** 2  # Fresnel transmittance, normal incidence


def _closed_form_upwelling(mu):
    """Radiance (band 531) going up at cos(theta) = mu at 1 m, from the vertical beam (band
    450, irradiance T at the surface) Raman-scattered below: p_R(mu) sum_i M[j, i] E_i(z) /
    (c_i mu + c_j), with c = a + b_R (what Raman scattering takes from each band)."""
    m = inelastic.raman_coupling(BANDS)
    c = np.asarray(A) + inelastic.raman_b([b.center_nm for b in BANDS])
    e450 = T * np.exp(-c[0] * 1.0)
    return inelastic.raman_phase(mu) * m[1, 0] * e450 / (c[0] * mu + c[1])


def test_raman_radiance_of_a_collimated_beam_matches_its_closed_form(zscore):
    """Upwelling radiance at 1 m (a 5 deg cap looking straight down) in water without elastic
    scattering, the sun at the zenith in band 450 only: all of band 531's light is the beam's
    Raman scattering, in closed form."""
    scene = _sea(BANDS, A, [1.0, 0.0], "radiance", [0.0, 0.0, -1.0], 5.0)
    r = render(scene, radiometer_samples=200_000, seed=5, threads=2).radiometers[0]
    cap = np.radians(5.0)
    mu = np.linspace(np.cos(cap), 1.0, 20_001)
    expect = np.trapz(_closed_form_upwelling(mu), mu) / (1.0 - np.cos(cap))
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    assert value == pytest.approx(float(r.components["raman"][0][0, 1]))  # all of it Raman
    assert se < 0.01 * value
    zscore("Raman Lu 531, beam (5 deg cap, sun 0 deg)", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 1e-3 * expect, (value, se, expect)
    assert r.mean[0, 0] == 0.0  # nothing reaches band 450 going up (no elastic scattering)
    assert inelastic.raman_coupling(BANDS)[0].max() == 0.0  # (nor from 531 nm: longer)


def test_raman_upwelling_irradiance_matches_its_closed_form(zscore):
    scene = _sea(BANDS, A, [1.0, 0.0], "Eu")
    r = render(scene, radiometer_samples=200_000, seed=6, threads=2).radiometers[0]
    mu = np.linspace(0.0, 1.0, 20_001)
    expect = 2 * np.pi * np.trapz(_closed_form_upwelling(mu) * mu, mu)
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    zscore("Raman Eu 531, beam (sun 0 deg)", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 1e-3 * expect, (value, se, expect)


def test_raman_radiance_under_an_oblique_sun_matches_its_closed_form(zscore):
    """The sun at 40 deg: the refracted beam (at theta_w) carries E0 T(40) cos(40) / cos(theta_w)
    normal to itself and is attenuated over z / cos(theta_w); the nadir radiance at 1 m is
    p_R(cos theta_w) M E(1 m) / (c_i / cos(theta_w) + c_j), with the cap's average."""
    zenith = np.radians(40.0)
    mu_w = np.sqrt(1.0 - (np.sin(zenith) / IOR) ** 2)
    mu_s = np.cos(zenith)
    rs = ((mu_s - IOR * mu_w) / (mu_s + IOR * mu_w)) ** 2
    rp = ((IOR * mu_s - mu_w) / (IOR * mu_s + mu_w)) ** 2
    t = 1.0 - 0.5 * (rs + rp)
    m = inelastic.raman_coupling(BANDS)
    c = np.asarray(A) + inelastic.raman_b([b.center_nm for b in BANDS])
    e = t * mu_s / mu_w * np.exp(-c[0] * 1.0 / mu_w)
    expect = inelastic.raman_phase(mu_w) * m[1, 0] * e / (c[0] / mu_w + c[1])
    scene = _sea(BANDS, A, [1.0, 0.0], "radiance", [0.0, 0.0, -1.0], 0.5, zenith=40.0)
    r = render(scene, radiometer_samples=100_000, seed=7, threads=2).radiometers[0]
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    zscore("Raman Lu 531, beam (0.5 deg cap, sun 40 deg)", value, expect, se)
    # (the 0.5 deg cap: the radiance varies by < 1e-4 across it)
    assert abs(value - expect) < 3.5 * se + 2e-4 * expect, (value, se, expect)


def test_without_raman_nothing_shifts():
    off = render(_sea(BANDS, A, [1.0, 0.0], "Eu", raman=False), radiometer_samples=20_000, seed=1).radiometers[0]
    assert off.mean[0, 1] == 0.0 and not off.components["raman"][0].any()
    assert not any("integrator" in w for w in scene_warnings(_sea(BANDS, A, [1.0, 0.0], "Eu", integrator="path")))


def _fresnel_in(mu_w):
    """Unpolarised Fresnel transmittance of the flat surface for light refracted to the
    in-water cosine mu_w (the same both ways)."""
    mu_a = np.sqrt(np.clip(1.0 - IOR ** 2 * (1.0 - mu_w ** 2), 0.0, None))
    rs = ((mu_a - IOR * mu_w) / (mu_a + IOR * mu_w)) ** 2
    rp = ((IOR * mu_a - mu_w) / (IOR * mu_a + mu_w)) ** 2
    return 1.0 - 0.5 * (rs + rp)


def _sky_raman_nadir_radiance(tau450, tau531, depth, sky, phase=inelastic.raman_phase, m_of_z=None):
    """The nadir radiance (light going straight up) in band 531 at `depth` below a flat
    surface under a uniform sky of radiance `sky` in band 450 only, in water that does not
    scatter elastically: band 450's light comes down inside Snell's window with radiance
    n^2 T(mu) sky exp(-tau450(0, z) / mu) (no light goes up in band 450: nothing scatters it
    back), is Raman-scattered at every depth z below, and comes up attenuated by
    tau531(depth, z): L = M[531, 450] int_depth^inf int_window p_R(mu) n^2 T(mu) sky
    exp(-tau450(0, z) / mu) exp(-tau531(depth, z)) 2 pi dmu dz. tau*(z0, z1): the optical
    depth (a + b_R) between two depths, vectorised. Another process: its phase function and
    coupling M(z) (a function of depth)."""
    mu_c = np.sqrt(1.0 - 1.0 / IOR ** 2)
    mu = np.linspace(mu_c, 1.0, 801)[:, None]
    z = np.unique(np.concatenate([np.linspace(depth, depth + 2.0, 2_001), np.geomspace(depth + 2.0, 3e4, 8_001)]))
    z = z[None, :]
    down = IOR ** 2 * _fresnel_in(mu) * sky * np.exp(-tau450(0.0, z) / mu)
    source = 2 * np.pi * np.trapz(phase(mu) * down, mu[:, 0], axis=0)
    m = m_of_z(z[0]) if m_of_z is not None else inelastic.raman_coupling(BANDS)[1, 0]
    return np.trapz(m * source * np.exp(-tau531(depth, z[0])), z[0])


SKY_A = [0.005, 0.01]  # clear water: the Raman light of a deep layer (the paths' Raman collisions
# come at the rate of Raman scattering, about 2e-4 per metre; what they find, attenuated)
SKY_TOP, SKY_LOW = [0.02, 0.04], [0.004, 0.008]


def _sun_raman_radiance_in_cap(tau450, tau531, depth, cap, phase=inelastic.raman_phase, m_of_z=None):
    """The same radiance from a sun at the zenith (irradiance 1 in band 450), averaged over a
    cap of half-angle `cap` around the nadir: p_R(mu) M T0 int exp(-tau450(0, z))
    exp(-tau531(depth, z) / mu) dz / mu."""
    mu = np.linspace(np.cos(cap), 1.0, 201)[:, None]
    z = np.unique(np.concatenate([np.linspace(depth, depth + 2.0, 2_001), np.geomspace(depth + 2.0, 3e4, 8_001)]))
    m = m_of_z(z) if m_of_z is not None else inelastic.raman_coupling(BANDS)[1, 0]
    up = m * np.exp(-tau450(0.0, z)[None, :] - tau531(depth, z)[None, :] / mu) / mu
    radiance = phase(mu[:, 0]) * T * np.trapz(up, z, axis=1)
    return np.trapz(radiance, mu[:, 0]) / (1.0 - np.cos(cap))


def _sky_sea(integrator, layered=False):
    d = _sea(BANDS, SKY_A, [0.0, 0.0], "radiance", [0.0, 0.0, -1.0], 2.0, integrator=integrator).to_dict()
    if integrator == "path":  # (path tracing finds the sun only by escaping into its disk)
        d.pop("sun", None)
    else:
        d["sun"]["irradiance"] = [1.0, 0.0]
    d["sky"] = {"type": "uniform", "radiance": [1.0, 0.0]}
    if layered:
        water = d["water"][0]
        iops = water.pop("iops")
        water["iop_profile"] = {"z_top": [0.0, -2.0], "layers": [
            {"iops": dict(iops, absorption=SKY_TOP)}, {"iops": dict(iops, absorption=SKY_LOW)}]}
    return Scene.from_dict(d)


@pytest.mark.parametrize("integrator", ["path", "hybrid"])
@pytest.mark.parametrize("layered", [False, True], ids=["homogeneous", "layered"])
def test_raman_of_skylight_matches_its_closed_form(zscore, integrator, layered):
    """Skylight, which no beam carries: the paths' own Raman collisions (both integrators)
    against the closed form of single Raman scattering of the refracted sky, in homogeneous
    water and in two layers (clearer below 2 m); the hybrid with the sun at the zenith too,
    whose Raman light its beams give (the two must add, neither counted twice)."""
    b_r = inelastic.raman_b([b.center_nm for b in BANDS])
    if layered:
        c_top, c_low = np.array(SKY_TOP) + b_r, np.array(SKY_LOW) + b_r

        def tau(k):
            return lambda z0, z1: (c_top[k] * np.clip(np.minimum(z1, 2.0) - z0, 0.0, None)
                                   + c_low[k] * np.clip(z1 - np.maximum(z0, 2.0), 0.0, None))
    else:
        c = np.asarray(SKY_A) + b_r

        def tau(k):
            return lambda z0, z1: c[k] * (z1 - z0)
    cap = np.radians(2.0)
    expect = _sky_raman_nadir_radiance(tau(0), tau(1), 1.0, 1.0)  # (the 2 deg cap: < 1e-4 off)
    if integrator == "hybrid":
        expect += _sun_raman_radiance_in_cap(tau(0), tau(1), 1.0, cap)
    r = render(_sky_sea(integrator, layered), radiometer_samples=4_000_000, seed=11, threads=2).radiometers[0]
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    assert value == pytest.approx(float(r.components["raman"][0][0, 1]))  # all of it Raman light
    assert se < 0.015 * value, (value, se)
    zscore(f"Raman Lu 531, sky ({integrator}, {'layers' if layered else 'homogeneous'})", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 2e-3 * expect, (value, se, expect, cap)


def test_bands_without_their_excitation_are_named():
    """450 nm's Raman light comes from 377-404 nm, outside the bands (a warning names it);
    531 nm's from 436-463 nm, 94 % inside the 450 nm band (no warning)."""
    warnings = scene_warnings(_sea(BANDS, A, [1.0, 0.0], "Eu"))
    assert len(warnings) == 1 and "band '450'" in warnings[0] and "377-404 nm" in warnings[0], warnings
    assert "none" in warnings[0]
    narrow = _sea([Band("450", 450.0, 10.0), Band("531", 531.0, 20.0)], A, [1.0, 0.0], "Eu")
    assert any("band '531'" in w and "%" in w for w in scene_warnings(narrow)), scene_warnings(narrow)


def test_raman_must_be_true_false_or_auto():
    scene = _sea(BANDS, A, [1.0, 0.0], "Eu")
    scene.settings.raman = "yes"
    with pytest.raises(SceneError, match="raman"):
        scene.validate()


def test_raman_is_on_by_default_where_the_bands_can_receive_it():
    d = _sea(BANDS, A, [1.0, 0.0], "Eu").to_dict()
    d["settings"].pop("raman")
    scene = Scene.from_dict(d)
    assert scene.settings.raman == "auto" and inelastic.raman_active(scene)
    assert "raman" not in scene.to_dict()["settings"]  # (the default is not written)
    one = Scene.from_dict(dict(d, bands=[{"name": "550", "center_nm": 550.0, "width_nm": 10.0}],
                               water=[dict(d["water"][0], iops={"absorption": [0.05], "b": [0.0],
                                                               "phase": {"type": "isotropic"}})],
                               sun=dict(d["sun"], irradiance=[1.0])))
    assert not inelastic.raman_active(one)  # one band: nothing to receive
    r = render(scene, radiometer_samples=20_000, seed=2).radiometers[0]
    assert r.mean[0, 1] > 0 and r.components["raman"][0][0, 1] == r.mean[0, 1]
    assert sum("settings.raman (auto: on)" in w for w in scene_warnings(scene)) == 1  # one line, not per band
    scene.settings.raman = False
    assert not inelastic.raman_active(scene) and not any("raman" in w for w in scene_warnings(scene))



def test_raman_light_lost_between_band_groups_is_said():
    """More than 16 bands render in groups whose paths carry only their own bands."""
    bands = [Band(f"{c}", float(c), 10.0) for c in range(405, 700, 10)]  # 30 bands: 2 groups
    scene = _sea(bands, [0.05] * len(bands), [1.0] * len(bands), "Eu")
    from photic.compile import inelastic_group_warnings
    assert not [w for w in scene_warnings(scene) if "groups" in w]
    warnings = inelastic_group_warnings(scene)
    assert len(warnings) == 1 and "Raman light" in warnings[0] and "'565'" in warnings[0] and "'405'" not in warnings[0], warnings


def test_a_camera_gets_its_raman_pass_and_the_passes_sum_to_the_total(tmp_path):
    """A camera 1 m down looking at the deep water below: in band 531 it sees only Raman
    light; the pixels' components (beam_surface, beam_volume, path, raman) sum to the total,
    in one process and merged from a batch's units alike."""
    from photic.distributed import parse_job, run_job

    d = _sea(BANDS, A, [1.0, 0.0], "Eu").to_dict()
    d["cameras"] = [{"name": "down", "type": "perspective", "position": [0.0, 0.0, -1.0],
                     "direction": [0.0, 0.0, -1.0], "up": [0.0, 1.0, 0.0], "fov_deg": 20.0,
                     "resolution": [6, 4]}]
    scene = Scene.from_dict(d)
    img = render(scene, samples=64, radiometer_samples=1024, seed=2).images["down"]
    assert set(img.components) == {"beam_surface", "beam_volume", "path", "raman"}
    np.testing.assert_allclose(sum(img.components.values()), img.mean, rtol=1e-12, atol=1e-15)
    assert img.components["raman"][:, :, 1].min() > 0 and not img.components["raman"][:, :, 0].any()
    # The nadir pixels' radiance is the closed form's (the cap of 20 deg: within 3 %)
    expect = float(_closed_form_upwelling(1.0))
    assert abs(img.mean[:, :, 1].mean() / expect - 1.0) < 0.03, (img.mean[:, :, 1].mean(), expect)
    (tmp_path / "s.json").write_text(__import__("json").dumps(d))
    job = parse_job({"photic_job": 1, "name": "r", "inputs": [str(tmp_path / "s.json")], "samples": 8,
                     "radiometer_samples": 1024, "seed": 2}, tmp_path)
    merged = {}
    run_job(job, tmp_path / "out", workers=0, progress=False,
            on_item_done=lambda item, res: merged.update(res.images), write_results=False)
    m = merged["down"]
    assert "raman" in m.components and m.components["raman"][:, :, 1].min() > 0
    np.testing.assert_allclose(sum(m.components.values()), m.mean, rtol=1e-12, atol=1e-15)


def test_raman_radiance_in_layered_water_matches_its_closed_form(zscore):
    """Two layers (the boundary at 2 m, clearer water below): the beam and the Raman light
    are attenuated by each layer's own a + b_R, the sun at the zenith; the nadir radiance at
    1 m, integrated over depth in closed form piece by piece (here by quadrature)."""
    a_top, a_low = np.array([0.05, 0.08]), np.array([0.01, 0.03])
    b_r = inelastic.raman_b([b.center_nm for b in BANDS])
    c_top, c_low = a_top + b_r, a_low + b_r
    d = _sea(BANDS, list(a_top), [1.0, 0.0], "radiance", [0.0, 0.0, -1.0], 0.5).to_dict()
    water = d["water"][0]
    iops = water.pop("iops")
    water["iop_profile"] = {"z_top": [0.0, -2.0], "layers": [
        {"iops": dict(iops, absorption=list(a_top))}, {"iops": dict(iops, absorption=list(a_low))}]}
    scene = Scene.from_dict(d)
    r = render(scene, radiometer_samples=100_000, seed=9, threads=2).radiometers[0]
    zs = np.linspace(1.0, 1000.0, 4_000_001)  # depth below the surface (beyond: < 1e-12 of it)

    def tau(c1, c2, z0, z1):  # optical depth from depth z0 down to z1 (boundary at 2 m)
        top = np.clip(np.minimum(z1, 2.0) - z0, 0.0, None)
        return c1 * top + c2 * np.clip(z1 - np.maximum(z0, 2.0), 0.0, None)

    e450 = T * np.exp(-tau(c_top[0], c_low[0], 0.0, zs))
    up = np.exp(-tau(c_top[1], c_low[1], 1.0, zs))
    m = inelastic.raman_coupling(BANDS)
    expect = inelastic.raman_phase(1.0) * m[1, 0] * np.trapz(e450 * up, zs)
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    zscore("Raman Lu 531, beam (two layers)", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 2e-5 * expect, (value, se, expect)


@pytest.mark.parametrize("integrator", ["path", "hybrid"])
def test_raman_in_gridded_water_matches_its_closed_form(zscore, integrator):
    """Gridded water (a 3-D grid of an absorbing field over the clear base, its density the
    same everywhere, down to 3 km): the grid's walks carry the Raman light (a deferred beam
    term's, and the paths' Raman collisions, whose absorption is a walk of their own) and
    b_R is the base's loss; the closed forms are the homogeneous ones with the summed
    absorption."""
    d = _sky_sea(integrator).to_dict()
    water = d["water"][0]
    base = water.pop("iops")
    unit = {"absorption": [0.01, 0.02], "b": [0.0, 0.0], "phase": {"type": "isotropic"}}
    water["iop_grid"] = {"base": {"iops": base}, "unit": {"iops": unit}, "origin": [-5000.0, -5000.0, -3000.0],
                         "size": [10000.0, 10000.0, 3001.0], "density": np.full((2, 2, 3), 0.5).tolist()}
    c = np.asarray(SKY_A) + 0.5 * np.asarray(unit["absorption"]) + inelastic.raman_b([b.center_nm for b in BANDS])

    def tau(k):
        return lambda z0, z1: c[k] * (z1 - z0)
    cap = np.radians(2.0)
    expect = _sky_raman_nadir_radiance(tau(0), tau(1), 1.0, 1.0)
    if integrator == "hybrid":
        expect += _sun_raman_radiance_in_cap(tau(0), tau(1), 1.0, cap)
    r = render(Scene.from_dict(d), radiometer_samples=4_000_000, seed=12, threads=2).radiometers[0]
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    assert value == pytest.approx(float(r.components["raman"][0][0, 1]))
    assert se < 0.02 * value, (value, se)
    zscore(f"Raman Lu 531, grid ({integrator})", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 2e-3 * expect, (value, se, expect)


def test_raman_rrs_against_the_quasi_single_scattering_model():
    """Clear water (pure water and a little CDOM, no particles), flat deep sea, sun 30 deg,
    black sky: Photic's Raman Rrs against Westberry et al.'s (2013) quasi-single-scattering
    model with its three simplifications put back (isotropic emission, the downward instead of
    the scalar irradiance as the source, no surface transmittance; scripts/raman_qss.py):
    within 1-5 % in the red, where the direct beam's single scattering is nearly all of it
    (the model's upward attenuation 1.03 (a + b_b) against c), and at most 15 % above it in the
    blue-green, where the water's elastic scattering adds light the model leaves out; never
    below it. And never below the exact single scattering of the direct beam alone."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import raman_qss
    sc = raman_qss.scene(0.0, True)
    r = render(sc, radiometer_samples=100_000, threads=2).radiometers[0]
    ed = math.cos(math.radians(raman_qss.ZENITH))
    photic, se = r.components["raman"][0][0] / ed, r.components["raman"][1][0] / ed
    m = raman_qss.models(raman_qss.scene(0.0, True))
    lam = raman_qss.CENTERS
    ok = (m["S"] > 0) & (lam >= 460)  # (440 nm's excitation is mostly outside the bands)
    ratio = photic[ok] / m["exact"][ok]
    red = lam[ok] >= 600
    assert np.all((ratio[red] > 1.0) & (ratio[red] < 1.06)), ratio
    assert np.all((ratio[~red] > 1.0) & (ratio[~red] < 1.15)), ratio
    assert np.all(photic[ok] + 3 * se[ok] >= m["single"][ok]), (photic, m["single"])
