"""IOP models (photic.iop_models): published spot values, band averages, mixtures, errors.

The chlorophyll-absorption tables below are *test inputs* (made-up shapes that exercise the
formulas), not published spectra: Photic bundles none (see docs/iop-models.md)."""
import math

import numpy as np
import pytest

from photic import iop_models as m
from photic import phase
from photic.scene import PHASE_FUNCTION_PARAMS, Band, PhaseFunction, SceneError

# Test inputs: a*_c normalised at 440 and linear in lambda; Bricaud-style A, E (made up).
ASTAR = m.SpectralTable("test a*_c", [400.0, 440.0, 700.0], a_star=[0.6, 1.0, 3.6])
AE = m.SpectralTable("test A,E", [400.0, 440.0, 700.0], A=[0.05, 0.06, 0.01], E=[0.7, 0.7, 0.8])
ASTAR_SPEC = {"wavelength_nm": [400.0, 440.0, 700.0], "a_star": [0.6, 1.0, 3.6]}
AE_SPEC = {"wavelength_nm": [400.0, 440.0, 700.0], "A": [0.05, 0.06, 0.01], "E": [0.7, 0.7, 0.8]}
RGB = [Band("blue", 460.0, 20.0), Band("green", 550.0, 20.0), Band("red", 620.0, 20.0)]


def at(*wavelengths):
    """Zero-width bands: the models evaluated at these wavelengths."""
    return [(w, 0.0) for w in wavelengths]


def quad_mean(f, lo, hi, n=200001):
    x = np.linspace(lo, hi, n)
    v = f(x)
    return float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(x)) / (hi - lo))


# --- pure water -------------------------------------------------------------------------

def test_pope_fry_spot_values():
    # Pope & Fry 1997 table values (also quoted in PHYSICS-NOTES 6: 0.00922, 0.0565, 0.340)
    a = m.pure_water_absorption(at(380, 450, 550, 650, 727.5), "pope_fry")
    assert a == pytest.approx([0.01137, 0.00922, 0.0565, 0.340, 1.678], rel=1e-12)
    # half-way between two 2.5 nm nodes: linear interpolation
    assert m.pure_water_absorption(at(441.25))[0] == pytest.approx(0.5 * (0.00635 + 0.00696))


def test_smith_baker_spot_values():
    a = m.pure_water_absorption(at(200, 440, 500, 600, 800), "smith_baker")
    assert a == pytest.approx([3.07, 0.0145, 0.0257, 0.244, 2.07], rel=1e-12)


def test_combined_table_uses_pope_fry_inside_and_smith_baker_outside():
    bands = [(350.0, 10.0), (450.0, 0.0), (375.0, 20.0), (755.0, 0.0)]
    a = m.pure_water_absorption(bands, "pope_fry_smith_baker")
    assert a[1] == 0.00922
    assert a[0] == m.pure_water_absorption([(350.0, 10.0)], "smith_baker")[0]
    assert a[2] == m.pure_water_absorption([(375.0, 20.0)], "smith_baker")[0]  # straddles 380
    assert a[3] == pytest.approx(0.5 * (2.47 + 2.55))


def test_pure_seawater_scattering():
    assert m.pure_seawater_scattering(at(500))[0] == pytest.approx(0.00288, rel=1e-12)
    assert m.pure_seawater_scattering(at(400))[0] == pytest.approx(0.0076, abs=0.00005)
    # against Smith & Baker's tabulated b_w (2-3 significant digits)
    sb = m.smith_baker_1981()
    wl, bw = sb.wavelength_nm, sb.columns["bw_seawater_per_m"]
    ours = m.pure_seawater_scattering(at(*wl))
    blue = (wl >= 300) & (wl <= 550)
    assert ours[blue] == pytest.approx(bw[blue], rel=0.025)
    red = wl > 550
    assert np.all(np.abs(ours[red] - bw[red]) <= 1.0e-4)
    water = m.pure_water(RGB)
    assert len(water.scattering) == 1 and water.scattering[0].phase.type == "pure_water"


def test_band_averages_are_exact():
    band = (452.3, 17.0)
    lo, hi = 452.3 - 8.5, 452.3 + 8.5
    t = m.pope_fry_1997()
    exact = quad_mean(lambda x: t("aw_per_m", x), lo, hi)
    assert m.pure_water_absorption([band])[0] == pytest.approx(exact, rel=1e-7)
    exact = quad_mean(lambda x: 0.00288 * (x / 500) ** -4.32, lo, hi)
    assert m.pure_seawater_scattering([band])[0] == pytest.approx(exact, rel=1e-9)
    exact = quad_mean(lambda x: 0.3 * np.exp(-0.017 * (x - 412.0)), lo, hi)
    assert m.cdom_absorption([band], 0.3, 412.0, 0.017)[0] == pytest.approx(exact, rel=1e-9)
    # a very narrow band equals the centre value
    assert m.pure_seawater_scattering([(500.0, 1e-9)])[0] == pytest.approx(0.00288, rel=1e-12)


def test_band_average_of_a_linear_function_is_its_centre_value():
    # a*_c of ASTAR is linear in lambda (0.01 per nm): a_p over [420, 460] = a_p(440)
    iops = m.case1_classic([(440.0, 40.0), (500.0, 60.0)], 1.0, ASTAR, covarying_cdom=False)
    assert iops.absorption == pytest.approx([0.06, 0.06 * 1.6], rel=1e-12)


# --- CDOM ---------------------------------------------------------------------------------

def test_cdom():
    a = m.cdom_absorption(at(440, 450, 430), 0.1)
    assert a == pytest.approx([0.1, 0.1 * math.exp(-0.14), 0.1 * math.exp(0.14)], rel=1e-12)
    a = m.cdom_absorption(at(400, 401), 0.5, 400.0, 0.018)
    assert a == pytest.approx([0.5, 0.5 * math.exp(-0.018)], rel=1e-12)
    assert m.cdom(RGB, 0.1).scattering == []


# --- Case 1 -------------------------------------------------------------------------------

def test_case1_classic_spot_values():
    iops = m.case1_classic(at(440, 550), 1.0, ASTAR, covarying_cdom=False)
    assert iops.absorption[0] == pytest.approx(0.06, rel=1e-12)          # 0.06 a*_c(440) C^0.65
    (particles,) = iops.scattering
    assert particles.b[1] == pytest.approx(0.30, rel=1e-12)              # 0.30 C^0.62 (550/550)
    assert particles.b[0] == pytest.approx(0.30 * 550 / 440, rel=1e-12)
    assert particles.phase.type == "petzold"
    c = 2.0
    iops = m.case1_classic(at(440, 550), c, ASTAR, covarying_cdom=False)
    assert iops.absorption[0] == pytest.approx(0.06 * c ** 0.65, rel=1e-12)
    assert iops.scattering[0].b[1] == pytest.approx(0.30 * c ** 0.62, rel=1e-12)


def test_case1_classic_normalises_a_star_and_adds_covarying_cdom():
    # a table in m^2/mg (not normalised) gives the same result
    scaled = m.SpectralTable("scaled", ASTAR.wavelength_nm, a_star=0.035 * ASTAR.columns["a_star"])
    one = m.case1_classic(RGB, 0.7, ASTAR)
    two = m.case1_classic(RGB, 0.7, scaled)
    assert one.absorption == pytest.approx(two.absorption, rel=1e-12)
    # co-varying CDOM: 0.2 a_p(440) exp(-0.014 (lambda - 440)) = 0.012 C^0.65 at 440
    with_cdom = m.case1_classic(at(440, 450), 1.0, ASTAR).absorption
    without = m.case1_classic(at(440, 450), 1.0, ASTAR, covarying_cdom=False).absorption
    assert with_cdom - without == pytest.approx([0.012, 0.012 * math.exp(-0.14)], rel=1e-12)


def test_case1_new_spot_values():
    c = 1.0
    iops = m.case1_new(at(440, 550, 700), c, AE, covarying_cdom=False)
    assert iops.absorption == pytest.approx([0.06, AE("A", 550.0) * 1.0, 0.01], rel=1e-12)
    b = sum(s.b for s in iops.scattering)
    nu = 0.5 * (0.0 - 0.3)
    assert b[1] == pytest.approx(0.416, rel=1e-12)                         # 0.416 C^0.766
    assert b[0] == pytest.approx(0.416 * (440 / 550) ** nu, rel=1e-12)
    # Morel & Maritorena 2001: b_bp / b_p at 550 nm and C = 1 is 0.002 + 0.01 * 0.5 = 0.007
    ratios = m.morel_maritorena_backscatter_ratio(c, at(440, 550, 700))
    assert ratios[1] == pytest.approx(0.007, rel=1e-12)
    assert ratios[0] == pytest.approx(0.002 * (440 / 550) ** -nu + 0.005, rel=1e-12)
    fracs = {s.phase.params["backscatter_fraction"] for s in iops.scattering}
    assert fracs == {float(f"{r:.4g}") for r in ratios}
    # chlorophyll-dependent exponents: nu = -1 below 0.02, 0 above 2
    for chl, nu in [(0.01, -1.0), (0.5, 0.5 * (math.log10(0.5) - 0.3)), (5.0, 0.0)]:
        b = sum(s.b for s in m.case1_new(at(450), chl, AE).scattering)
        assert b[0] == pytest.approx(0.416 * chl ** 0.766 * (450 / 550) ** nu, rel=1e-12)
    # co-varying CDOM: 0.2 a_p(440) exp(-0.014 (lambda - 440)), a_p(440) = A(440) C^E(440)
    c = 3.0
    diff = (m.case1_new(at(440, 460), c, AE).absorption
            - m.case1_new(at(440, 460), c, AE, covarying_cdom=False).absorption)
    a440 = 0.06 * c ** 0.7
    assert diff == pytest.approx([0.2 * a440, 0.2 * a440 * math.exp(-0.28)], rel=1e-12)


def test_fournier_forand_backscatter_round_trip():
    # every band's b_bp/b_p becomes a Fournier-Forand (n, mu) that gives it back
    iops = m.case1_new(RGB, 0.3, AE)
    assert len(iops.scattering) == 3
    for comp in iops.scattering:
        assert np.count_nonzero(comp.b) == 1  # one band per fraction
        bb = comp.phase.params["backscatter_fraction"]
        n, mu = phase.ff_parameters(bb)
        assert phase.ff_backscatter_fraction(n, mu) == pytest.approx(bb, rel=1e-6)
    n, mu = phase.ff_parameters(0.0183)  # Mobley et al. 2002: Petzold-like, mu = 3.5835
    assert mu == pytest.approx(3.5835, abs=2e-4) and n == pytest.approx(1.10, abs=2e-3)


def test_particles():
    p = m.particles(at(550, 440), 0.5, phase=0.01, a_ref=0.02)
    assert p.scattering[0].b == pytest.approx([0.5, 0.5 * 550 / 440], rel=1e-12)
    assert p.scattering[0].phase == PhaseFunction("fournier_forand", {"backscatter_fraction": 0.01})
    assert p.absorption == pytest.approx([0.02 * math.exp(-0.0123 * 107),
                                          0.02 * math.exp(0.0123 * 3)], rel=1e-12)
    hg = m.particles(at(500), 1.0, exponent=0.0,
                     phase=PhaseFunction("henyey_greenstein", {"g": 0.9}))
    assert hg.scattering[0].b[0] == 1.0 and hg.scattering[0].phase.params == {"g": 0.9}


# --- mixtures and the declarative description --------------------------------------------

def test_mixture_sums():
    spec = {"model": "mixture", "water": "pope_fry",
            "components": [{"model": "cdom", "a_ref": 0.05},
                           {"model": "particles", "b_ref": 0.4, "backscatter_fraction": 0.02},
                           {"model": "case1", "chlorophyll": 0.5,
                            "chlorophyll_absorption": ASTAR_SPEC}]}
    iops = m.iops_from_model(spec, RGB)
    parts = [m.pure_water(RGB), m.cdom(RGB, 0.05), m.particles(RGB, 0.4, phase=0.02),
             m.case1_classic(RGB, 0.5, ASTAR)]
    assert iops.absorption == pytest.approx(sum(p.absorption for p in parts), rel=1e-12)
    assert iops.total_scattering == pytest.approx(sum(p.total_scattering for p in parts), rel=1e-12)
    assert [s.phase.type for s in iops.scattering] == ["pure_water", "fournier_forand", "petzold"]
    assert m.mix(*parts).absorption == pytest.approx(iops.absorption, rel=1e-12)
    for s in iops.scattering:  # valid scene IOPs
        assert s.b.shape == (3,) and set(s.phase.params) == set(PHASE_FUNCTION_PARAMS[s.phase.type])


def test_case1_description_options(tmp_path):
    base = {"model": "case1", "chlorophyll": 0.5, "variant": "new", "water": "none"}
    inline = m.iops_from_model({**base, "chlorophyll_absorption": AE_SPEC}, RGB)
    (tmp_path / "ae.csv").write_text("# test table\nwavelength_nm,A,E\n400,0.05,0.7\n"
                                     "440,0.06,0.7\n700,0.01,0.8\n")
    filed = m.iops_from_model({**base, "chlorophyll_absorption": {"file": "ae.csv"}}, RGB,
                              base_dir=tmp_path)
    assert filed.absorption == pytest.approx(inline.absorption, rel=1e-12)
    direct = m.case1_new(RGB, 0.5, AE)
    assert inline.absorption == pytest.approx(direct.absorption, rel=1e-12)
    # CDOM options: none, a slope, an independent CDOM
    spec = {**base, "chlorophyll_absorption": AE_SPEC}
    none = m.iops_from_model({**spec, "cdom": "none"}, RGB).absorption
    assert none == pytest.approx(m.case1_new(RGB, 0.5, AE, covarying_cdom=False).absorption)
    slope = m.iops_from_model({**spec, "cdom": {"slope": 0.02}}, RGB).absorption
    assert slope == pytest.approx(m.case1_new(RGB, 0.5, AE, cdom_slope=0.02).absorption)
    own = m.iops_from_model({**spec, "cdom": {"a_ref": 0.1, "slope": 0.01}}, RGB).absorption
    assert own == pytest.approx(none + m.cdom_absorption(RGB, 0.1, 440.0, 0.01))
    ff = m.iops_from_model({**spec, "particle_phase": {"type": "fournier_forand",
                                                       "backscatter_fraction": 0.01}}, RGB)
    assert len(ff.scattering) == 1 and ff.scattering[0].phase.params["backscatter_fraction"] == 0.01


def errors(spec, bands=RGB, **kw):
    with pytest.raises(SceneError) as info:
        m.iops_from_model(spec, bands, **kw)
    return info.value


def test_errors_name_the_field():
    case1 = {"model": "case1", "chlorophyll": 1.0, "chlorophyll_absorption": ASTAR_SPEC}
    e = errors({**case1, "chlorophyll": -1.0})
    assert e.field == "chlorophyll" and ">= 0" in e.message
    e = errors({**case1, "variant": "new", "chlorophyll": 0.0,
                "chlorophyll_absorption": AE_SPEC})
    assert e.field == "chlorophyll" and "> 0" in e.message
    e = errors({"model": "mixture", "components": [{"model": "cdom", "a_ref": 0.1},
                                                   {**case1, "chlorophyll": -2}]},
               obj="water 'sea'", prefix="iop_model.")
    assert (e.obj, e.field) == ("water 'sea'", "iop_model.components[1].chlorophyll")
    assert str(e).startswith("water 'sea': field 'iop_model.components[1].chlorophyll'")
    e = errors({"model": "case2"})
    assert e.field == "model" and "case2" in e.message
    e = errors({"water": "pope_fry"})
    assert e.field == "model" and "required" in e.message
    e = errors({**case1, "chlorophyl": 1.0})
    assert e.field == "chlorophyl" and "unknown field" in e.message
    e = errors({"model": "case1", "chlorophyll": 1.0})
    assert e.field == "chlorophyll_absorption" and "bundled" in e.message
    e = errors({**case1, "variant": "new"})  # a classic table for the new model
    assert e.field == "chlorophyll_absorption.a_star"
    e = errors({**case1, "particle_phase": {"type": "fournier_forand",
                                            "backscatter_fraction": "morel_maritorena_2001"}})
    assert e.field == "particle_phase.backscatter_fraction"
    e = errors({"model": "particles", "b_ref": 1, "backscatter_fraction": 0.5})
    assert e.field == "backscatter_fraction"
    e = errors({"model": "cdom", "a_ref": 0.1, "slope": "steep"})
    assert e.field == "slope"
    e = errors({"model": "mixture", "components": [{"model": "cdom", "a_ref": 0.1,
                                                    "water": "pope_fry"}]})
    assert e.field == "components[0].water"
    e = errors({"model": "pure_water", "water": "segelstein"})
    assert e.field == "water"
    # the new model's particle backscatter fraction follows the chlorophyll: far outside the
    # fit it leaves the Fournier-Forand range, which is the chlorophyll's problem, not the table's
    for chl, fraction in ((1e-300, "0.7567"), (1e4, "-0.003")):
        e = errors({**case1, "variant": "new", "chlorophyll": chl, "chlorophyll_absorption": AE_SPEC})
        assert e.field == "chlorophyll" and f"b_bp/b_p of {fraction}" in e.message and "band 0" in e.message
    m.iops_from_model({**case1, "variant": "new", "chlorophyll": 1e-40, "chlorophyll_absorption": AE_SPEC}, RGB)


def test_bands_outside_a_table_are_refused():
    uv = [Band("blue", 450.0, 10.0), Band("uv", 370.0, 10.0)]
    e = errors({"model": "pure_water"}, uv)
    assert e.field == "water" and "band 1 'uv' (370 +- 5 nm)" in e.message
    assert "Pope & Fry" in e.message
    # Smith & Baker reaches 200 nm; a band straddling 380 nm is not silently clipped
    assert m.iops_from_model({"model": "pure_water", "water": "smith_baker"}, uv).absorption[1] > 0
    e = errors({"model": "pure_water"}, [(726.0, 4.0)])
    assert "band 0 (726 +- 2 nm)" in e.message
    with pytest.raises(ValueError, match="band 0 .*Smith & Baker"):
        m.pure_water_absorption([(805.0, 0.0)], "smith_baker")
    case1 = {"model": "case1", "chlorophyll": 1.0, "chlorophyll_absorption": ASTAR_SPEC,
             "water": "none"}
    e = errors(case1, [Band("deep red", 710.0, 20.0)])
    assert e.field == "chlorophyll_absorption" and "band 0 'deep red'" in e.message


def test_bad_tables_are_refused(tmp_path):
    with pytest.raises(ValueError, match="strictly increasing"):
        m.SpectralTable("t", [440.0, 400.0], a_star=[1.0, 1.0])
    case1 = {"model": "case1", "chlorophyll": 1.0}
    e = errors({**case1, "chlorophyll_absorption": {"file": "missing.csv"}}, base_dir=tmp_path)
    assert e.field == "chlorophyll_absorption.file" and "missing.csv" in e.message
    e = errors({**case1, "chlorophyll_absorption": {"wavelength_nm": [400, 430], "a_star": [1, 1]}})
    assert e.field == "chlorophyll_absorption" and "440" in e.message


def test_scene_files_take_an_iop_model():
    """A water body's 'iop_model' becomes per-band IOPs when the scene is read; errors name the
    water body and the model's field."""
    from photic.scene import Scene, SceneError
    d = {"photic_scene": 1, "name": "m",
         "bands": [{"name": "450", "center_nm": 450, "width_nm": 10},
                   {"name": "550", "center_nm": 550, "width_nm": 10}],
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat"},
                    "iop_model": {"model": "mixture", "components": [
                        {"model": "cdom", "a_ref": 0.1},
                        {"model": "particles", "b_ref": 0.3}]}}],
         "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [0, 0, -1]}]}
    scene = Scene.from_dict(d)
    iops = scene.water[0].iops
    assert iops.absorption[0] > iops.absorption[1] > 0.0565  # CDOM falls with wavelength; + water
    assert [c.phase.type for c in iops.scattering][0] == "pure_water"
    again = Scene.from_dict(scene.to_dict())  # written back as the resulting IOPs
    np.testing.assert_array_equal(again.water[0].iops.absorption, iops.absorption)
    d["water"][0]["iop_model"]["components"][0]["a_ref"] = -1.0
    with pytest.raises(SceneError, match=r"water 'sea'.*iop_model\.components\[0\]\.a_ref"):
        Scene.from_dict(d)
