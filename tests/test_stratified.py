"""Stratified water (an 'iop_profile' of horizontal layers): closed forms, agreement of the
hybrid and path integrators, Gershun's law across a layer boundary, equivalence with
homogeneous water, the scene format and its errors. Fixed seeds; z-scores recorded."""
import json
import math

import numpy as np
import pytest

from analytic import simpson, transmitted_uniform_sky, trapezoid
from photic import _core
from photic.profiles import align_components, gaussian_chlorophyll, profile_from_function
from photic.render import render
from photic.scene import (IOPProfile, IOPs, PhaseFunction, ScatteringComponent, Scene,
                          SceneError)

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

N_W = 1.34
Z_MAX = 3.0   # closed forms and cross-checks: within 3 standard errors

PETZOLD = {"type": "petzold"}
WATER = {"type": "pure_water"}


def iops(a, b_particles=0.0, b_water=0.0):
    return {"absorption": [a], "scattering": [{"b": [b_particles], "phase": PETZOLD},
                                              {"b": [b_water], "phase": WATER}]}


def layered_sea(z_top, layers, radiometers, *, sun=None, sky=None, integrator="path", seed=1,
                cone=0.0):
    water = {"name": "sea", "type": "ocean", "ior": N_W, "surface": {"kind": "flat", "z": 0.0}}
    if z_top is None:  # homogeneous: the first layer's IOPs everywhere
        water["iops"] = layers[0]
    else:
        water["iop_profile"] = {"z_top": list(z_top), "layers": [{"iops": x} for x in layers]}
    d = {"photic_scene": 1, "name": "stratified", "water": [water],
         "sky": sky or {"type": "black"}, "radiometers": list(radiometers),
         "settings": {"integrator": integrator, "seed": seed, "forward_cone_deg": cone}}
    if sun:
        d["sun"] = sun
    return Scene.from_dict(d)


def rad(q, z):
    return {"name": f"{q}_{z:g}", "quantity": q, "position": [0.0, 0.0, -z]}


def column_depth(z_top, a, depth):
    """int a dz from the surface (z = 0) down to `depth` (m) through piecewise-constant layers."""
    tops = list(z_top) + [-math.inf]
    tau = 0.0
    for i, ai in enumerate(a):
        hi, lo = min(0.0, tops[i]) if i else 0.0, max(-depth, tops[i + 1])
        tau += ai * max(0.0, hi - lo)
    return tau


def refracted_sun(zenith_deg, tau, e_sun=1.0, diameter_deg=0.53, weight="Ed"):
    """Ed (or Eo) at vertical absorption optical depth `tau` below a flat sea, b = 0, from a
    uniform sun disk: L_sun int_disk cos(theta) T_F(theta) exp(-tau / mu_w) w dw with w = 1
    (Ed) or 1 / mu_w (Eo); mu_w the refracted direction's cosine. Gauss-Legendre in the angle
    from the disk centre, trapezoid (periodic) in azimuth."""
    alpha = np.radians(diameter_deg) / 2
    th0 = np.radians(zenith_deg)
    x, wx = np.polynomial.legendre.leggauss(48)
    r, wr = alpha * (x + 1) / 2, wx * alpha / 2
    ph = np.linspace(0, 2 * np.pi, 256, endpoint=False)
    R, P = np.meshgrid(r, ph, indexing="ij")
    cz = np.cos(th0) * np.cos(R) + np.sin(th0) * np.sin(R) * np.cos(P)
    T = 1 - np.vectorize(lambda c: _core.fresnel(c, 1.0, N_W))(cz)
    mu_w = np.sqrt(1 - (1 - cz ** 2) / N_W ** 2)
    f = cz * T * np.exp(-tau / mu_w) * (1 / mu_w if weight == "Eo" else 1.0)
    integral = np.sum((f * np.sin(R)).mean(axis=1) * 2 * np.pi * wr)
    return e_sun / (np.pi * np.sin(alpha) ** 2) * integral


# --------------------------------------------------------------------------------------
# b = 0: Beer-Lambert through the layers
# --------------------------------------------------------------------------------------

TWO_LAYERS = ([0.0, -2.0], [0.1, 0.45])   # z_top (m), absorption (1/m)
DEPTHS = (1.0, 2.5, 4.0)                  # in both layers


def test_hybrid_sun_through_two_absorbing_layers(zscore):
    """Sun at 35 deg, black sky, b = 0: Ed and Eo equal the disk quadrature of
    E_sun cos T_F exp(-sum a_i dz_i / mu_w) (the product of the layers' transmittances along
    the refracted sun)."""
    z_top, a = TWO_LAYERS
    rads = [rad(q, z) for z in DEPTHS for q in ("Ed", "Eo")]
    sc = layered_sea(z_top, [iops(x) for x in a], rads, integrator="hybrid", seed=21,
                     sun={"zenith_deg": 35.0, "azimuth_deg": 20.0, "irradiance": [1.0]})
    res = render(sc, radiometer_samples=20_000)
    for z in DEPTHS:
        tau = column_depth(z_top, a, z)
        for q in ("Ed", "Eo"):
            r = res.radiometer(f"{q}_{z:g}")
            ref = refracted_sun(35.0, tau, weight=q)
            assert abs(zscore(f"hybrid sun {q}({z:g} m)", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
            assert abs(r.mean[0, 0] / ref - 1) < 1e-3


def test_path_uniform_sky_through_two_absorbing_layers(zscore):
    """Pure path tracing, uniform sky, b = 0: Ed and Eo equal the quadrature over Snell's
    window of n^2 T_F L exp(-tau(z) / mu) (mu or 1). A uniform sky rather than the sun: path
    tracing finds a 0.5-deg sun through a smooth surface only by chance, and a rough surface
    would need the rough BTDF in the reference; the sky gives a sharp closed form with the
    same absorption along every direction through the layers."""
    z_top, a = TWO_LAYERS
    rads = [rad(q, z) for z in DEPTHS for q in ("Ed", "Eo")]
    sc = layered_sea(z_top, [iops(x) for x in a], rads, integrator="path", seed=22,
                     sky={"type": "uniform", "radiance": [1.0]})
    res = render(sc, radiometer_samples=300_000)
    for z in DEPTHS:
        tau = column_depth(z_top, a, z)
        for q in ("Ed", "Eo"):
            r = res.radiometer(f"{q}_{z:g}")
            ref = transmitted_uniform_sky(1.0, tau, weight=q)
            assert abs(zscore(f"path sky {q}({z:g} m)", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX


# --------------------------------------------------------------------------------------
# Identical layers are homogeneous water
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("integrator", ["hybrid", "path"])
def test_identical_layers_reproduce_homogeneous_water(zscore, integrator):
    """A profile of three identical layers gives the homogeneous result: with the same seed to
    rounding (the same random decisions), with another seed within the standard errors."""
    layer = iops(0.15, 0.3, 0.05)
    rads = [rad(q, z) for z in (1.0, 3.0, 6.0) for q in ("Ed", "Eu", "Eo")]
    kw = dict(sky={"type": "uniform", "radiance": [0.3]}, integrator=integrator)
    if integrator == "hybrid":
        kw["sun"] = {"zenith_deg": 30.0, "azimuth_deg": 0.0, "irradiance": [1.0]}
    n = 20_000 if integrator == "hybrid" else 50_000
    homog = render(layered_sea(None, [layer], rads, seed=31, **kw), radiometer_samples=n)
    same = render(layered_sea([0.0, -2.0, -4.5], [layer] * 3, rads, seed=31, **kw), radiometer_samples=n)
    other = render(layered_sea([0.0, -2.0, -4.5], [layer] * 3, rads, seed=32, **kw), radiometer_samples=n)
    for r in homog.radiometers:
        s, o = same.radiometer(r.name), other.radiometer(r.name)
        assert s.mean[0, 0] == pytest.approx(r.mean[0, 0], rel=1e-9)
        se = float(np.hypot(r.stderr[0, 0], o.stderr[0, 0]))
        assert abs(zscore(f"{integrator} identical layers {r.name}", o.mean[0, 0], r.mean[0, 0], se)) < Z_MAX


# --------------------------------------------------------------------------------------
# With scattering: hybrid against path tracing in a three-layer column
# --------------------------------------------------------------------------------------

HG = {"type": "henyey_greenstein", "g": 0.85}


def mixture(a, b_particles, b_water):
    return {"absorption": [a], "scattering": [{"b": [b_particles], "phase": HG},
                                              {"b": [b_water], "phase": WATER}]}


# A clear layer, a turbid one (2-4 m) and clear water below; the particles' share of
# scattering differs between layers (component choice with the local coefficients).
THREE_LAYERS = ([0.0, -2.0, -4.0], [mixture(0.10, 0.25, 0.05), mixture(0.30, 1.2, 0.05),
                                    mixture(0.12, 0.08, 0.02)])


def test_hybrid_agrees_with_path_tracing_in_three_layers(zscore):
    """Ed, Eu, Eo at 1, 3 and 5 m (one depth per layer) agree within 3 combined standard
    errors. The sun is enlarged to 20 deg so that path tracing, which finds it only by
    escaping paths, converges; Henyey-Greenstein particles (g = 0.85) keep both estimators'
    variance moderate."""
    z_top, layers = THREE_LAYERS
    rads = [rad(q, z) for z in (1.0, 3.0, 5.0) for q in ("Ed", "Eu", "Eo")]
    sun = {"zenith_deg": 30.0, "azimuth_deg": 60.0, "irradiance": [1.0], "angular_diameter_deg": 20.0}
    hy = render(layered_sea(z_top, layers, rads, sun=sun, integrator="hybrid", seed=41),
                radiometer_samples=100_000)
    pt = render(layered_sea(z_top, layers, rads, sun=sun, integrator="path", seed=42),
                radiometer_samples=600_000)
    for r in hy.radiometers:
        p = pt.radiometer(r.name)
        se = float(np.hypot(r.stderr[0, 0], p.stderr[0, 0]))
        assert abs(zscore(f"3 layers hybrid vs path {r.name}", r.mean[0, 0], p.mean[0, 0], se)) < Z_MAX
        assert se / p.mean[0, 0] < (0.15 if r.name.startswith("Eu") else 0.05)


# --------------------------------------------------------------------------------------
# Conservation: a stratified white furnace
# --------------------------------------------------------------------------------------

def test_stratified_white_furnace_conserves_energy(zscore):
    """A closed non-absorbing water box in an isotropic environment L0, stratified into a
    scattering layer, a layer that does not scatter at all (majorant 0: crossed without
    collisions) and one with another mix of components: Eo = 4 pi n^2 L0 and L = n^2 L0 in
    every layer, whatever the layers do (regional tracking, local component choice)."""
    from geometry import box
    n, l0 = 1.34, 1.0
    wv, wt = box((-2, -2, -2), (2, 2, 2))
    layers = [mixture(0.0, 1.5, 0.5), mixture(0.0, 0.0, 0.0), mixture(0.0, 0.2, 0.6)]
    d = {"photic_scene": 1, "name": "furnace",
         "water": [{"name": "tank", "type": "mesh", "ior": n, "vertices": wv, "triangles": wt,
                    "iop_profile": {"z_top": [2.0, 0.5, -0.7], "layers": [{"iops": x} for x in layers]}}],
         "sky": {"type": "uniform", "radiance": [l0], "full_sphere": True},
         "radiometers": [{"name": f"Eo_{z:g}", "quantity": "Eo", "position": [0.3, -0.4, z]}
                         for z in (1.2, 0.0, -1.3)] +
                        [{"name": "L_mid", "quantity": "radiance", "position": [0.0, 0.5, 0.1],
                          "direction": [0.3, 0.2, -1.0]}],
         "settings": {"seed": 61, "max_depth": 100000}}
    res = render(Scene.from_dict(d), radiometer_samples=50_000)
    for r in res.radiometers:
        ref = (4 * np.pi if r.name.startswith("Eo") else 1.0) * n * n * l0
        assert r.medium == "tank"
        assert abs(zscore(f"stratified furnace {r.name}", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
        assert abs(r.mean[0, 0] / ref - 1) < 0.02


# --------------------------------------------------------------------------------------
# Gershun's law with the local absorption
# --------------------------------------------------------------------------------------

def test_gershun_law_across_a_layer_boundary(zscore):
    """Uniform sky; a = 0.1, b = 0.6 above z = -3 m and a = 0.4, b = 0.2 below:
    (Ed - Eu)(2 m) - (Ed - Eu)(4 m) = int a(z) Eo(z) dz, Simpson on Eo at 0.25-m steps within
    each layer (Eo is continuous at the boundary; a jumps there)."""
    z_top, a = [0.0, -3.0], [0.1, 0.4]
    layers = [iops(a[0], 0.5, 0.1), iops(a[1], 0.15, 0.05)]
    eo_depths = np.arange(2.0, 4.0001, 0.25)
    rads = [rad(q, z) for z in (2.0, 4.0) for q in ("Ed", "Eu")] + [rad("Eo", z) for z in eo_depths]
    res = render(layered_sea(z_top, layers, rads, integrator="path", seed=51,
                             sky={"type": "uniform", "radiance": [1.0]}), radiometer_samples=200_000)
    val = lambda n: (res.radiometer(n).mean[0, 0], res.radiometer(n).stderr[0, 0])
    (ed1, sd1), (eu1, su1) = val("Ed_2"), val("Eu_2")
    (ed2, sd2), (eu2, su2) = val("Ed_4"), val("Eu_4")
    lhs = (ed1 - eu1) - (ed2 - eu2)
    rhs, var = 0.0, sd1 ** 2 + su1 ** 2 + sd2 ** 2 + su2 ** 2
    for ai, (z1, z2) in zip(a, ((2.0, 3.0), (3.0, 4.0))):
        zs = [z for z in eo_depths if z1 - 1e-9 <= z <= z2 + 1e-9]
        eo = np.array([val(f"Eo_{z:g}") for z in zs])
        w = np.ones(len(zs)); w[1:-1:2] = 4; w[2:-1:2] = 2; w *= 0.25 / 3
        assert abs(np.sum(w * eo[:, 0]) - simpson(eo[:, 0], 0.25)) < 1e-12
        rhs += ai * np.sum(w * eo[:, 0])
        var += ai ** 2 * np.sum((w * eo[:, 1]) ** 2)
    se = math.sqrt(var)
    assert abs(zscore("Gershun 2-4 m across a boundary", lhs, rhs, se)) < Z_MAX
    assert se / rhs < 0.03
    # Either layer's a alone in place of a(z) misses by far: the test resolves the layers.
    eo_all = np.array([val(f"Eo_{z:g}")[0] for z in eo_depths])
    for ai in a:
        assert abs(lhs - ai * simpson(eo_all, 0.25)) > 10 * se


# --------------------------------------------------------------------------------------
# Scene format
# --------------------------------------------------------------------------------------

def profile_dict(**changes):
    d = {"photic_scene": 1, "name": "strat",
         "bands": [{"name": "b", "center_nm": 490, "width_nm": 10},
                   {"name": "g", "center_nm": 550, "width_nm": 10}],
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0},
                    "iop_profile": {"z_top": [0.0, -5.0, -10.0], "layers": [
                        {"iops": {"absorption": [0.02, 0.06], "b": [0.1, 0.1], "phase": PETZOLD}},
                        {"iops": {"absorption": [0.05, 0.08], "b": [0.5, 0.4], "phase": PETZOLD}},
                        {"iops": {"absorption": 0.04, "b": 0.05, "phase": PETZOLD}}]}}],
         "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [0, 0, -3]}]}
    for path, value in changes.items():
        node = d
        *head, last = path.split(".")
        for key in head:
            node = node[int(key)] if isinstance(node, list) else node[key]
        if value is _DELETE:
            del node[last]
        elif isinstance(node, list):
            node[int(last)] = value
        else:
            node[last] = value
    return d


_DELETE = object()


def test_profile_round_trips_and_broadcasts():
    sc = Scene.from_dict(profile_dict())
    prof = sc.water[0].iops
    assert isinstance(prof, IOPProfile)
    np.testing.assert_array_equal(prof.z_top, [0.0, -5.0, -10.0])
    np.testing.assert_array_equal(prof.layers[2].absorption, [0.04, 0.04])
    assert prof.layer_index(3.0) == 0 and prof.layer_index(-5.0) == 1 and prof.layer_index(-5.01) == 1
    assert prof.layer_index(-10.0) == 2 and prof.layer_index(-10.01) == 2
    assert prof.at(-100.0) is prof.layers[2]
    d = sc.to_dict()
    assert "iops" not in d["water"][0]
    back = Scene.from_dict(json.loads(json.dumps(d)))
    assert back == sc
    import jsonschema
    from photic.scene import scene_schema
    jsonschema.validate(d, scene_schema())


BAD = [
    pytest.param({"water.0.iop_profile.z_top": [0.0, -10.0, -5.0]}, "iop_profile.z_top[2]",
                 "strictly", id="unsorted"),
    pytest.param({"water.0.iop_profile.z_top": [0.0, -5.0, -5.0]}, "iop_profile.z_top[2]",
                 "strictly", id="repeated-top"),
    pytest.param({"water.0.iop_profile.z_top.1": math.nan}, "iop_profile.z_top[1]", "finite",
                 id="nan-top"),
    pytest.param({"water.0.iop_profile.layers.1.iops.absorption": [0.05, math.nan]},
                 "iop_profile.layers[1].iops.absorption[1]", "finite", id="nan-absorption"),
    pytest.param({"water.0.iop_profile.layers.2.iops.b": [0.1, 0.1, 0.1]},
                 "iop_profile.layers[2].iops.b", "band", id="band-count"),
    pytest.param({"water.0.iop_profile.layers.1.iops.phase": {"type": "henyey_greenstein", "g": 0.9}},
                 "iop_profile.layers[1].iops.scattering[0].phase", "layers may differ only in a and b",
                 id="other-phase"),
    pytest.param({"water.0.iop_profile.layers.2.iops": {"absorption": 0.04}},
                 "iop_profile.layers[2].iops.scattering", "same components", id="missing-component"),
    pytest.param({"water.0.iop_profile.z_top": [0.0, -5.0]}, "iop_profile.layers",
                 "one IOPs per layer top", id="count-mismatch"),
    pytest.param({"water.0.iop_profile.layers.0.iops.absorption": -0.1},
                 "iop_profile.layers[0].iops.absorption", ">= 0", id="negative"),
    pytest.param({"water.0.iop_profile.layers.0.extra": 1}, "iop_profile.layers[0].extra",
                 "unknown key", id="unknown-key"),
    pytest.param({"water.0.iops": {"absorption": 0.1}}, "iop_profile",
                 "only one of", id="iops-and-profile"),
    pytest.param({"water.0.iop_profile": _DELETE}, "iops", "give one of", id="no-iops"),
    pytest.param({"water.0.iop_profile.z_top": []}, "iop_profile.z_top", "at least 1", id="empty"),
]


@pytest.mark.parametrize("changes,field,words", BAD)
def test_bad_profiles_name_the_field(changes, field, words):
    with pytest.raises(SceneError) as info:
        Scene.from_dict(profile_dict(**changes))
    e = info.value
    assert e.obj == "water 'sea'", str(e)
    assert e.field == field, str(e)
    assert words in str(e), str(e)


def test_python_profiles_are_validated_like_files():
    sc = Scene.from_dict(profile_dict())
    sc.water[0].iops.z_top = np.array([0.0, -5.0, np.nan])
    with pytest.raises(SceneError, match=r"iop_profile\.z_top\[2\]"):
        sc.validate()
    sc = Scene.from_dict(profile_dict())
    sc.water[0].iops.layers[1].scattering.append(
        ScatteringComponent([0.1, 0.1], PhaseFunction("pure_water")))
    with pytest.raises(SceneError, match=r"layers\[1\]\.iops\.scattering'.*2 component"):
        sc.validate()


def test_model_layers_are_aligned_on_their_phase_functions():
    """Layers from 'iop_model': particles only in the middle layer; the profile's layers all
    get [pure water, particles] with b = 0 where there are none, and CDOM only absorbs."""
    d = profile_dict()
    particles = {"model": "particles", "b_ref": 0.4, "backscatter_fraction": 0.012}
    d["water"][0]["iop_profile"]["layers"] = [
        {"iop_model": {"model": "cdom", "a_ref": 0.05}},
        {"iop_model": {"model": "mixture", "components": [particles, {"model": "cdom", "a_ref": 0.2}]}},
        {"iops": {"absorption": [0.1, 0.1], "b": [0.0, 0.0], "phase": WATER}}]
    prof = Scene.from_dict(d).water[0].iops
    phases = [[c.phase for c in layer.scattering] for layer in prof.layers]
    assert phases[0] == phases[1] == phases[2]
    assert [p.type for p in phases[0]] == ["pure_water", "fournier_forand"]
    np.testing.assert_array_equal(prof.layers[0].scattering[1].b, [0.0, 0.0])
    assert np.all(prof.layers[1].scattering[1].b > 0.3)
    # explicit pure-water b = 0 summed with nothing: the third layer scatters nothing
    np.testing.assert_array_equal(prof.layers[2].scattering[0].b, [0.0, 0.0])
    with pytest.raises(SceneError, match=r"iop_profile\.layers\[1\]\.iop_model\.components\[0\]\.b_ref"):
        particles["b_ref"] = -1.0
        Scene.from_dict(d)


def test_profile_from_a_gaussian_chlorophyll_maximum():
    """The helper averages each layer's coefficients over its depth (Gauss-Legendre): checked
    against a fine trapezoid of the same model; components aligned; the last layer takes the
    value at its top. Chlorophyll drives particle scattering and CDOM here (the Case-1 models
    need a user-supplied chlorophyll absorption table)."""
    chl = gaussian_chlorophyll(background=0.2, peak=1.5, z_max=-20.0, width=4.0)
    assert chl(-20.0) == pytest.approx(1.7) and chl(-1000.0) == pytest.approx(0.2)
    bands = [(490.0, 10.0), (550.0, 10.0)]

    def model(z):
        c = chl(z)
        return {"model": "mixture", "water": "none", "components": [
            {"model": "particles", "b_ref": 0.3 * c ** 0.62, "backscatter_fraction": 0.01},
            {"model": "cdom", "a_ref": 0.01 + 0.03 * c}]}

    tops = np.arange(0.0, -40.0, -4.0)
    prof = profile_from_function(model, tops, bands, nodes=6)
    assert len(prof.layers) == len(tops)
    from photic.iop_models import iops_from_model
    for i in (2, 5):   # layers around the maximum
        zs = np.linspace(tops[i + 1], tops[i], 2001)
        b = np.array([iops_from_model(model(z), bands).scattering[0].b for z in zs])
        a = np.array([iops_from_model(model(z), bands).absorption for z in zs])
        np.testing.assert_allclose(prof.layers[i].scattering[0].b, trapezoid(b, zs, axis=0) / 4.0, rtol=1e-5)
        np.testing.assert_allclose(prof.layers[i].absorption, trapezoid(a, zs, axis=0) / 4.0, rtol=1e-5)
    last = iops_from_model(model(tops[-1]), bands)
    np.testing.assert_allclose(prof.layers[-1].absorption, last.absorption, rtol=1e-12)
    # explicit IOPs from the function, aligned; a scene takes the profile
    explicit = profile_from_function(lambda z: IOPs([0.1 - 0.001 * z], []) if z > -10 else
                                     IOPs([0.2], [ScatteringComponent([0.3], PhaseFunction("isotropic"))]),
                                     [0.0, -5.0, -10.0], nodes=2)
    assert [len(x.scattering) for x in explicit.layers] == [1, 1, 1]
    np.testing.assert_allclose(explicit.layers[0].absorption, [0.1025])  # linear: exact mean
    with pytest.raises(ValueError, match="descending"):
        profile_from_function(model, [0.0, 1.0], bands)


def test_align_components_sums_equal_phase_functions():
    p, q = PhaseFunction("petzold"), PhaseFunction("henyey_greenstein", {"g": 0.8})
    out = align_components([IOPs([0.1], [ScatteringComponent([0.2], p), ScatteringComponent([0.3], p)]),
                            IOPs([0.2], [ScatteringComponent([0.4], q)])])
    assert [c.phase for c in out[0].scattering] == [p, q] == [c.phase for c in out[1].scattering]
    np.testing.assert_allclose(out[0].scattering[0].b, [0.5])
    np.testing.assert_allclose(out[1].scattering[0].b, [0.0])
