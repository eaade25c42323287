"""``photic bench --error --cases examples``: the errors it reports, and a small run."""
import math

import numpy as np

from photic.bench_examples import example_scenes, image_errors, run_examples_bench


def test_image_errors_remove_the_reference_noise_and_read_the_error_bars():
    """Synthetic renders of a known image: the error with the reference's noise removed is the
    render's own noise, and what it reports of itself is the same."""
    rng = np.random.default_rng(5)
    truth = rng.uniform(0.5, 1.5, size=(200, 300, 1))
    sigma, sigma_ref = 0.08, 0.03
    ref = truth + rng.normal(0.0, sigma_ref, truth.shape)
    x = truth + rng.normal(0.0, sigma, truth.shape)
    e = image_errors(x, np.full(truth.shape, sigma ** 2), ref, np.full(truth.shape, sigma_ref ** 2))
    m = float(ref.mean())
    assert math.isclose(e["rms"], sigma / m, rel_tol=0.02)
    assert math.isclose(e["reported"], sigma / m, rel_tol=1e-9)
    assert math.isclose(e["rms_raw"], math.hypot(sigma, sigma_ref) / m, rel_tol=0.02)
    assert math.isclose(e["median_pixel"], float(np.median(sigma / ref)), rel_tol=1e-9)
    assert math.isclose(e["top_0.1"], 0.001, rel_tol=0.05)  # no fireflies: 0.1 % of pixels, 0.1 %
    # one firefly pixel holding most of the variance
    var = np.full(truth.shape, sigma ** 2)
    var[7, 9] = 1e4 * sigma ** 2 * truth.size
    assert image_errors(x, var, ref, np.full(truth.shape, sigma_ref ** 2))["top_0.1"] > 0.99


def test_examples_bench_measures_every_json_example(tmp_path):
    names = [e.name for e in example_scenes(16, blends=False)]
    assert "stepped_pool.json" in names and "coastal_shelf.json" in names
    records = run_examples_bench(width=16, ref_spp=8, budgets=(2, 4), seeds=3, seed_spp=2, blends=False,
                                 names=["stepped_pool.json"], plot=tmp_path / "examples.png", print_table=False)
    (r,) = records
    assert r["scene"] == "stepped_pool.json" and r["resolution"][0] == 16
    assert [b["spp"] for b in r["budgets"]] == [2, 4]
    for b in r["budgets"]:
        assert b["seconds"] > 0 and all(math.isfinite(b[k]) for k in ("rms", "median_pixel", "top_0.1"))
    assert len(r["seed_errors"]) == 3 and math.isfinite(r["error_bar_ratio"]) and r["error_bar_ratio"] > 0
    assert r["time_to_5pct_rms"]["seconds"] is not None
    assert (tmp_path / "examples.png").stat().st_size > 0


def test_examples_bench_refuses_single_sample_renders():
    import pytest
    with pytest.raises(ValueError, match="at least 2 samples"):
        run_examples_bench(budgets=(1, 2), blends=False, plot=None, print_table=False)
