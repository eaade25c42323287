"""Sun glint and sky reflection from the rough sea surface, through the path tracer.

An orthographic camera looking straight down at a rough, flat-mean sea sees, in every pixel,
the sun glint reflectance of Cox & Munk: L = rho E_sun cos(theta_s) / pi with
rho = pi R_F p(slope) / (4 cos(theta_s) cos(theta_v) cos^4(beta)) (photic.surface).
"""
import math

import numpy as np
import pytest

from photic.render import Renderer
from photic.scene import Scene, SceneError
from photic.surface import glint_reflectance

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)


def sea_scene(zenith, wind, camera_dir=(0.0, 0.0, -1.0), sky=None, integrator="path",
              resolution=(32, 32), kind="flat"):
    surface = {"kind": "flat", "z": 0.0, "roughness": {"wind_speed": wind}}
    return Scene.from_dict({
        "photic_scene": 1, "name": "glint",
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": surface,
                   "iops": {"absorption": [30.0], "b": [0.0], "phase": {"type": "isotropic"}}}],
        "sun": {"zenith_deg": zenith, "azimuth_deg": 0.0, "irradiance": [1.0]},
        "sky": sky or {"type": "black"},
        "cameras": [{"name": "down", "type": "orthographic", "position": [0.0, 0.0, 10.0],
                     "direction": list(camera_dir), "up": [0.0, 1.0, 0.0], "ortho_width": 4.0,
                     "resolution": list(resolution)}],
        "settings": {"integrator": integrator, "samples": 16, "seed": 3},
    })


@pytest.mark.parametrize("zenith, wind", [(30.0, 5.0), (20.0, 2.0), (40.0, 10.0)])
def test_glint_seen_from_nadir_matches_cox_munk(zscore, zenith, wind):
    res = Renderer(sea_scene(zenith, wind)).run()
    img = res.images["down"]
    mean = float(img.mean.mean())
    se = float(np.sqrt(img.variance.sum()) / img.variance.size)
    ts = math.radians(zenith)
    expected = float(glint_reflectance(ts, 0.0, math.pi, wind)) * math.cos(ts) / math.pi
    zscore(f"glint L, sun {zenith:g} deg, U {wind:g} m/s (ref: closed form, no G)", mean, expected, se)
    assert abs(mean / expected - 1) < 0.05, (mean, expected)


def test_rough_surface_reflects_the_sky():
    """A uniform sky of radiance L0 over a black sea: looking down, the rough surface reflects
    the sky's radiance times its directional reflectance (about Fresnel at normal incidence,
    0.021), less what the shadowing loses."""
    scene = sea_scene(30.0, 5.0, sky={"type": "uniform", "radiance": [1.0]})
    scene.sun = None
    res = Renderer(scene).run()
    mean = float(res.images["down"].mean.mean())
    r0 = ((1.34 - 1) / 2.34) ** 2
    assert 0.9 * r0 < mean < 1.1 * r0, (mean, r0)


def rough_sea(integrator, kind="flat"):
    """A rough sea (Cox-Munk, 8 m/s; flat-mean, or a JONSWAP wave patch with the sub-pixel
    remainder) in sun and sky, HG water; radiometers Ed, Eo at 1, 3, 6 m and a small underwater
    camera looking up towards the surface."""
    surface = {"kind": "flat", "z": 0.0, "roughness": {"wind_speed": 8.0}}
    if kind == "waves":
        surface = {"kind": "waves", "spectrum": "jonswap", "wind_speed": 8.0, "fetch_m": 20000.0,
                   "patch_size_m": [20.0, 20.0], "resolution": [16, 16], "seed": 2,
                   "roughness": {"wind_speed": 8.0}}
    return Scene.from_dict({
        "photic_scene": 1, "name": "rough",
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34, "surface": surface,
                   "iops": {"absorption": [0.1], "b": [0.2],
                            "phase": {"type": "henyey_greenstein", "g": 0.8}}}],
        "sun": {"zenith_deg": 50.0, "azimuth_deg": 0.0, "irradiance": [1.0]},
        "sky": {"type": "uniform", "radiance": [0.05]},
        "radiometers": [{"name": f"{q}_{z:g}", "quantity": q, "position": [0.0, 0.0, -z]}
                        for z in (1.0, 3.0, 6.0) for q in ("Ed", "Eo")],
        "cameras": [{"name": "cam", "type": "perspective", "position": [0.0, 0.0, -2.0],
                     "direction": [1.0, 0.0, 0.3], "fov_deg": 60.0, "resolution": [24, 16]}],
        "settings": {"integrator": integrator, "samples": 64, "radiometer_samples": 200000,
                     "seed": 4, "forward_cone_deg": 0.0}})


@pytest.mark.parametrize("kind", ["flat", "waves"])
def test_hybrid_and_path_tracing_agree_under_a_rough_sea(zscore, kind):
    """The beams refract through sub-pixel facets (16 stratified facets per build below a flat
    sea, one per build below a wave patch, relative to the exact normals), path tracing samples
    the rough BSDF around the same shading normals and estimates the sun at the surface; in-water
    Ed and Eo at three depths and an underwater image mean agree within 3 combined standard
    errors (the hybrid's from the spread of its passes as well)."""
    hybrid = Renderer(rough_sea("hybrid", kind), radiometer_samples=200_000 if kind == "flat" else 100_000).run()
    path = Renderer(rough_sea("path", kind), radiometer_samples=1_000_000).run()
    for r in hybrid.radiometers:
        p = path.radiometer(r.name)
        se = math.hypot(r.stderr[0, 0], p.stderr[0, 0])
        z = zscore(f"rough {kind} sea {r.name}: hybrid vs path", r.mean[0, 0], p.mean[0, 0], se)
        assert abs(z) < 3, (r.name, r.mean[0, 0], p.mean[0, 0], se)
    ih, ip = hybrid.images["cam"], path.images["cam"]
    se = math.hypot(np.sqrt(ih.variance.sum()), np.sqrt(ip.variance.sum())) / ih.variance.size
    z = zscore(f"rough {kind} sea image: hybrid vs path", ih.mean.mean(), ip.mean.mean(), se)
    assert abs(z) < 3


def test_rough_surface_round_trips_through_the_scene_format():
    scene = sea_scene(30.0, 5.0)
    again = Scene.from_dict(scene.to_dict())
    assert again.water[0].surface.roughness.wind_speed == 5.0
    bad = scene.to_dict()
    bad["water"][0]["surface"]["roughness"]["wind_speed"] = -1
    with pytest.raises(SceneError, match="roughness.*wind_speed"):
        Scene.from_dict(bad)
