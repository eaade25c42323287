"""CDOM fluorescence (issue 42, third process): Hawes' (1992) quantum efficiency against its own
closed forms (peak, photon yield), the coupling's photon bookkeeping, and both integrators'
CDOM fluorescence against closed forms of single fluorescence of the refracted sky and sun in
water that does not scatter elastically, homogeneous and layered, beside chlorophyll
fluorescence (each in its own component); its inputs named when wrong."""
import math

import numpy as np
import pytest

from photic import inelastic
from photic.iop_models import fluorescent_absorption, iops_from_model
from photic.render import render
from photic.scene import Band, Scene, SceneError, scene_warnings
from test_fluorescence import ISO, single_fluorescence_lu
from test_raman import IOR, _sun_raman_radiance_in_cap

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

BANDS = [Band("440", 440.0, 20.0), Band("560", 560.0, 20.0), Band("685", 685.0, 30.0)]
A = np.array([0.02, 0.07, 0.45])       # the water's absorption (m^-1)
A_CDOM = np.array([0.015, 0.0, 0.0])   # the CDOM's part: it absorbs (and is excited) at 440 only
A_PH = np.array([0.004, 0.0, 0.0])


def test_hawes_efficiency_peaks_where_its_fit_says_and_yields_its_integral():
    """For each excitation l', eta is a Gaussian in wavenumber centred at A1 / l' + B1 with
    1/e half-width s = 0.6 (A2 / l' + B2): its peak is at 1 / (A1 / l' + B1), and its photon
    yield int eta dl = A0 int exp(-((nu - nu0) / s)^2) nu^-2 dnu = A0 s sqrt(pi) / nu0^2
    (1 + 3 v + 15 v^2 + 105 v^3), v = s^2 / (2 nu0^2) (the Gaussian's moments of nu^-2)."""
    lam = np.linspace(300.0, 900.0, 600_001)
    for lx, a0 in ((350.0, 8.00e-5), (450.0, 13.48e-5), (490.0, 9.27e-5)):
        nu0 = inelastic.HAWES_A1 / lx + inelastic.HAWES_B1
        s = 0.6 * (inelastic.HAWES_A2 / lx + inelastic.HAWES_B2)
        eta = inelastic.cdom_efficiency(lx, lam)
        assert lam[eta.argmax()] == pytest.approx(1.0 / nu0, abs=0.002)
        assert eta.max() == pytest.approx(a0, rel=1e-9)
        v = s * s / (2.0 * nu0 * nu0)
        closed = a0 * s * math.sqrt(math.pi) / nu0 ** 2 * (1 + 3 * v + 15 * v ** 2 + 105 * v ** 3)
        assert inelastic.cdom_quantum_yield(lx) == pytest.approx(closed, rel=2e-4)
    assert 0.009 < inelastic.cdom_quantum_yield(310.0) < inelastic.cdom_quantum_yield(450.0) < 0.02
    assert inelastic.cdom_quantum_yield(300.0) == 0.0 and inelastic.cdom_quantum_yield(550.0) == 0.0


def test_coupling_keeps_the_photons():
    """Photons emitted (energy per nm x wavelength, over emission bands 1 nm wide from 300 to
    1,200 nm) = photons absorbed (a x the band's integral of l') x the yield."""
    bands = [Band("450", 450.0, 2.0)] + [Band(f"{c}", float(c), 1.0) for c in np.arange(300.5, 1200.0, 1.0)]
    a = np.zeros(len(bands))
    a[0] = 0.05
    m = inelastic.cdom_coupling(bands, a, efficiency_scale=2.0)
    centers = np.array([b.center_nm for b in bands])
    emitted = float((m[1:, 0] * 1.0 * centers[1:]).sum())
    absorbed = 2.0 * 0.05 * 2.0 * 450.0 * inelastic.cdom_quantum_yield(450.0)
    assert emitted == pytest.approx(absorbed, rel=2e-3)
    assert not m[:, 1:].any()  # only the absorbing band excites
    layered = inelastic.cdom_coupling(bands[:3], np.stack([a[:3], 0.5 * a[:3]]))
    np.testing.assert_allclose(layered[1], 0.5 * layered[0])
    assert inelastic.cdom_coverage(BANDS, A_CDOM) < 0.5 < inelastic.cdom_coverage(
        [Band(f"{c}", float(c), 10.0) for c in range(405, 700, 10)], np.full(30, 0.01))


def _scene(integrator, sun, sky, layered=False, a_cdom=A_CDOM, a_ph=None):
    water = {"name": "sea", "type": "ocean", "ior": IOR, "surface": {"kind": "flat", "z": 0.0}}
    iops = {"absorption": list(A), "b": [0.0] * 3, "phase": {"type": "isotropic"}}
    if layered:
        water["iop_profile"] = {"z_top": [0.0, -3.0], "layers": [{"iops": iops},
                                                                   {"iops": dict(iops, absorption=list(A * 0.5))}]}
    else:
        water["iops"] = iops
    water["cdom_fluorescence"] = {"absorption": np.asarray(a_cdom).tolist(), "efficiency_scale": 1.5}
    if a_ph is not None:
        water["chlorophyll_fluorescence"] = {"absorption": np.asarray(a_ph).tolist(), "quantum_yield": 0.03}
    d = {"photic_scene": 1, "name": "cdom fluorescence",
         "bands": [{"name": b.name, "center_nm": b.center_nm, "width_nm": b.width_nm} for b in BANDS],
         "water": [water], "sky": {"type": "uniform", "radiance": [sky, 0.0, 0.0]},
         "radiometers": [{"name": "Lu", "quantity": "radiance", "position": [0.0, 0.0, -1.0],
                          "direction": [0.0, 0.0, -1.0], "half_angle_deg": 2.0}],
         "settings": {"integrator": integrator, "raman": False, "seed": 3, "forward_cone_deg": 0}}
    if sun:
        d["sun"] = {"zenith_deg": 0.0, "azimuth_deg": 0.0, "irradiance": [1.0, 0.0, 0.0]}
    return Scene.from_dict(d)


@pytest.mark.parametrize("integrator, layered", [("path", False), ("path", True), ("hybrid", False),
                                                 ("hybrid", True)])
def test_cdom_fluorescence_matches_its_closed_form(zscore, integrator, layered):
    """Band 440 lit (the sky; the hybrid also the sun at the zenith), CDOM fluorescence at
    560 nm seen going straight up at 1 m: single fluorescence (isotropic) of the refracted
    light, the CDOM absorbing 0.015 m^-1 at 440 nm (half that below 3 m in the layered water,
    whose total absorption halves there too)."""
    m = inelastic.cdom_coupling(BANDS, A_CDOM, 1.5)[1, 0]
    expect = single_fluorescence_lu(A, 1, m, integrator == "hybrid", layered)
    a_cdom = [list(A_CDOM), list(A_CDOM * 0.5)] if layered else A_CDOM
    scene = _scene(integrator, integrator == "hybrid", 1.0, layered, a_cdom=a_cdom)
    r = render(scene, radiometer_samples=2_000_000, seed=31, threads=2).radiometers[0]
    value, se = float(r.mean[0, 1]), float(r.stderr[0, 1])
    assert value == pytest.approx(float(r.components["cdom"][0][0, 1]))  # all of it CDOM fluorescence
    assert not r.components["chlorophyll"][0].any() and not r.components["raman"][0].any()
    assert se < 0.02 * value, (value, se)
    zscore(f"CDOM fluorescence Lu 560 ({integrator}, {'layers' if layered else 'homogeneous'})", value, expect, se)
    assert abs(value - expect) < 3.5 * se + 2e-3 * expect, (value, se, expect)


def test_cdom_and_chlorophyll_fluorescence_each_in_their_own_component(zscore):
    """Both from the same beam (hybrid, the sun alone): CDOM's light at 560 nm and
    chlorophyll's at 685 nm, each in its component against its closed form (band 685 also gets
    a little of CDOM's far tail: within its own component)."""
    scene = _scene("hybrid", True, 0.0, a_ph=A_PH)
    r = render(scene, radiometer_samples=400_000, seed=32, threads=2).radiometers[0]
    tau = lambda k: (lambda z0, z1: A[k] * (z1 - z0))  # noqa: E731
    cap = np.radians(2.0)
    m_cdom = inelastic.cdom_coupling(BANDS, A_CDOM, 1.5)
    m_chl = inelastic.chlorophyll_coupling(BANDS, A_PH, quantum_yield=0.03)[2, 0]
    cdom = _sun_raman_radiance_in_cap(tau(0), tau(1), 1.0, cap, ISO, lambda z: m_cdom[1, 0])
    chl = _sun_raman_radiance_in_cap(tau(0), tau(2), 1.0, cap, ISO, lambda z: m_chl)
    for band, comp, expect in ((1, "cdom", cdom), (2, "chlorophyll", chl)):
        value, se = float(r.components[comp][0][0, band]), float(r.stderr[0, band])
        zscore(f"{comp} Lu beside the other fluorescence", value, expect, se)
        assert abs(value - expect) < 3.5 * se + 2e-4 * expect, (comp, value, se, expect)
    assert r.components["chlorophyll"][0][0, 1] == 0.0
    total = sum(v[0] for v in r.components.values())
    np.testing.assert_allclose(total, r.mean, rtol=1e-12)


def test_bad_cdom_fluorescence_input_is_named():
    good = _scene("hybrid", True, 0.0).to_dict()

    def bad(**f):
        d = dict(good)
        d["water"] = [dict(good["water"][0], cdom_fluorescence=dict(good["water"][0]["cdom_fluorescence"], **f))]
        return d
    with pytest.raises(SceneError, match="cdom_fluorescence.absorption.*at most"):
        Scene.from_dict(bad(absorption=[0.03, 0.0, 0.0])).validate()  # more than the water absorbs
    with pytest.raises(SceneError, match="cdom_fluorescence.absorption.*one value per band"):
        Scene.from_dict(bad(absorption=[0.001, 0.0])).validate()
    with pytest.raises(SceneError, match="cdom_fluorescence.efficiency_scale"):
        Scene.from_dict(bad(efficiency_scale=-1.0)).validate()
    both = dict(good)
    both["water"] = [dict(good["water"][0], chlorophyll_fluorescence={"absorption": [0.01, 0.0, 0.0]})]
    with pytest.raises(SceneError, match="cdom_fluorescence.absorption.*phytoplankton and CDOM"):
        Scene.from_dict(both).validate()  # 0.015 + 0.01 > 0.02
    no_model = dict(good)
    no_model["water"] = [dict(good["water"][0], cdom_fluorescence={})]
    with pytest.raises(SceneError, match="cdom_fluorescence.absorption.*iop_model"):
        Scene.from_dict(no_model)
    warnings = scene_warnings(Scene.from_dict(good))
    assert any("CDOM fluoresces" in w and "hold" in w for w in warnings), warnings
    red = dict(good)
    red["water"] = [dict(good["water"][0], cdom_fluorescence={"absorption": [0.0, 0.0, 0.1]})]
    assert any("adds nothing" in w for w in scene_warnings(Scene.from_dict(red)))
    again = Scene.from_dict(Scene.from_dict(good).to_dict())  # round trip
    np.testing.assert_array_equal(again.water[0].cdom_fluorescence.absorption, A_CDOM)
    assert again.water[0].cdom_fluorescence.efficiency_scale == 1.5


def test_absorption_comes_from_the_water_model():
    """With an iop_model and no absorption given, CDOM fluorescence takes the model's CDOM."""
    model = {"model": "mixture", "components": [{"model": "cdom", "a_ref": 0.2},
                                                {"model": "particles", "b_ref": 0.1}]}
    bands = [(440.0, 20.0), (560.0, 20.0), (685.0, 30.0)]
    parts = fluorescent_absorption(model, bands)
    np.testing.assert_allclose(parts["cdom"], iops_from_model({"model": "cdom", "a_ref": 0.2, "water": "none"}, bands).absorption)
    assert not parts["phytoplankton"].any()
    d = _scene("hybrid", True, 0.0).to_dict()
    water = {k: v for k, v in d["water"][0].items() if k != "iops"}
    d["water"] = [dict(water, iop_model=model, cdom_fluorescence={"efficiency_scale": 1.0})]
    scene = Scene.from_dict(d)
    scene.validate()
    np.testing.assert_allclose(scene.water[0].cdom_fluorescence.absorption, parts["cdom"])
