"""The hybrid integrator (beams + paths) against pure path tracing and conservation laws."""
import numpy as np
import pytest

from photic import _core
from photic.render import render
from photic.scene import Scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

Z_AGREE = 3.0  # hybrid and path tracing agree within 3 combined standard errors


def sunlit_sea(integrator, diameter=10.0, surface=None, cone=0, bottom=6.0):
    rads = []
    for z in (1.0, 3.0, 5.0):
        rads += [{"name": f"{q}_{z:g}", "quantity": q, "position": [0.2, -0.1, -z]} for q in ("Ed", "Eu", "Eo")]
    d = {"photic_scene": 1, "name": "sunlit",
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.35]}},
         "water": [{"name": "sea", "type": "ocean", "surface": surface or {"kind": "flat", "z": 0.0},
                    "bottom": {"depth": bottom, "material": "sand"},
                    "iops": {"absorption": [0.15], "scattering": [
                        {"b": [0.35], "phase": {"type": "petzold"}},
                        {"b": [0.05], "phase": {"type": "pure_water"}}]}}],
         "sun": {"zenith_deg": 30.0, "azimuth_deg": 60.0, "irradiance": [1.0], "angular_diameter_deg": diameter},
         "sky": {"type": "black"},
         "cameras": [{"name": "down", "type": "perspective", "position": [0, 0, -2.0], "direction": [0.1, 0.2, -1],
                      "up": [0, 1, 0], "fov_deg": 50, "resolution": [16, 12]}],
         "radiometers": rads,
         "settings": {"integrator": integrator, "seed": 17, "forward_cone_deg": cone}}
    return Scene.from_dict(d)


def test_hybrid_agrees_with_path_tracing_under_a_10_degree_sun(zscore):
    """With the sun enlarged to 10 deg, pure path tracing finds it by escaping paths and
    converges; the hybrid integrator must agree: Ed, Eu, Eo at 3 depths and an image mean."""
    hy = render(sunlit_sea("hybrid"), samples=64, radiometer_samples=200_000)
    pt = render(sunlit_sea("path"), samples=256, radiometer_samples=1_000_000)
    assert hy.stats["integrator"] == "hybrid" and pt.stats["integrator"] == "path"
    for r in hy.radiometers:
        p = pt.radiometer(r.name)
        se = float(np.hypot(r.stderr[0, 0], p.stderr[0, 0]))
        assert abs(zscore(f"hybrid vs path {r.name}", r.mean[0, 0], p.mean[0, 0], se)) < Z_AGREE
    hi, pi = hy.images["down"], pt.images["down"]
    se = np.hypot(np.sqrt(hi.variance.sum()), np.sqrt(pi.variance.sum())) / hi.mean.size
    assert abs(zscore("hybrid vs path image mean", hi.mean.mean(), pi.mean.mean(), se)) < Z_AGREE
