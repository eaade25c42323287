"""The example scenes of photic.scenes, the PNG writer, and the error benchmark in quick mode."""
import math

import numpy as np
import trimesh
from matplotlib.image import imread

from photic.images import tonemap, write_png
from photic.render import render
from photic.scenes import stepped_pool, water_volume


def test_stepped_pool_validates_and_its_water_is_closed():
    scene = stepped_pool()
    scene.validate()
    assert [c.name for c in scene.cameras] == ["above", "under"]
    assert scene.sun.angular_diameter_deg == 0.53 and scene.settings.integrator == "hybrid"
    (water,) = scene.water
    tm = trimesh.Trimesh(water.mesh.vertices, water.mesh.triangles, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0
    # It fills the pool (6 m x 3 m) down to the deepest floor (1.8 m): the volume of the box.
    assert abs(tm.volume - 6.0 * 3.0 * 1.8) < 0.1
    z = water.mesh.vertices[:, 2]
    assert 0.02 < z.max() < 0.06 and math.isclose(z.min(), -1.801)
    # The flat variant and a standalone volume are closed too.
    flat = stepped_pool(waves=False).water[0].mesh
    assert trimesh.Trimesh(flat.vertices, flat.triangles, process=False).is_watertight
    v, t = water_volume(0, 1, 0, 2, -1, 3, 5, lambda x, y: 0.1 * np.sin(x + y))
    tm = trimesh.Trimesh(v, t, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0


def test_stepped_pool_tiny_hybrid_render_has_beams_on_surfaces():
    scene = stepped_pool(resolution=(8, 6), samples=2)
    scene.cameras = [c for c in scene.cameras if c.name == "under"]
    result = render(scene, samples=2)
    img = result.images["under"]
    assert img.mean.shape == (6, 8, 3)
    assert np.all(np.isfinite(img.mean)) and np.all(img.mean >= 0)
    assert np.all(np.isfinite(img.variance)) and np.all(img.variance >= 0)
    assert result.stats["integrator"] == "hybrid" and result.stats["beam_prisms"] > 0
    assert img.components["beam_surface"].sum() > 0


def _read_png(path):
    """A PNG file as (H, W, 3) uint8 RGB (it must be opaque)."""
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = np.round(imread(path, format="png") * 255).astype(np.uint8)
    if img.shape[2] == 4:
        assert np.all(img[:, :, 3] == 255)
    return img[:, :, :3]


def test_png_writer_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, size=(7, 5, 3), dtype=np.uint8)
    assert np.array_equal(_read_png(write_png(tmp_path / "a.png", img)), img)
    grey = rng.random((4, 3))
    assert np.array_equal(_read_png(write_png(tmp_path / "g.png", grey)),
                          np.repeat(np.round(grey * 255).astype(np.uint8)[:, :, None], 3, axis=2))
    rgb = tonemap(rng.random((4, 6, 3)))
    assert rgb.shape == (4, 6, 3) and rgb.min() >= 0 and rgb.max() <= 1


def test_error_bench_quick(tmp_path):
    from photic.bench import run_error_bench, time_to_error

    plot = tmp_path / "err.png"
    records = run_error_bench(quick=True, threads=2, plot=plot, print_table=False)
    assert {r["scene"] for r in records} == {"problem2_omega0.9", "stepped_pool_under_16x12"}
    assert {r["method"] for r in records} == {"path", "hybrid cone 0", "hybrid auto"}
    for r in records:
        assert r["seconds"] > 0 and math.isfinite(r["rel_error"]) and r["rel_error"] >= 0
    # The refracted 0.53 deg sun is out of reach of pure path tracing under the flat surface.
    assert all(r["rel_error"] > 0.5 for r in records if r["method"] == "path" and r["scene"].startswith("problem"))
    assert _read_png(plot).shape[2] == 3
    fake = [{"budget": 1, "seconds": 1.0, "rel_error": 0.2}, {"budget": 2, "seconds": 4.0, "rel_error": 0.025}]
    assert math.isclose(time_to_error(fake)["seconds"], 1.0 * 4.0 ** (math.log(4) / math.log(8)))
    assert time_to_error(fake[:1])["seconds"] is None


def test_error_bench_takes_cases_and_their_own_values():
    """run_error_bench on a given case whose ``pick`` chooses the values that count (here the
    first radiometer's, of canonical problem 2, in every band): those, not the default, enter
    the errors."""
    from photic.bench import ErrorCase, run_error_bench
    from photic.problems import problem_scene
    from photic.scene import Scene

    seen = []

    def pick(result):
        r = result.radiometers[0]
        seen.append(r.name)
        return r.mean[0], r.stderr[0] ** 2  # (nbins = 1, nbands)

    def make(integrator, cone):
        d = problem_scene(2, 0.9)
        d["settings"].update(integrator=integrator, forward_cone_deg=cone)
        return Scene.from_dict(d)

    case = ErrorCase("p2_first", "P2", "radiometers", make,
                     {"path": [2048], "hybrid cone 0": [512], "hybrid auto": [512]}, 2048, "samples", pick)
    records = run_error_bench(threads=2, plot=None, print_table=False, cases=[case])
    assert {r["scene"] for r in records} == {"p2_first"} and len(records) == 3
    assert len(seen) >= 3 and set(seen) == {make("path", 0.0).radiometers[0].name}
    assert all(math.isfinite(r["rel_error"]) for r in records)


def test_grid_error_script_runs(tmp_path):
    """scripts/grid_error.py --quick on a small grid of the plume example: every method's
    records over the 20 values (Lu above plume and clear water in 10 bands), and its plot."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    try:
        import grid_error
        records = grid_error.main(["--quick", "--shape", "16", "16", "4", "--plot", str(tmp_path / "e.png")])
    finally:
        sys.path.pop(0)
    assert {r["method"] for r in records} == {"path", "hybrid cone 0", "hybrid auto"}
    assert all(r["scene"] == "sediment_plume_16x16x4" and math.isfinite(r["rel_error"]) for r in records)
    assert _read_png(tmp_path / "e.png").shape[2] == 3
