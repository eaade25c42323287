"""A target relative error per radiometer (settings.target_error, --target-error).

An adaptive render runs rounds with their own seeds and stops each radiometer when its worst
relative standard error is at most the target and can be trusted. Stopping on the estimated
error must not bias the means or make the errors dishonest: over 16 seeds the spread of the
means is compared with the median reported error (as in test_error_bars.py), and the mean of
the means with a fixed-count render's, by z-score.
"""
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from photic.cli import main
from photic.render import FIRST_ROUND, next_round_samples, render, worst_relative_error
from photic.scene import Scene, SceneError, save_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from se_calibration import scene as calibration_scene  # noqa: E402

SEEDS = range(1, 17)


def _runs(surface, zenith, target, max_samples=1 << 20):
    """Per radiometer over SEEDS: adaptive means, their errors and sample counts, and the means
    of fixed renders of FIRST_ROUND samples with the same seeds (the adaptive renders' first
    rounds, bit for bit)."""
    runs = {}
    for seed in SEEDS:
        sc = calibration_scene(surface, zenith, 3.0, seed, False)
        res = render(sc, radiometer_samples=max_samples, threads=2, target_error=target)
        first = render(sc, radiometer_samples=FIRST_ROUND, threads=2)
        assert res.stats["target_reached"] == len(res.radiometers)
        for r, f in zip(res.radiometers, first.radiometers):
            assert r.target_reached and r.relative_error <= target, (r.name, r.relative_error)
            d = runs.setdefault(r.name, {"mean": [], "se": [], "n": [], "first": []})
            d["mean"].append(float(r.mean[0, 0]))
            d["se"].append(float(r.stderr[0, 0]))
            d["n"].append(r.samples)
            d["first"].append(float(f.mean[0, 0]))
    return {k: {q: np.array(v) for q, v in d.items()} for k, d in runs.items()}


@pytest.mark.parametrize("surface, zenith, target", [
    ("flat", 80.0, 0.01),
    pytest.param("waves", 30.0, 0.02, marks=pytest.mark.slow),     # about 2 minutes
])
def test_adaptive_errors_are_honest_and_unbiased(surface, zenith, target, zscore):
    """Flat sea under an 80 deg sun (the hard case of the paired strata) and a wavy sea: every
    radiometer reaches its target, its error stays honest (spread / median SE in 0.6-1.6, the
    band of 16 seeds), and stopping adds no bias: the adaptive mean minus its own first round
    (the same samples a fixed render of that size gives) averages zero over the seeds, and
    the mean over seeds agrees with a long fixed-count render."""
    runs = _runs(surface, zenith, target)
    ref = render(calibration_scene(surface, zenith, 3.0, 99, False), radiometer_samples=1 << 17,
                 threads=2)
    for r in ref.radiometers:
        d = runs[r.name]
        ratio = d["mean"].std(ddof=1) / np.median(d["se"])
        assert 0.6 <= ratio <= 1.6, (r.name, ratio)
        diff = d["mean"] - d["first"]
        if np.any(diff != 0):
            z = zscore(f"{surface} {zenith:g}: {r.name} adaptive - first round", float(diff.mean()),
                       0.0, float(diff.std(ddof=1) / np.sqrt(len(diff))))
            assert abs(z) < 3.5, (r.name, z)
        grand_se = float(np.sqrt(np.mean(d["se"] ** 2) / len(d["se"])))
        z = zscore(f"{surface} {zenith:g}: {r.name} mean of seeds", float(d["mean"].mean()),
                   float(r.mean[0, 0]), float(np.hypot(grand_se, r.stderr[0, 0])))
        assert abs(z) < 4.5, (r.name, z)
        # most seeds stop within a few rounds; a seed whose samples show heavy tails keeps
        # doubling (its error cannot be trusted) and may run to the maximum
        assert np.median(d["n"]) < 1 << 15, (r.name, d["n"])
    if surface == "flat":
        # the dim deep radiometers need more samples than the bright shallow ones
        assert np.median(runs["Eo_5"]["n"]) > np.median(runs["Ed_1"]["n"]), runs


def test_unreachable_target_takes_the_maximum_and_says_so(tmp_path):
    sc = calibration_scene("flat", 30.0, 3.0, 1, False)
    res = render(sc, radiometer_samples=6000, threads=2, target_error=1e-4)
    assert res.stats["target_reached"] == 0
    for r in res.radiometers:
        assert r.samples == 6000 and not r.target_reached and r.relative_error > 1e-4
    # a plain render of the maximum equals the adaptive one's first round only when that
    # round is all of it: with no target the counts are the scene's, bit for bit as before
    a = render(sc, radiometer_samples=4096, threads=2)
    b = render(sc, radiometer_samples=4096, threads=2, target_error=1e-4)
    for ra, rb in zip(a.radiometers, b.radiometers):
        assert np.array_equal(ra.mean, rb.mean) and np.array_equal(ra.stderr, rb.stderr)
        assert ra.target_error is None and rb.target_error == 1e-4


def test_target_error_with_several_band_groups():
    """More bands than one core pass holds: each band group runs its own rounds (the worst
    band of the group decides), the result covers every band, and the slow band (strong
    absorption: a dim deep Ed) takes more samples."""
    from photic.compile import MAX_BANDS
    nb = MAX_BANDS + 2
    a = [0.05] * (nb - 1) + [0.8]
    d = {"photic_scene": 1, "name": "groups",
         "bands": [{"name": f"b{i}", "center_nm": 400.0 + 10 * i, "width_nm": 10.0} for i in range(nb)],
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.3] * nb}},
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0},
                    "bottom": {"depth": 6.0, "material": "sand"},
                    "iops": {"absorption": a, "b": [0.2] * nb, "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": 30.0, "azimuth_deg": 0.0, "irradiance": [1.0] * nb},
         "sky": {"type": "black"},
         "radiometers": [{"name": "Ed_4", "quantity": "Ed", "position": [0, 0, -4.0]}],
         "settings": {"integrator": "hybrid", "forward_cone_deg": 3.0, "target_error": 0.01,
                      "radiometer_samples": 1 << 18}}
    res = render(Scene.from_dict(d), threads=2)
    r = res.radiometers[0]
    assert r.target_reached and r.relative_error <= 0.01
    assert np.all(r.stderr[0] / r.mean[0] <= 0.01) and np.all(r.reliable)
    fixed = render(Scene.from_dict(d), threads=2, target_error=None, radiometer_samples=1 << 16)
    z = (r.mean[0] - fixed.radiometers[0].mean[0]) / np.hypot(r.stderr[0], fixed.radiometers[0].stderr[0])
    assert np.all(np.abs(z) < 4.5), z


def test_bad_target_errors_name_the_field():
    for bad in (0, 1, 1.5, -0.01, float("nan"), float("inf"), "1%"):
        sc = calibration_scene("flat", 30.0, 3.0, 1, False)
        sc.settings.target_error = bad
        with pytest.raises(SceneError, match="target_error"):
            render(sc, radiometer_samples=1024)
    d = calibration_scene("flat", 30.0, 3.0, 1, False).to_dict()
    d["settings"]["target_error"] = 2
    with pytest.raises(SceneError, match="target_error"):
        Scene.from_dict(d).validate()


def test_target_error_in_the_file_and_on_the_command_line(tmp_path, capsys):
    sc = calibration_scene("flat", 30.0, 3.0, 1, False)
    sc.settings.target_error = 0.02
    path = tmp_path / "s.json"
    save_scene(sc, path)
    assert json.loads(path.read_text())["settings"]["target_error"] == 0.02
    assert main(["render", str(path), "--radiometer-samples", "200000", "--quiet",
                 "--out", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "target error 2 %: reached by 4 of 4 radiometers" in out
    assert main(["render", str(path), "--target-error", "1.5%", "--radiometer-samples", "200000",
                 "--quiet", "--out", str(tmp_path / "b")]) == 0
    assert "target error 1.5 %" in capsys.readouterr().out
    doc = json.loads((tmp_path / "b" / "se_calibration_radiometers.json").read_text())
    for r in doc["radiometers"]:
        assert r["target_error"] == 0.015 and r["target_reached"] and r["relative_error"] <= 0.015
    with pytest.raises(SystemExit):
        main(["render", str(path), "--target-error", "150%"])
    assert "--target-error" in capsys.readouterr().err


def test_round_sizes_and_worst_error():
    assert next_round_samples(4096, 0.02, 0.01, True, 10**6) == int(np.ceil(4096 * 3 * 1.1))
    assert next_round_samples(4096, 0.009, 0.01, True, 10**6) == 0
    assert next_round_samples(4096, 0.005, 0.01, False, 10**6) == 4096    # untrusted: double
    assert next_round_samples(4096, 0.02, 0.01, True, 100) == 100           # capped
    assert next_round_samples(4096, 0.0101, 0.01, True, 10**6) == 1024      # at least MIN_ROUND
    m = np.array([[1.0, 0.0, 2.0]])
    assert worst_relative_error(m, np.array([[0.01, 0.0, 0.01]])) == pytest.approx(0.01)
    assert worst_relative_error(m, np.array([[0.01, 0.1, 0.01]])) == np.inf
    assert worst_relative_error(np.zeros((1, 2)), np.zeros((1, 2))) == 0.0


def test_per_radiometer_targets():
    """``radiometer_targets``: each named radiometer stops at its own target; one without a
    target takes all its samples; the others' rounds do not drag a quick one along."""
    sc = calibration_scene("flat", 30.0, 3.0, 1, False)
    res = render(sc, radiometer_samples=100_000, threads=2,
                 radiometer_targets={"Ed_1": 0.001, "Eo_5": 0.05})
    r = {x.name: x for x in res.radiometers}
    assert r["Ed_1"].target_reached and r["Ed_1"].relative_error <= 0.001
    assert r["Eo_5"].target_reached and r["Eo_5"].samples == FIRST_ROUND
    assert r["Ed_1"].samples > FIRST_ROUND
    for name in ("Eo_1", "Ed_5"):
        assert r[name].samples == 100_000 and r[name].target_error is None
    with pytest.raises(SceneError, match="Ed_9"):
        render(sc, radiometer_samples=1024, radiometer_targets={"Ed_9": 0.01})
    with pytest.raises(SceneError, match="Ed_1"):
        render(sc, radiometer_samples=1024, radiometer_targets={"Ed_1": 0.0})


def test_problems_stop_at_a_third_of_their_band():
    """``photic problems``: each radiometer's target is a third of its pass band; it stops
    there (or at the file's count) and passes."""
    from photic.problems import band_targets, reference_table, run_problem
    from photic.scene import load_scene
    refs = reference_table()
    scene = load_scene(Path(__file__).resolve().parents[1] / "examples" / "problems"
                       / "mobley1993_problem1_omega0.2.json")
    records = run_problem(scene, 1, 0.2, refs, samples=200_000, threads=2)
    targets = band_targets(1, 0.2, refs)
    for rec in records:
        name = f"{rec['quantity']}_tau{rec['tau']:g}"
        assert rec["target_error"] == pytest.approx(targets[name])
        assert rec["passed"], rec
        assert rec["stderr"] <= rec["target_error"] * abs(rec["value"]) or rec["samples"] == 200_000
    assert min(r["samples"] for r in records) < 200_000
