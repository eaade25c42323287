"""Adaptive sampling of pixels (settings.noise_threshold, --noise-threshold).

After ``adaptive_min_samples`` a pixel whose relative standard error is at most the threshold
in every band takes no more passes. Stopping must not bias the image or make its errors
dishonest, and the pixels that stop must be those whose error is small: the reported numbers
are checked against fixed-count renders, by z-score, and against the spread over seeds.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

from photic.cli import main
from photic.render import ADAPTIVE_FLOOR, Renderer, pixels_converged, render
from photic.scene import Scene, SceneError, save_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from se_calibration import scene as calibration_scene  # noqa: E402


def floor_scene(seed=1, bands=1):
    """The calibration scene's camera (24 x 16 pixels of a sandy floor 5 m below, a flat sea,
    sun at 30 deg, forward cone 3 deg), optionally with more bands (same water in each)."""
    sc = calibration_scene("flat", 30.0, 3.0, seed, True)
    if bands > 1:
        d = sc.to_dict()
        d["bands"] = [{"name": f"b{k}", "center_nm": 400.0 + 10 * k, "width_nm": 10.0} for k in range(bands)]
        for w in d["water"]:
            w["iops"]["absorption"] = [0.1] * bands
            w["iops"]["scattering"][0]["b"] = [0.2] * bands
        d["materials"]["sand"]["reflectance"] = [0.3] * bands
        d["sun"]["irradiance"] = [1.0] * bands
        sc = Scene.from_dict(d)
    return sc


def test_pixels_stop_at_the_threshold_and_stay_unbiased(zscore):
    """Threshold 3 %: pixels stop between the minimum and the most samples; every pixel that
    stopped early met the threshold at its last pass (and still does); the adaptive image
    agrees with a fixed render of the largest count pixel by pixel (z-scores of the
    difference: mean ~0, spread ~1) and over the image."""
    sc = floor_scene(1)
    res = render(sc, samples=256, threads=2, noise_threshold=0.03, adaptive_min_samples=16)
    img = res.images["floor"]
    ps = img.pixel_samples
    assert img.noise_threshold == 0.03 and ps.shape == img.mean.shape[:2]
    assert ps.min() >= 16 and ps.max() <= 256 and ps.min() < ps.max(), (ps.min(), ps.max())
    early = ps < 256
    assert early.any() and np.all(img.converged[early])
    assert np.all(pixels_converged(img, 0.03)[early])
    assert res.stats["pixel_samples_mean"]["floor"] == pytest.approx(float(ps.mean()))
    fixed = render(floor_scene(2), samples=256, threads=2).images["floor"]
    z = (img.mean - fixed.mean) / np.sqrt(img.variance + fixed.variance)
    assert abs(float(np.mean(z))) < 4.0 / np.sqrt(z.size) + 0.1, float(np.mean(z))
    assert 0.7 < float(np.std(z)) < 1.3, float(np.std(z))
    m = float(np.mean(img.mean))
    se = float(np.sqrt(np.sum(img.variance))) / img.variance.size
    ref_se = float(np.sqrt(np.sum(fixed.variance))) / fixed.variance.size
    assert abs(zscore("adaptive image mean vs fixed 256 spp", m, float(np.mean(fixed.mean)),
                      float(np.hypot(se, ref_se)))) < 4


def test_adaptive_pixel_errors_are_honest():
    """Over 12 seeds, the pixels' spread of means against their median reported error stays in
    the band of honest errors (stopping on a small estimate must not leave errors too small)."""
    imgs, var = [], []
    for seed in range(1, 13):
        img = render(floor_scene(seed), samples=128, threads=2, noise_threshold=0.04).images["floor"]
        imgs.append(img.mean[..., 0])
        var.append(img.variance[..., 0])
    spread = np.std(imgs, axis=0, ddof=1)
    se = np.median(np.sqrt(var), axis=0)
    ratio = float(np.median(spread / se))
    assert 0.7 <= ratio <= 1.5, ratio


def test_threshold_never_reached_and_the_floor():
    """A threshold no pixel reaches: every pixel takes every sample, as without one (the same
    numbers bit for bit). The floor: a pixel far darker than the image counts as a twentieth of
    the image's mean, so it stops on an absolute error."""
    sc = floor_scene(3)
    a = render(sc, samples=32, threads=2, noise_threshold=1e-6).images["floor"]
    b = render(sc, samples=32, threads=2).images["floor"]
    assert np.all(a.pixel_samples == 32) and not np.any(a.converged)
    assert np.array_equal(a.mean, b.mean) and np.array_equal(a.variance, b.variance)
    dark = b.__class__(b.name, b.mean.copy(), b.variance.copy(), b.samples)
    dark.mean[0, 0, 0] = 0.0
    dark.variance[0, 0, 0] = (0.9 * 0.1 * ADAPTIVE_FLOOR * float(np.mean(dark.mean))) ** 2
    assert pixels_converged(dark, 0.1)[0, 0]
    dark.variance[0, 0, 0] *= 1.5 ** 2
    assert not pixels_converged(dark, 0.1)[0, 0]


def test_adaptive_with_several_band_groups():
    """18 bands (two band groups of the core): the pixels that stop stop in every band, after
    the same passes (samples per pixel decided on the first group)."""
    sc = floor_scene(4, bands=18)
    sc.settings.raman = False  # (Raman light would make the bands differ)
    res = render(sc, samples=64, threads=2, noise_threshold=0.05)
    img = res.images["floor"]
    assert img.mean.shape[-1] == 18 and img.pixel_samples.min() < 64
    # the same water in every band: the bands' values agree (same paths, same passes)
    assert np.allclose(img.mean[..., 0], img.mean[..., 17], rtol=1e-12)


def test_settings_cli_and_exr(tmp_path, capsys):
    """settings.noise_threshold is checked like every relative error; --noise-threshold turns
    it on; the EXR's samples channel holds each pixel's count."""
    import OpenEXR

    bad = floor_scene(1)
    bad.settings.noise_threshold = 1.5
    with pytest.raises(SceneError, match="noise_threshold"):
        bad.validate()
    with pytest.raises(SceneError, match="adaptive_min_samples"):
        Renderer(floor_scene(1), adaptive_min_samples=0)
    sc = floor_scene(5)
    sc.settings.samples = 64
    path = tmp_path / "floor.json"
    save_scene(sc, path)
    again = Scene.from_dict(sc.to_dict())
    assert again.settings.noise_threshold is None
    sc.settings.noise_threshold, sc.settings.adaptive_min_samples = 0.05, 8
    again = Scene.from_dict(sc.to_dict())
    assert (again.settings.noise_threshold, again.settings.adaptive_min_samples) == (0.05, 8)
    assert main(["render", str(path), "--out", str(tmp_path / "out"), "--quiet", "--threads", "2",
                 "--noise-threshold", "5%"]) == 0
    out = capsys.readouterr().out
    assert "noise threshold 5 % reached by" in out, out
    exr = OpenEXR.File(str(tmp_path / "out" / "se_calibration_floor.exr"))
    samples = np.asarray(exr.parts[0].channels["samples"].pixels)
    assert samples.min() < 64 and samples.max() <= 64
    assert float(exr.header()["photic:noise_threshold"]) == pytest.approx(0.05)
