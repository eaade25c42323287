"""Chlorophyll fluorescence (issue 42, second process): the emission model against its own
closed forms (photon bookkeeping), and both integrators' fluorescence against closed forms of
single fluorescence of the refracted sun and sky in water that does not scatter elastically,
homogeneous and layered, alone and beside Raman scattering (each reported in its own
component)."""
import numpy as np
import pytest

from photic import inelastic
from photic.render import render
from photic.scene import Band, Scene, SceneError, scene_warnings
from test_raman import IOR, _sky_raman_nadir_radiance, _sun_raman_radiance_in_cap

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

ISO = lambda mu: np.full_like(np.asarray(mu, float), 1.0 / (4.0 * np.pi))  # noqa: E731
BANDS = [Band("450", 450.0, 20.0), Band("531", 531.0, 20.0), Band("685", 685.0, 30.0)]
A = np.array([0.006, 0.012, 0.4])   # clear water (red: its own absorption)
A_PH = np.array([0.004, 0.001, 0.0])  # the phytoplankton's part (m^-1)


def test_emission_is_normalised_and_photons_are_kept():
    lam = np.linspace(550.0, 820.0, 27_001)
    assert np.trapz(inelastic.chlorophyll_emission(lam), lam) == pytest.approx(1.0, abs=1e-9)
    bands = [Band("440", 440.0, 20.0)] + [Band(f"{c}", float(c), 5.0) for c in np.arange(582.5, 790.0, 5.0)]
    a = np.zeros(len(bands))
    a[0] = 0.05
    m = inelastic.chlorophyll_coupling(bands, a, quantum_yield=0.03)
    # photons emitted (energy per nm x wavelength, over the emission bands) = yield x photons
    # absorbed (a x the band's integral of lambda')
    centers = np.array([b.center_nm for b in bands])
    emitted = float((m[1:, 0] * 5.0 * centers[1:]).sum())
    absorbed = 0.03 * 0.05 * 20.0 * 440.0
    assert emitted == pytest.approx(absorbed, rel=1e-4)
    assert not m[:, 1:].any() and m[0].max() == 0.0  # only the absorbing band excites, nothing below 580
    # excitation only between 370 and 690 nm: a band straddling 690 counts its part below
    half = inelastic.chlorophyll_coupling([Band("690", 690.0, 20.0), Band("700", 700.0, 10.0)], [0.1, 0.1])
    full = inelastic.chlorophyll_coupling([Band("680", 680.0, 20.0), Band("700", 700.0, 10.0)], [0.1, 0.1])
    assert half[1, 1] == 0.0 and 0.4 < half[1, 0] / full[1, 0] * 680.0 / 685.0 < 0.6
    assert inelastic.chlorophyll_coverage([Band("685", 685.0, 100.0)]) > 0.999


def _scene(integrator, sun, sky, layered=False, raman=False, a_ph=A_PH):
    water = {"name": "sea", "type": "ocean", "ior": IOR, "surface": {"kind": "flat", "z": 0.0}}
    iops = {"absorption": list(A), "b": [0.0] * 3, "phase": {"type": "isotropic"}}
    if layered:
        water["iop_profile"] = {"z_top": [0.0, -3.0], "layers": [{"iops": iops},
                                                                   {"iops": dict(iops, absorption=list(A * 0.5))}]}
    else:
        water["iops"] = iops
    water["chlorophyll_fluorescence"] = {"absorption": np.asarray(a_ph).tolist(), "quantum_yield": 0.03}
    d = {"photic_scene": 1, "name": "fluorescence",
         "bands": [{"name": b.name, "center_nm": b.center_nm, "width_nm": b.width_nm} for b in BANDS],
         "water": [water], "sky": {"type": "uniform", "radiance": [sky, 0.0, 0.0]},
         "radiometers": [{"name": "Lu", "quantity": "radiance", "position": [0.0, 0.0, -1.0],
                          "direction": [0.0, 0.0, -1.0], "half_angle_deg": 2.0}],
         "settings": {"integrator": integrator, "raman": raman, "seed": 3, "forward_cone_deg": 0}}
    if sun:
        d["sun"] = {"zenith_deg": 0.0, "azimuth_deg": 0.0, "irradiance": [1.0, 0.0, 0.0]}
    return Scene.from_dict(d)


def single_fluorescence_lu(a, em, m, sun, layered):
    """The closed form of single isotropic fluorescence of band 0's refracted sky (radiance 1)
    and, with ``sun``, sun at the zenith (irradiance 1) into band ``em`` (coupling ``m``), seen
    going straight up at 1 m (2 deg cap) in water of absorption ``a`` that does not scatter
    elastically; ``layered``: below 3 m half the absorption and half the coupling."""
    if layered:
        def tau(k):
            return lambda z0, z1: (a[k] * np.clip(np.minimum(z1, 3.0) - z0, 0.0, None)
                                   + 0.5 * a[k] * np.clip(z1 - np.maximum(z0, 3.0), 0.0, None))
        m_of_z = lambda z: np.where(np.asarray(z) <= 3.0, m, 0.5 * m)  # noqa: E731
    else:
        def tau(k):
            return lambda z0, z1: a[k] * (z1 - z0)
        m_of_z = lambda z: m  # noqa: E731
    expect = _sky_raman_nadir_radiance(tau(0), tau(em), 1.0, 1.0, ISO, m_of_z)
    if sun:
        expect += _sun_raman_radiance_in_cap(tau(0), tau(em), 1.0, np.radians(2.0), ISO, m_of_z)
    return expect


@pytest.mark.parametrize("integrator, layered", [("path", False), ("path", True), ("hybrid", False),
                                                 ("hybrid", True)])
def test_fluorescence_matches_its_closed_form(zscore, integrator, layered):
    """Band 450 lit (the sky; the hybrid also the sun at the zenith), fluorescence at 685 nm
    seen going straight up at 1 m: single fluorescence (isotropic) of the refracted light, the
    phytoplankton absorbing 0.004 m^-1 at 450 nm (half that below 3 m in the layered water,
    whose total absorption halves there too)."""
    m = inelastic.chlorophyll_coupling(BANDS, A_PH, quantum_yield=0.03)[2, 0]
    expect = single_fluorescence_lu(A, 2, m, integrator == "hybrid", layered)
    a_ph = [list(A_PH), list(A_PH * 0.5)] if layered else A_PH
    scene = _scene(integrator, integrator == "hybrid", 1.0, layered, a_ph=a_ph)
    r = render(scene, radiometer_samples=2_000_000, seed=21, threads=2).radiometers[0]
    value, se = float(r.mean[0, 2]), float(r.stderr[0, 2])
    assert value == pytest.approx(float(r.components["chlorophyll"][0][0, 2]))  # all of it fluorescence
    assert not r.components["raman"][0].any()
    assert se < 0.02 * value, (value, se)
    zscore(f"fluorescence Lu 685 ({integrator}, {'layers' if layered else 'homogeneous'})", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 2e-3 * expect, (value, se, expect)


def test_fluorescence_and_raman_each_in_their_own_component(zscore):
    """Raman (450 -> 531 nm) and fluorescence (450 -> 685 nm) from the same beam: each band's
    light in its own component, each against its closed form (hybrid, the sun alone; the
    phytoplankton absorbing at 450 nm only, so no Raman light of band 531 fluoresces)."""
    a_ph = np.array([0.004, 0.0, 0.0])
    scene = _scene("hybrid", True, 0.0, raman=True, a_ph=a_ph)
    r = render(scene, radiometer_samples=400_000, seed=22, threads=2).radiometers[0]
    b_r = inelastic.raman_b([b.center_nm for b in BANDS])
    c = A + b_r
    tau = lambda k: (lambda z0, z1: c[k] * (z1 - z0))  # noqa: E731
    m_raman = inelastic.raman_coupling(BANDS)[1, 0]
    m_chl = inelastic.chlorophyll_coupling(BANDS, a_ph, quantum_yield=0.03)[2, 0]
    cap = np.radians(2.0)
    raman = _sun_raman_radiance_in_cap(tau(0), tau(1), 1.0, cap, inelastic.raman_phase, lambda z: m_raman)
    chl = _sun_raman_radiance_in_cap(tau(0), tau(2), 1.0, cap, ISO, lambda z: m_chl)
    for band, comp, expect in ((1, "raman", raman), (2, "chlorophyll", chl)):
        value, se = float(r.components[comp][0][0, band]), float(r.stderr[0, band])
        zscore(f"{comp} Lu beside the other process", value, expect, se)
        assert abs(value - expect) < 3.5 * se + 2e-4 * expect, (comp, value, se, expect)
    # (band 685 also gets a little Raman light of band 531's Raman light: a second inelastic
    # event, through the paths)
    assert r.components["chlorophyll"][0][0, 1] == 0.0 and r.components["raman"][0][0, 2] < 0.01 * chl
    total = sum(v[0] for v in r.components.values())
    np.testing.assert_allclose(total, r.mean, rtol=1e-12)


def test_bad_fluorescence_input_is_named():
    good = _scene("hybrid", True, 0.0).to_dict()

    def bad(**f):
        d = dict(good)
        d["water"] = [dict(good["water"][0], chlorophyll_fluorescence=dict(good["water"][0]["chlorophyll_fluorescence"], **f))]
        return d
    with pytest.raises(SceneError, match="chlorophyll_fluorescence.absorption.*at most"):
        Scene.from_dict(bad(absorption=[0.01, 0.0, 0.0])).validate()  # more than the water absorbs
    with pytest.raises(SceneError, match="chlorophyll_fluorescence.absorption.*one value per band"):
        Scene.from_dict(bad(absorption=[0.001, 0.0])).validate()
    with pytest.raises(SceneError, match="chlorophyll_fluorescence.quantum_yield"):
        Scene.from_dict(bad(quantum_yield=1.5)).validate()
    with pytest.raises(SceneError, match="chlorophyll_fluorescence.fwhm_nm"):
        Scene.from_dict(bad(fwhm_nm=0.0)).validate()
    blue = dict(good, bands=[{"name": "450", "center_nm": 450.0, "width_nm": 20.0},
                             {"name": "531", "center_nm": 531.0, "width_nm": 20.0},
                             {"name": "600", "center_nm": 600.0, "width_nm": 30.0}])
    assert any("fluoresces around 685 nm" in w for w in scene_warnings(Scene.from_dict(blue)))
    again = Scene.from_dict(Scene.from_dict(good).to_dict())  # round trip
    np.testing.assert_array_equal(again.water[0].fluorescence.absorption, A_PH)
    assert again.water[0].fluorescence.quantum_yield == 0.03
