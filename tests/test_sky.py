"""Sky models: Harrison & Coombes (1988) as a normalised table read by the core."""
import math

import numpy as np
import pytest

from photic.render import Renderer
from photic.scene import Scene, SceneError
from photic.sky import harrison_coombes, horizontal_irradiance, sky_table

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)


def hc_scene(cloud=0.0, zenith=40.0):
    return Scene.from_dict({
        "photic_scene": 1, "name": "sky",
        "sun": {"zenith_deg": zenith, "azimuth_deg": 30.0, "irradiance": [0.0]},
        "sky": {"type": "harrison_coombes", "irradiance": [2.0], "cloud_fraction": cloud},
        "radiometers": [
            {"name": "Ed", "quantity": "Ed", "position": [0.0, 0.0, 1.0]},
            {"name": "L_zenith", "quantity": "radiance", "position": [0.0, 0.0, 1.0],
             "direction": [0.0, 0.0, 1.0], "half_angle_deg": 5.0},
            {"name": "L_sun_side", "quantity": "radiance", "position": [0.0, 0.0, 1.0],
             "direction": [math.sin(math.radians(60)) * math.cos(math.radians(30)),
                           math.sin(math.radians(60)) * math.sin(math.radians(30)),
                           math.cos(math.radians(60))], "half_angle_deg": 5.0}],
        "settings": {"integrator": "path", "radiometer_samples": 400000, "seed": 2}})


def test_table_is_normalised_and_peaks_towards_the_sun():
    table = sky_table(40.0, 30.0, 0.0)
    assert horizontal_irradiance(table) == pytest.approx(math.pi, rel=1e-9)
    # the circumsolar term: brighter near the sun than opposite it at the same zenith angle
    near = harrison_coombes(math.radians(45), math.radians(30), 40.0, 30.0)
    far = harrison_coombes(math.radians(45), math.radians(210), 40.0, 30.0)
    assert near > 3 * far
    # overcast: brighter at the zenith than at the horizon (the 0.43 mu term)
    assert harrison_coombes(0.0, 0.0, 40.0, 30.0, 1.0) > harrison_coombes(math.radians(85), 2.0, 40.0, 30.0, 1.0)


@pytest.mark.parametrize("cloud", [0.0, 1.0])
def test_rendered_sky_gives_the_irradiance_and_the_radiance_of_the_model(zscore, cloud):
    res = Renderer(hc_scene(cloud)).run()
    ed = res.radiometer("Ed")
    zscore(f"HC sky C={cloud:g}: Ed = given irradiance", ed.mean[0, 0], 2.0, ed.stderr[0, 0])
    assert abs(ed.mean[0, 0] - 2.0) < 4 * ed.stderr[0, 0] + 1e-3
    # radiance in a 5 deg cap against the model averaged over the cap (fine quadrature)
    table = sky_table(40.0, 30.0, cloud)
    scale = 2.0 / math.pi
    for name, centre in (("L_zenith", (0.0, 0.0)), ("L_sun_side", (60.0, 30.0))):
        c = np.array([math.sin(math.radians(centre[0])) * math.cos(math.radians(centre[1])),
                      math.sin(math.radians(centre[0])) * math.sin(math.radians(centre[1])),
                      math.cos(math.radians(centre[0]))])
        # the model averaged over the cap by a polar quadrature around its axis
        a = np.radians(5.0) * (np.arange(200) + 0.5) / 200
        b = 2 * math.pi * (np.arange(200) + 0.5) / 200
        aa, bb = np.meshgrid(a, b, indexing="ij")
        e1 = np.cross(c, [0.0, 1.0, 0.0] if abs(c[1]) < 0.9 else [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(c, e1)
        v = (np.cos(aa)[..., None] * c + np.sin(aa)[..., None] *
             (np.cos(bb)[..., None] * e1 + np.sin(bb)[..., None] * e2))
        th, ph = np.arccos(np.clip(v[..., 2], -1, 1)), np.arctan2(v[..., 1], v[..., 0])
        from photic.sky import _bilinear
        w = np.sin(aa)
        expected = scale * float(np.sum(_bilinear(table, th, ph) * w) / np.sum(w))
        r = res.radiometer(name)
        zscore(f"HC sky C={cloud:g}: {name}", r.mean[0, 0], expected, r.stderr[0, 0])
        assert abs(r.mean[0, 0] - expected) < 4 * r.stderr[0, 0] + 2e-3 * expected


def test_harrison_coombes_needs_a_sun():
    d = hc_scene().to_dict()
    d["sun"] = None
    with pytest.raises(SceneError, match="needs a sun"):
        Scene.from_dict(d)
    d = hc_scene().to_dict()
    d["sky"]["cloud_fraction"] = 1.5
    with pytest.raises(SceneError, match="cloud_fraction"):
        Scene.from_dict(d)
