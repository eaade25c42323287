"""Numerically hard cases render finite, non-negative, sensible numbers."""
import numpy as np
import pytest

from analytic import sun_disk_planar_irradiance, transmitted_uniform_sky
from photic.render import render
from photic.scene import Scene


def scene(water_iops, sun=None, sky=None, radiometers=(), cameras=(), **kw):
    d = {"photic_scene": 1, "name": "hard",
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0}, "iops": water_iops, **kw}],
         "sky": sky or {"type": "uniform", "radiance": [1.0]},
         "radiometers": list(radiometers), "cameras": list(cameras), "settings": {"seed": 1}}
    if sun:
        d["sun"] = sun
    return Scene.from_dict(d)


def finite_nonneg(res):
    for r in res.radiometers:
        assert np.isfinite(r.mean).all() and (r.mean >= 0).all() and np.isfinite(r.stderr).all()
    for img in res.images.values():
        assert np.isfinite(img.mean).all() and (img.mean >= 0).all()


def test_grazing_sun_above_water(zscore):
    sun = {"zenith_deg": 89.9, "azimuth_deg": 0.0, "irradiance": [1.0]}
    res = render(scene({"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}, sun=sun,
                       radiometers=[{"name": "Ed", "quantity": "Ed", "position": [0, 0, 0.1]},
                                    {"name": "Ed_w", "quantity": "Ed", "position": [0, 0, -0.1]}]),
                 radiometer_samples=20000)
    finite_nonneg(res)
    r = res.radiometer("Ed")
    # The disk straddles the horizon: the part below it does not count, so the sun gives more
    # than E cos(89.9 deg) here (quadrature over the disk).
    ref = sun_disk_planar_irradiance(89.9) + np.pi
    assert sun_disk_planar_irradiance(30.0) == pytest.approx(np.cos(np.radians(30)), rel=1e-5)
    assert abs(zscore("Ed(0+) grazing sun", r.mean[0, 0], ref, r.stderr[0, 0])) < 4


def test_optical_depth_40_and_albedo_near_one():
    """tau = 40 below the surface with omega0 = 0.999: tiny but finite, positive numbers."""
    res = render(scene({"absorption": [0.004], "b": [3.996], "phase": {"type": "henyey_greenstein", "g": 0.9}},
                       radiometers=[{"name": "Ed_deep", "quantity": "Ed", "position": [0, 0, -10.0]},
                                    {"name": "Eu_deep", "quantity": "Eu", "position": [0, 0, -10.0]}]),
                 radiometer_samples=4096)
    finite_nonneg(res)


def test_total_internal_reflection_only_view():
    """Radiance looking up at 60 deg from the vertical under a flat surface is outside Snell's
    window: with b = 0 it sees only total internal reflection of (black) deep water: zero."""
    d = [np.sin(np.radians(60)), 0.0, np.cos(np.radians(60))]
    res = render(scene({"absorption": [0.1], "b": [0.0], "phase": {"type": "isotropic"}},
                       radiometers=[{"name": "L", "quantity": "radiance", "position": [0, 0, -1],
                                     "direction": d, "half_angle_deg": 5.0}]),
                 radiometer_samples=5000)
    assert res.radiometer("L").mean[0, 0] == 0.0


def test_radiometer_just_below_the_surface(zscore):
    res = render(scene({"absorption": [0.2], "b": [0.0], "phase": {"type": "isotropic"}},
                       radiometers=[{"name": "Ed", "quantity": "Ed", "position": [0, 0, -1e-4]}]),
                 radiometer_samples=100_000)
    r = res.radiometer("Ed")
    assert r.medium == "sea"
    assert abs(zscore("Ed(0-)", r.mean[0, 0], transmitted_uniform_sky(1e-4, 0.2), r.stderr[0, 0])) < 4


def test_empty_scene_with_only_a_camera():
    d = {"photic_scene": 1, "sky": {"type": "cardioidal", "irradiance": [1.0]},
         "cameras": [{"name": "c", "type": "orthographic", "position": [0, 0, 0], "direction": [0, 0, 1],
                      "up": [0, 1, 0], "resolution": [4, 3]}]}
    res = render(Scene.from_dict(d), samples=4)
    img = res.images["c"]
    # Looking straight up at a cardioidal sky: L = L0 (1 + 2) with L0 = 3 E / (7 pi).
    assert np.allclose(img.mean, 9 / (7 * np.pi), rtol=1e-3)


def test_cancel_keeps_only_completed_passes():
    sc = scene({"absorption": [0.1], "b": [0.5], "phase": {"type": "petzold"}},
               radiometers=[{"name": "Eo", "quantity": "Eo", "position": [0, 0, -1]}])
    from photic.render import Renderer
    r = Renderer(sc, radiometer_samples=10 * 65536)
    calls = []

    def progress(frac, msg):
        calls.append(frac)
        if len(calls) == 2:
            r.cancel()

    res = r.run(progress)
    assert res.cancelled
    assert res.radiometer("Eo").samples == 2 * 65536
    assert np.isfinite(res.radiometer("Eo").mean).all()
