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


def test_hybrid_refuses_rough_surfaces_and_auto_chooses_path():
    scene = sea_scene(30.0, 5.0, integrator="hybrid")
    with pytest.raises(SceneError, match="roughness of water 'sea'"):
        Renderer(scene)
    scene.settings.integrator = "auto"
    assert Renderer(scene).integrator == "path"


def test_rough_surface_round_trips_through_the_scene_format():
    scene = sea_scene(30.0, 5.0)
    again = Scene.from_dict(scene.to_dict())
    assert again.water[0].surface.roughness.wind_speed == 5.0
    bad = scene.to_dict()
    bad["water"][0]["surface"]["roughness"]["wind_speed"] = -1
    with pytest.raises(SceneError, match="roughness.*wind_speed"):
        Scene.from_dict(bad)
