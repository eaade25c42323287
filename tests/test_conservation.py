"""Conservation checks: a white furnace (no absorption anywhere, uniform light from every
direction) must give back exactly the light it receives, radiance n^2 L0 inside water; and a
tiled wave-patch ocean that happens to be flat must match the analytic flat ocean."""
import numpy as np
import pytest

from analytic import transmitted_uniform_sky
from geometry import box, height_field
from photic.render import render
from photic.scene import Scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

Z_MAX = 4.0


def test_closed_non_absorbing_box_conserves_energy(zscore):
    """Water box (a = 0, b = 2, Petzold + pure water) holding a white block, in a uniform
    environment L0 over the full sphere: Eo = 4 pi n^2 L0 inside, L = n^2 L0 in any direction,
    Eu = pi L0 outside. Any loss or gain of energy (Fresnel, n^2 law, TIR, phase sampling,
    Russian roulette) shows up here."""
    n, l0 = 1.34, 1.0
    wv, wt = box((-2, -2, -2), (2, 2, 2))
    bv, bt = box((-0.5, -0.5, -1.5), (0.5, 0.5, -0.5))
    d = {"photic_scene": 1, "name": "furnace",
         "materials": {"white": {"type": "lambertian", "reflectance": [1.0]}},
         "meshes": [{"name": "block", "material": "white", "vertices": bv, "triangles": bt}],
         "water": [{"name": "tank", "type": "mesh", "ior": n, "vertices": wv, "triangles": wt,
                    "iops": {"absorption": [0.0], "scattering": [
                        {"b": [1.5], "phase": {"type": "petzold"}},
                        {"b": [0.5], "phase": {"type": "pure_water"}}]}}],
         "sky": {"type": "uniform", "radiance": [l0], "full_sphere": True},
         "radiometers": [
             {"name": "Eo_in", "quantity": "Eo", "position": [0.3, 0.9, 0.5]},
             {"name": "L_in", "quantity": "radiance", "position": [-1, 1, 1], "direction": [0.3, 0.2, -1]},
             {"name": "Eu_out_above", "quantity": "Eu", "position": [0, 0, 2.5]},
             {"name": "Eu_out", "quantity": "Eu", "position": [3, 0, 0]}],
         "settings": {"seed": 5, "max_depth": 100000}}
    res = render(Scene.from_dict(d), radiometer_samples=100_000)
    expect = {"Eo_in": 4 * np.pi * n * n * l0, "L_in": n * n * l0, "Eu_out_above": np.pi * l0, "Eu_out": np.pi * l0}
    for name, ref in expect.items():
        r = res.radiometer(name)
        assert r.medium == ("tank" if name.endswith("_in") else "air")
        assert abs(zscore(f"furnace {name}", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
        assert abs(r.mean[0, 0] / ref - 1) < 0.01


def flat_patch(period=2.0, n=8):
    return height_field(period, n)


def test_tiled_flat_patch_equals_flat_ocean(zscore):
    """A 2 m patch repeated without limit: rays cross many tiles and tile borders."""
    v, t = flat_patch()
    a = 0.3
    d = {"photic_scene": 1, "name": "patch",
         "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "patch", "vertices": v, "triangles": t,
                                                             "period": [2.0, 2.0]},
                    "iops": {"absorption": [a], "b": [0.0], "phase": {"type": "isotropic"}}}],
         "sky": {"type": "uniform", "radiance": [1.0]},
         "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [7.3, -11.1, -1.5]},
                         {"name": "Eo", "quantity": "Eo", "position": [0.0, 0.0, -0.2]}],
         "settings": {"seed": 3}}
    res = render(Scene.from_dict(d), radiometer_samples=100_000)
    for name, z in (("Ed", 1.5), ("Eo", 0.2)):
        r = res.radiometer(name)
        assert r.medium == "sea"
        ref = transmitted_uniform_sky(z, a, weight=name)
        assert abs(zscore(f"tiled patch {name}", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
