"""Derived quantities (photic.derived, ``photic derive``): exact values on constructed
radiometers, first-order errors against a Monte Carlo of the inputs, and Kd of a real render."""
import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from photic.derived import (DerivedError, Reading, attenuation, attenuation_fit, derive, irradiance_reflectance,
                            load_table, mean_cosine, mean_cosine_down, mean_cosine_up,
                            remote_sensing_reflectance)
from photic.output import write_radiometer_tables
from photic.render import RadiometerResult, RenderResult, render
from photic.scene import Band, Scene

BANDS = [Band("450", 450.0, 10.0), Band("550", 550.0, 10.0)]


def rr(name, q, z, value, stderr=None, x=0.0, y=0.0, medium="sea"):
    value = np.atleast_1d(np.asarray(value, float))
    stderr = 0.01 * value if stderr is None else np.broadcast_to(np.asarray(stderr, float), value.shape)
    return RadiometerResult(name, q, np.array([x, y, z]), medium, value[None, :].copy(),
                            np.array(stderr, float)[None, :].copy(), 10000)


def result(*rads):
    return RenderResult("synthetic", list(BANDS), radiometers=list(rads))


def by_name(derived):
    return {d.name: d for d in derived}


K_D, K_U = np.array([0.12, 0.5]), np.array([0.2, 0.03])
DEPTHS = [0.5, 1.0, 2.0, 4.0]


def profile_result():
    """Exponential Ed and Eu profiles (an array) under an air Ed and a nadir radiance."""
    rads = []
    for i, d in enumerate(DEPTHS):
        rads += [rr(f"prof[{i}].Ed", "Ed", -d, 2.0 * np.exp(-K_D * d)),
                 rr(f"prof[{i}].Eu", "Eu", -d, 0.1 * np.exp(-K_U * d))]
    rads += [rr("Ed_air", "Ed", 0.1, [2.5, 2.0], medium="air"), rr("Lu_air", "radiance", 0.5, [0.01, 0.02], medium="air")]
    return result(*rads)


def test_k_of_an_exponential_profile_is_exact():
    out = by_name(derive(profile_result()))
    for q, k in (("Ed", K_D), ("Eu", K_U)):
        kname = {"Ed": "Kd", "Eu": "Ku"}[q]
        for i in range(len(DEPTHS) - 1):
            d = out[f"{kname}(prof[{i}].{q}, prof[{i + 1}].{q})"]
            assert d.quantity == kname and d.units == "m^-1" and d.medium == "sea"
            assert d.depths == (DEPTHS[i], DEPTHS[i + 1])
            assert d.sources == (f"prof[{i}].{q}", f"prof[{i + 1}].{q}")
            np.testing.assert_allclose(d.value, k, rtol=1e-12)
            # 1 % relative errors at both depths
            np.testing.assert_allclose(d.stderr, np.sqrt(2) * 0.01 / (DEPTHS[i + 1] - DEPTHS[i]), rtol=1e-12)
        fit = out[f"{kname}_fit(prof[0].{q} .. prof[3].{q}, 4 depths)"]
        np.testing.assert_allclose(fit.value, k, rtol=1e-12)
        assert fit.depths == (DEPTHS[0], DEPTHS[-1]) and len(fit.sources) == 4
        # equal weights: var = s^2 / sum (d - mean d)^2
        np.testing.assert_allclose(fit.stderr, 0.01 / np.sqrt(np.sum((np.array(DEPTHS) - np.mean(DEPTHS)) ** 2)),
                                   rtol=1e-12)
        np.testing.assert_allclose(fit.extra["chi2_dof"], 0.0, atol=1e-20)
    # Nothing is attenuated in air, and the order of the arguments does not matter.
    assert not any(d.quantity.startswith("K") and d.medium == "air" for d in out.values())
    t = load_table(profile_result())
    a, b = t.reading("prof[2].Ed"), t.reading("prof[0].Ed")
    np.testing.assert_allclose(attenuation(a, b).value, K_D, rtol=1e-12)


def test_r_mean_cosines_and_rrs_are_exact():
    ed, eu, eod, eou, eo = np.array([2.0, 1.0]), np.array([0.1, 0.02]), np.array([2.5, 1.6]), \
        np.array([0.4, 0.05]), np.array([2.9, 1.65])
    res = result(rr("Ed", "Ed", -1, ed), rr("Eu", "Eu", -1, eu), rr("Eod", "Eod", -1, eod), rr("Eou", "Eou", -1, eou),
                 rr("Eo", "Eo", -1, eo),
                 # a second station without Eo: mu from Eod + Eou
                 rr("Ed2", "Ed", -1, ed, x=5), rr("Eu2", "Eu", -1, eu, x=5), rr("Eod2", "Eod", -1, eod, x=5),
                 rr("Eou2", "Eou", -1, eou, x=5),
                 rr("Ed_air", "Ed", 0.2, [3.0, 2.0], medium="air"), rr("Lu", "radiance", 1.0, [0.015, 0.02], medium="air"),
                 rr("Lsky", "radiance", 1.0, [0.1, 0.2], medium="air", x=50))
    out = derive(res)
    got = {(d.quantity, d.sources): d for d in out}
    np.testing.assert_allclose(got["R", ("Eu", "Ed")].value, eu / ed, rtol=1e-14)
    np.testing.assert_allclose(got["mu_d", ("Ed", "Eod")].value, ed / eod, rtol=1e-14)
    np.testing.assert_allclose(got["mu_u", ("Eu", "Eou")].value, eu / eou, rtol=1e-14)
    np.testing.assert_allclose(got["mu", ("Ed", "Eu", "Eo")].value, (ed - eu) / eo, rtol=1e-14)
    np.testing.assert_allclose(got["mu", ("Ed2", "Eu2", "Eod2", "Eou2")].value, (ed - eu) / (eod + eou), rtol=1e-14)
    assert ("mu", ("Ed", "Eu", "Eod", "Eou")) not in got  # an Eo radiometer is preferred
    assert got["R", ("Eu", "Ed")].units.startswith("1")
    # Rrs: matched by position (Lsky has no Ed at its x, y), reported as uncorrected.
    rrs = [d for d in out if d.quantity.startswith("Rrs")]
    assert len(rrs) == 1 and rrs[0].quantity == "Rrs_uncorrected" and rrs[0].units == "sr^-1"
    np.testing.assert_allclose(rrs[0].value, [0.005, 0.01], rtol=1e-14)
    # Explicit: Lw = Lu - rho Lsky, or Lu - a reflected-radiance radiometer.
    rho = 0.028
    out = derive(res, rrs=[{"lu": "Lu", "ed": "Ed_air", "sky": "Lsky", "rho": rho}])
    rrs = [d for d in out if d.quantity.startswith("Rrs")]
    assert len(rrs) == 1 and rrs[0].quantity == "Rrs" and rrs[0].sources == ("Lu", "Ed_air", "Lsky")
    np.testing.assert_allclose(rrs[0].value, (np.array([0.015, 0.02]) - rho * np.array([0.1, 0.2])) / [3.0, 2.0],
                               rtol=1e-14)
    t = load_table(res)
    d = remote_sensing_reflectance("Lu", "Ed_air", reflected="Lsky", table=t)
    np.testing.assert_allclose(d.value, (np.array([0.015, 0.02]) - [0.1, 0.2]) / [3.0, 2.0], rtol=1e-14)
    with pytest.raises(DerivedError, match="not above the water"):
        remote_sensing_reflectance("Lu", "Ed", table=t)
    with pytest.raises(DerivedError, match="rho"):
        remote_sensing_reflectance("Lu", "Ed_air", sky="Lsky", table=t)
    with pytest.raises(DerivedError, match="expected Ed"):
        irradiance_reflectance("Eu", "Eod", table=t)
    with pytest.raises(DerivedError, match="no radiometer named"):
        t.reading("nope")


def _draw(r: Reading, n, rng):
    """n independent draws of a radiometer as n 'bands'."""
    return Reading(r.name, r.quantity, r.position, r.medium,
                   rng.normal(r.value[0], r.stderr[0], n), np.full(n, r.stderr[0]), r.units)


def test_first_order_errors_match_a_monte_carlo_of_the_inputs():
    """Draw every input from a normal distribution with its standard error; the spread of the
    output agrees with the propagated standard error within 10 %."""
    rng = np.random.default_rng(7)
    n = 20000

    def one(value, rel, q, z=-1.0, medium="sea", name=None):
        return Reading(name or q, q, np.array([0.0, 0.0, z]), medium, np.array([value]), np.array([rel * value]))

    ed1, ed2 = one(1.5, 0.02, "Ed", -1.0, name="Ed1"), one(0.6, 0.03, "Ed", -3.0, name="Ed2")
    eu, eod, eou, eo = one(0.08, 0.03, "Eu"), one(1.9, 0.02, "Eod"), one(0.3, 0.04, "Eou"), one(2.2, 0.02, "Eo")
    lu, eda, sky = one(0.012, 0.02, "radiance", 1, "air"), one(2.0, 0.01, "Ed", 0.5, "air"), \
        one(0.09, 0.05, "radiance", 1, "air")
    prof = [one(2.0 * np.exp(-0.3 * d), 0.01 + 0.01 * i, "Ed", -d, name=f"p{i}") for i, d in enumerate([1, 2, 3, 5])]
    cases = {
        "Kd": (lambda *r: attenuation(*r), [ed1, ed2]),
        "Kd_fit": (lambda *r: attenuation_fit(list(r)), prof),
        "R": (lambda *r: irradiance_reflectance(*r), [eu, ed1]),
        "mu_d": (lambda *r: mean_cosine_down(*r), [ed1, eod]),
        "mu_u": (lambda *r: mean_cosine_up(*r), [eu, eou]),
        "mu": (lambda d, u, o: mean_cosine(d, u, eo=o), [ed1, eu, eo]),
        "mu (Eod + Eou)": (lambda d, u, od, ou: mean_cosine(d, u, eod=od, eou=ou), [ed1, eu, eod, eou]),
        "Rrs": (lambda u, d, s: remote_sensing_reflectance(u, d, sky=s, rho=0.05), [lu, eda, sky]),
    }
    for label, (f, inputs) in cases.items():
        nominal = f(*inputs)
        m = 4000 if label == "Kd_fit" else n  # the fit loops over draws
        drawn = f(*[_draw(r, m, rng) for r in inputs])
        spread = np.std(drawn.value, ddof=1)
        assert abs(spread / nominal.stderr[0] - 1) < 0.1, (label, spread, nominal.stderr[0])


def test_json_table_gives_the_same_values_as_the_result(tmp_path):
    res = profile_result()
    res.radiometers.append(RadiometerResult("dist", "radiance_distribution", np.zeros(3), "sea",
                                            np.ones((4, 2)), np.ones((4, 2)), 100, (2, 2)))
    _, json_path = write_radiometer_tables(tmp_path, res)
    a, b = derive(res), derive(json_path)
    assert [d.name for d in a] == [d.name for d in b] and len(a) == 3 * 2 + 2 + 4 + 1
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.value, y.value)
        np.testing.assert_array_equal(x.stderr, y.stderr)
    assert load_table(json_path).bands == [("450", 450.0), ("550", 550.0)]
    with pytest.raises(DerivedError, match="not a Photic radiometer table"):
        load_table({"images": []})


def sunlit_sea(a, seed, samples, diameter=0.53):
    d = {"photic_scene": 1, "name": "beer", "bands": [{"name": "b1", "center_nm": 450, "width_nm": 10},
                                                      {"name": "b2", "center_nm": 550, "width_nm": 10}],
         "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": {"kind": "flat", "z": 0.0},
                    "iops": {"absorption": list(a), "scattering": [{"b": [0.0, 0.0], "phase": {"type": "petzold"}}]}}],
         "sky": {"type": "black"},
         "sun": {"zenith_deg": 0.0, "azimuth_deg": 0.0, "irradiance": [1.0, 2.0], "angular_diameter_deg": diameter},
         "radiometer_arrays": [{"name": "prof", "quantities": ["Ed", "Eod"], "positions": [[0, 0, -1.0], [0, 0, -3.0]]}],
         "settings": {"seed": seed, "radiometer_samples": samples, "integrator": "hybrid", "threads": 2}}
    return Scene.from_dict(d)


def test_kd_of_a_sunlit_non_scattering_sea_is_the_absorption_coefficient(zscore):
    """Flat sea, b = 0, black sky, sun at the zenith: Ed(z) is the refracted direct beam, so
    Kd = a <1 / mu_w> over the sun's disk (refracted into the water) = a (1 + 3.0e-6), and
    mu_d = Ed / Eod = <mu_w> = 1 - 3.0e-6.

    The direct beam is constant within a pass (one sun direction per pass), so the engine's
    per-sample standard error of a flat-sea hybrid radiometer understates the spread between
    seeds (about 5x at 49 passes); the error here is the larger of the propagated one and the
    standard error of the mean over independent seeds."""
    a = np.array([0.3, 0.1])
    alpha = np.radians(0.53) / 2
    mu = np.linspace(np.cos(alpha), 1.0, 20001)                    # uniform in solid angle
    mu_w = np.cos(np.arcsin(np.sin(np.arccos(mu)) / 1.34))
    kd_ref, mud_ref = a * np.mean(1 / mu_w), np.mean(mu_w)
    kd, kd_se, mud, mud_se = [], [], [], []
    for seed in range(6):
        out = {d.quantity: d for d in derive(render(sunlit_sea(a, seed, 32768))) if d.quantity in ("Kd", "mu_d")
               and d.sources[0] == "prof[0].Ed"}
        kd.append(out["Kd"].value); kd_se.append(out["Kd"].stderr)
        mud.append(out["mu_d"].value); mud_se.append(out["mu_d"].stderr)
        assert out["Kd"].sources == ("prof[0].Ed", "prof[1].Ed")
    for label, v, se, ref in (("Kd", kd, kd_se, kd_ref), ("mu_d", mud, mud_se, np.full(2, mud_ref))):
        v, se = np.array(v), np.array(se)
        mean = v.mean(0)
        err = np.maximum(np.sqrt((se ** 2).sum(0)) / len(v), v.std(0, ddof=1) / np.sqrt(len(v)))
        for k in range(2):
            assert abs(zscore(f"{label} Beer-Lambert band {k}", mean[k], ref[k], err[k])) < 3
    np.testing.assert_allclose(np.mean(kd, 0), a, rtol=1e-5)  # Beer-Lambert: Kd = a


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "photic", *map(str, args)], capture_output=True, text=True)


def test_cli_derive_prints_a_table_and_writes_csv(tmp_path):
    _, json_path = write_radiometer_tables(tmp_path, profile_result())
    p = run_cli("derive", json_path)
    assert p.returncode == 0, p.stderr
    assert "Kd(prof[0].Ed, prof[1].Ed)" in p.stdout and "+-" in p.stdout and "m^-1" in p.stdout
    assert "Rrs_uncorrected" in p.stdout
    csv_path = tmp_path / "synthetic_radiometers_derived.csv"
    assert str(csv_path) in p.stdout
    rows = list(csv.DictReader(line for line in open(csv_path) if not line.startswith("#")))
    kd = [r for r in rows if r["name"] == "Kd(prof[0].Ed, prof[1].Ed)"]
    assert [r["band"] for r in kd] == ["450", "550"]
    np.testing.assert_allclose([float(r["value"]) for r in kd], K_D, rtol=1e-12)
    assert kd[0]["depth_top_m"] == "0.5" and kd[0]["sources"] == "prof[0].Ed;prof[1].Ed"

    out = tmp_path / "derived"
    p = run_cli("derive", json_path, "--json", "--out", out, "--rrs", "Lu_air", "Ed_air", "--sky", "Lu_air",
                "--rho", "0.5", "--no-fit")
    assert p.returncode == 0, p.stderr
    records = json.loads(p.stdout)
    rrs = [r for r in records if r["quantity"].startswith("Rrs")]
    assert [r["quantity"] for r in rrs] == ["Rrs", "Rrs"]
    np.testing.assert_allclose([r["value"] for r in rrs], [0.5 * 0.01 / 2.5, 0.5 * 0.02 / 2.0], rtol=1e-12)
    assert not any(r["quantity"].endswith("_fit") for r in records)
    assert (out / "synthetic_radiometers_derived.csv").is_file()

    for bad in (["derive", tmp_path / "missing.json"], ["derive", json_path, "--rrs", "Lu_air", "nope"],
                ["derive", json_path, "--rho", "0.1"]):
        p = run_cli(*bad)
        assert p.returncode == 2 and "Traceback" not in p.stderr and "photic derive:" in p.stderr
