"""3-D IOP grids with several density fields on one lattice (an 'iop_grid' with 'fields': e.g.
sediment and CDOM that do not follow each other): the walk integrates every field exactly, the
sun through two absorbing fields follows Beer-Lambert, two slab fields equal the layered
profile they make, a grid of random scattering fields conserves energy, an empty extra field
changes nothing, and the scene format reads, writes and refuses them. Fixed seeds; z-scores
recorded."""
import json

import numpy as np
import pytest

from photic.render import render
from photic.scene import GridField, IOPGrid, Scene, SceneError
from test_grid import (N, RADS, Z_MAX, _exact_integral, _sparse_field, absorbing_grid, add, compare,
                       grid, mixture, rad, sea)

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

BOX = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])  # (the top above the surface)


def _offset_field():
    """A field on the sparse field's lattice that is non-zero mostly where that one is zero
    (a slanted sheet), so that bricks hold one field, the other or both."""
    rng = np.random.default_rng(21)
    i, j, k = np.meshgrid(*(np.arange(n) for n in (37, 29, 45)), indexing="ij")
    sheet = np.abs(k - 0.6 * i - 0.3 * j - 5) < 3
    return np.where(sheet, rng.random(sheet.shape) * 1.5 + 0.2, 0.0)


def _fields(d, *extra):
    """The grid of scene dict d with further fields (name, unit IOPs, densities)."""
    d["water"][0]["iop_grid"]["fields"] = [
        {"name": name, "unit": {"iops": unit}, "density": np.asarray(rho, dtype=float).tolist()}
        for name, unit, rho in extra]
    return d


def test_walk_integrates_every_field_exactly():
    """Three fields of different sparsity on one 37 x 29 x 45 lattice: along 300 random
    segments each field's integral equals numpy's (cut at every voxel face) to 1e-9, point
    lookups give every field's voxel, and regular tracking of s0 + sum_f s1_f rho_f stops
    where that optical depth reaches xi."""
    from photic.compile import compile_scene
    rng = np.random.default_rng(4)
    rhos = [_sparse_field(), _offset_field(), rng.random((37, 29, 45)) * (rng.random((37, 29, 45)) < 0.05)]
    d = _fields(absorbing_grid(rhos[0], BOX), ("sheet", mixture(0.2, 0.0, 0.0), rhos[1]),
                ("specks", mixture(0.1, 0.0, 0.0), rhos[2]))
    sc = Scene.from_dict(d)
    core = compile_scene(sc)
    g = sc.water[0].iops
    lo, size = np.array(BOX[0]), np.array(BOX[1])
    crossed = np.zeros(3, dtype=int)
    reached = 0
    for _ in range(300):
        p0 = lo - 0.2 * size + rng.random(3) * 1.4 * size
        p1 = lo - 0.2 * size + rng.random(3) * 1.4 * size
        got = core.grid_integral(0, p0.tolist(), p1.tolist())
        ref = [_exact_integral(r, lo, size, p0, p1) for r in rhos]
        assert got == pytest.approx(ref, rel=1e-9, abs=1e-12)
        crossed += np.array(ref) > 0
        p = lo + rng.random(3) * size
        assert core.grid_density(0, p.tolist()) == [float(np.float32(g.density_at(p, f))) for f in range(3)]
        # tracking along p0 -> p1
        u = (p1 - p0) / np.linalg.norm(p1 - p0)
        s0, s1, xi = 0.1, [1.5, 0.7, 2.0], rng.exponential()
        hit, t, rho_at, integrals, left = core.grid_march(0, p0.tolist(), u.tolist(), s0, s1, xi, 8.0)
        r = [_exact_integral(x, lo, size, p0, p0 + u * t) for x in rhos]
        assert integrals == pytest.approx(r, rel=1e-9, abs=1e-12)
        depth = s0 * t + sum(a * b for a, b in zip(s1, r))
        if hit:
            reached += 1
            assert depth == pytest.approx(xi, rel=1e-9, abs=1e-12)
            q = p0 + u * (t - 1e-9)
            assert rho_at == pytest.approx([g.density_at(q, f) for f in range(3)], rel=1e-6, abs=1e-12)
        else:
            assert left == pytest.approx(xi - depth, rel=1e-9, abs=1e-12)
    assert np.all(crossed > 40) and reached > 40


def test_sun_through_two_absorbing_fields():
    """b = 0, a small sun at 35 deg, two random absorbing fields (units a = 0.3 and 0.7 per unit
    density) on 4 x 5 x 6 voxels: Ed at three points equals the disk quadrature with the optical
    depth 0.05 l + 0.3 int rho_1 + 0.7 int rho_2 integrated in numpy, to 1e-3 (deterministic)."""
    import math
    from test_grid import SMALL_SUN, N_W
    from test_stratified import refracted_sun
    rng = np.random.default_rng(7)
    rho1, rho2 = rng.random((4, 5, 6)) * 2.0, rng.random((4, 5, 6)) * (rng.random((4, 5, 6)) < 0.5)
    d = _fields(absorbing_grid(rho1, BOX), ("cdom", mixture(0.7, 0.0, 0.0), rho2))
    points = [(0.3, -0.2, -1.0), (-0.5, 0.7, -2.5), (0.9, 0.1, -3.7)]
    d["radiometers"] = [{"name": f"Ed_{i}", "quantity": "Ed", "position": list(p)} for i, p in enumerate(points)]
    d["sun"] = {"zenith_deg": 35.0, "azimuth_deg": 20.0, "irradiance": [1.0], "angular_diameter_deg": SMALL_SUN}
    d["sky"] = {"type": "black"}
    res = render(Scene.from_dict(d), radiometer_samples=4_000)
    sin_w = math.sin(math.radians(35.0)) / N_W
    mu_w = math.sqrt(1 - sin_w ** 2)
    up = np.array([sin_w * math.cos(math.radians(20.0)), sin_w * math.sin(math.radians(20.0)), mu_w])
    for i, p in enumerate(points):
        length = -p[2] / mu_w
        ends = (np.asarray(p), np.asarray(p) + up * length)
        tau_ray = (0.05 * length + 0.3 * _exact_integral(rho1, BOX[0], BOX[1], *ends)
                   + 0.7 * _exact_integral(rho2, BOX[0], BOX[1], *ends))
        assert _exact_integral(rho2, BOX[0], BOX[1], *ends) > 0.1
        ref = refracted_sun(35.0, tau_ray * mu_w, diameter_deg=SMALL_SUN)
        assert abs(res.radiometer(f"Ed_{i}").mean[0, 0] / ref - 1) < 1e-3


@pytest.mark.parametrize("integrator", ["hybrid", "path"])
def test_two_slab_fields_equal_the_layered_profile(zscore, integrator):
    """Sediment (scattering, forward-peaked) in a slab from 2 to 5 m deep and CDOM-like water
    (absorbing, some pure-water-like scattering) below 4 m, as two fields of one grid: the
    four-layer profile base | base + U1 | base + U1 + U2 | base + U2 they make, within errors
    (Ed, Eu, Eo at 1, 3 and 6 m)."""
    base, u1, u2 = mixture(0.06, 0.1, 0.03), mixture(0.2, 0.8, 0.0), mixture(0.3, 0.0, 0.05)
    z = -40.0 + (np.arange(42) + 0.5)   # cell centres of the 1 m cells from -40 to +2 m
    rho1 = np.broadcast_to(np.where((z < -2.0) & (z > -5.0), 1.0, 0.0), (2, 2, 42))
    rho2 = np.broadcast_to(np.where(z < -4.0, 1.0, 0.0), (2, 2, 42))
    g = grid(base, u1, rho1)
    g["fields"] = [{"name": "cdom", "unit": {"iops": u2}, "density": rho2.tolist()}]
    layers = [base, add(base, u1), add(add(base, u1), u2), add(base, u2)]
    prof = render(sea(RADS, profile=([0.0, -2.0, -4.0, -5.0], layers), integrator=integrator, seed=91),
                  radiometer_samples=N[integrator])
    gr = render(sea(RADS, grid=g, integrator=integrator, seed=92), radiometer_samples=N[integrator])
    compare(zscore, f"{integrator} two slab fields", prof, gr)


def test_white_furnace_with_two_fields(zscore):
    """A closed non-absorbing water box in an isotropic environment L0 holding two random
    scattering fields of different sparsity and phase-function mix: Eo = 4 pi n^2 L0 and
    L = n^2 L0 wherever measured."""
    from geometry import box
    n, l0 = 1.34, 1.0
    wv, wt = box((-2, -2, -2), (2, 2, 2))
    rng = np.random.default_rng(13)
    rho1, rho2 = rng.random((20, 12, 9)) * 3.0, rng.random((20, 12, 9)) * 2.0
    rho1[rng.random(rho1.shape) < 0.3] = 0.0
    rho2[rng.random(rho2.shape) < 0.6] = 0.0
    g = grid(mixture(0.0, 0.2, 0.1), mixture(0.0, 1.0, 0.2), rho1, ([-1.5, -1.0, -1.8], [2.5, 2.8, 3.0]))
    g["fields"] = [{"name": "fine", "unit": {"iops": mixture(0.0, 0.1, 1.5)}, "density": rho2.tolist()}]
    d = {"photic_scene": 1, "name": "furnace",
         "water": [{"name": "tank", "type": "mesh", "ior": n, "vertices": wv, "triangles": wt, "iop_grid": g}],
         "sky": {"type": "uniform", "radiance": [l0], "full_sphere": True},
         "radiometers": [{"name": f"Eo_{i}", "quantity": "Eo", "position": list(p)}
                         for i, p in enumerate([(0.3, -0.4, 0.2), (-1.2, 1.5, -0.7)])] +
                        [{"name": "L_mid", "quantity": "radiance", "position": [0.0, 0.5, 0.1],
                          "direction": [0.3, 0.2, -1.0]}],
         "settings": {"seed": 83, "max_depth": 100000}}
    res = render(Scene.from_dict(d), radiometer_samples=30_000)
    for r in res.radiometers:
        ref = (4 * np.pi if r.name.startswith("Eo") else 1.0) * n * n * l0
        assert abs(zscore(f"two-field furnace {r.name}", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX


@pytest.mark.parametrize("integrator", ["hybrid", "path"])
def test_an_empty_extra_field_changes_nothing(integrator):
    """A second field that is zero everywhere (its unit absorbs) leaves a scattering plume's
    render bit for bit as it was: the walk reads each field's own voxels."""
    rho = _sparse_field()
    base, unit = mixture(0.05, 0.1, 0.02), mixture(0.3, 1.5, 0.0)
    one = sea(RADS, grid=grid(base, unit, rho, BOX), integrator=integrator, seed=5)
    g = grid(base, unit, rho, BOX)
    g["fields"] = [{"name": "none", "unit": {"iops": mixture(0.8, 0.0, 0.0)}, "density": np.zeros_like(rho).tolist()}]
    two = sea(RADS, grid=g, integrator=integrator, seed=5)
    a, b = (render(s, radiometer_samples=3000) for s in (one, two))
    assert a.radiometers[0].mean.any()
    for r1, r2 in zip(a.radiometers, b.radiometers):
        assert np.array_equal(r1.mean, r2.mean) and np.array_equal(r1.stderr, r2.stderr)


def test_fields_from_npz_keys_round_trip_and_validate(tmp_path):
    """Fields read by key from the grid's .npz are saved by reference, validate against the
    schema and read back equal; inline ones are written inline; a field's unit from a model is
    aligned with the base's components."""
    import jsonschema
    from photic.scene import load_scene, save_scene, scene_schema
    rng = np.random.default_rng(2)
    rho, cdom = rng.random((5, 4, 3)).astype(np.float32), rng.random((5, 4, 3)).astype(np.float32)
    np.savez(tmp_path / "plume.npz", density=rho, cdom=cdom)
    d = absorbing_grid(rho, BOX)
    g = d["water"][0]["iop_grid"]
    del g["density"]
    g["file"] = "plume.npz"
    g["fields"] = [{"name": "cdom", "unit": {"iops": mixture(0.5, 0.0, 0.0)}, "key": "cdom"},
                   {"name": "bloom", "unit": {"iop_model": {"model": "particles", "b_ref": 1.0,
                                                            "backscatter_fraction": 0.01}},
                    "density": np.ones((5, 4, 3)).tolist()}]
    sc = Scene.from_dict(d, base_dir=tmp_path)
    w = sc.water[0].iops
    assert isinstance(w, IOPGrid) and [f.name for f in w.extra_fields] == ["cdom", "bloom"]
    assert isinstance(w.extra_fields[0], GridField) and w.extra_fields[0].key == "cdom"
    np.testing.assert_array_equal(w.extra_fields[0].density, cdom)
    phases = [[c.phase for c in u.scattering] for u in [w.iops] + w.units()]
    assert all(p == phases[0] for p in phases) and len(phases[0]) == 3
    save_scene(sc, tmp_path / "s.json")
    saved = json.loads((tmp_path / "s.json").read_text())
    jsonschema.validate(saved, scene_schema())
    fields = saved["water"][0]["iop_grid"]["fields"]
    assert fields[0]["key"] == "cdom" and "density" not in fields[0] and "density" in fields[1]
    assert load_scene(tmp_path / "s.json") == sc
    assert render(sc, radiometer_samples=1_000).radiometer("Ed_1").mean[0, 0] > 0


def _field_scene(field, grid_changes=None):
    d = absorbing_grid(np.ones((2, 2, 2)), BOX)
    d["water"][0]["iop_grid"]["fields"] = field if isinstance(field, list) else [field]
    d["water"][0]["iop_grid"].update(grid_changes or {})
    return d


CDOM = {"iops": mixture(0.5, 0.0, 0.0)}
ONES = np.ones((2, 2, 2)).tolist()


@pytest.mark.parametrize("field, changes, where, text", [
    ({"name": "c", "unit": CDOM, "density": np.ones((2, 2, 3)).tolist()}, None,
     "iop_grid.fields[0].density", "the fields share the grid's voxels"),
    ({"name": "c", "unit": CDOM, "density": [[[1.0, -0.5], [1.0, 1.0]], [[1.0, 1.0], [1.0, 1.0]]]}, None,
     "iop_grid.fields[0].density[0, 0, 1]", ">= 0"),
    ({"name": "c", "unit": {"iops": mixture(-0.1, 0.0, 0.0)}, "density": ONES}, None,
     "iop_grid.fields[0].unit.iops.absorption", ">= 0"),
    ({"name": "c", "unit": {"iops": {"absorption": [0.1], "scattering": []}}, "density": ONES}, None,
     "iop_grid.fields[0].unit.iops.scattering", "same components"),
    ({"name": "c", "unit": CDOM, "key": "cdom"}, None, "iop_grid.fields[0].key", "has no 'file'"),
    ({"name": "c", "unit": CDOM}, None, "iop_grid.fields[0]", "give one of 'density', 'key'"),
    ({"unit": CDOM, "density": ONES}, None, "iop_grid.fields[0].name", "required field is missing"),
    ([{"name": "c", "unit": CDOM, "density": ONES}] * 2, None, "iop_grid.fields[1].name", "of its own"),
    ([{"name": f"c{i}", "unit": CDOM, "density": ONES} for i in range(4)], None, "iop_grid.fields", "at most 3"),
])
def test_bad_fields_are_scene_errors(field, changes, where, text):
    with pytest.raises(SceneError) as e:
        Scene.from_dict(_field_scene(field, changes))
    msg = str(e.value)
    assert "sea" in msg and where in msg and text in msg, msg


def test_missing_npz_key_is_a_scene_error(tmp_path):
    np.savez(tmp_path / "g.npz", density=np.ones((2, 2, 2)))
    d = _field_scene({"name": "c", "unit": CDOM, "key": "cdom"}, {"file": "g.npz"})
    del d["water"][0]["iop_grid"]["density"]
    with pytest.raises(SceneError, match=r"iop_grid.fields\[0\].key.*no array 'cdom'"):
        Scene.from_dict(d, base_dir=tmp_path)


@pytest.mark.parametrize("bad", [float("nan"), -1.0, float("inf")])
def test_core_refuses_bad_densities_in_a_further_field(bad):
    """The core checks every field itself (a scene changed after validation): a NaN, negative
    or infinite value in the second field, where the first is clean, is refused."""
    from photic.compile import compile_scene
    rho = np.zeros((3, 4, 40))
    rho[1, 2, 5] = 1.0
    sc = Scene.from_dict(_fields(absorbing_grid(rho, BOX), ("cdom", mixture(0.5, 0.0, 0.0), rho)))
    sc.water[0].iops.extra_fields[0].density[2, 3, 37] = bad
    with pytest.raises(ValueError, match="finite and >= 0"):
        compile_scene(sc)
