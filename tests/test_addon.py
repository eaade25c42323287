"""The Blender add-on through ``import bpy`` (Blender 5.0 as a Python module), as batch users run it.

Each test starts from an empty Blender file with the add-on registered. Renders go through the
RenderEngine (``bpy.ops.render.render``), exactly as F12 and ``blender -b -f`` render.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

import bpy  # noqa: E402  (a requirement: the add-on's tests must not be skipped silently)

from photic.cli import load_addon  # noqa: E402
from photic.render import Renderer  # noqa: E402
from photic.scene import load_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
BLENDS = REPO / "example_blends"

addon = load_addon()
from photic_blender import export, final_render  # noqa: E402
from photic_blender.batch import ensure_registered, render_blend  # noqa: E402

import photic  # noqa: E402
import photic.output  # noqa: E402,F401  (as the add-on's engine loader imports it)


@pytest.fixture
def empty():
    """An empty Blender file with the add-on registered and Photic as the engine."""
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    scene.render.resolution_percentage = 100
    return scene


def add_mesh(name, vertices, faces, location=(0, 0, 0)):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([list(v) for v in vertices], [], [list(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_box(name, size=1.0, location=(0, 0, 0)):
    s = size / 2
    v = [(-s, -s, -s), (s, -s, -s), (s, s, -s), (-s, s, -s), (-s, -s, s), (s, -s, s), (s, s, s), (-s, s, s)]
    f = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return add_mesh(name, v, f, location)


def add_camera(location=(0, -6, 2), rotation=(math.radians(75), 0, 0)):
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    return cam


def add_sun(zenith_deg=30.0, azimuth_deg=0.0, name="Sun"):
    light = bpy.data.lights.new(name, "SUN")
    light.energy = 1.0
    obj = bpy.data.objects.new(name, light)
    obj.rotation_euler = (math.radians(zenith_deg), 0, math.radians(azimuth_deg + 90))
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_sea(name="Sea", depth=None):
    obj = add_mesh(name, [(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [(0, 1, 2, 3)])
    obj.photic.role = "WATER_SURFACE"
    if depth is not None:
        obj.photic.use_bottom, obj.photic.bottom_depth = True, depth
    return obj


def export_current(**kw):
    return export.export_scene(bpy.context.evaluated_depsgraph_get(), photic, **kw)


# ------------------------------------------------------------------------------------------
# Example files rendered through the add-on
# ------------------------------------------------------------------------------------------

def exr_channels(path):
    import OpenEXR
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: ch.pixels for part in f.parts for name, ch in part.channels.items()}


@pytest.mark.parametrize("name, has_radiometers", [("canonical_problem2", True),
                                                   ("stepped_pool", False),
                                                   ("underwater_objects", False),
                                                   ("seagrass_meadow", True)])
def test_example_blends_render_through_the_addon(tmp_path, name, has_radiometers):
    summary = render_blend(BLENDS / f"{name}.blend", out_dir=tmp_path, samples=2,
                           radiometer_samples=8192, resolution_percentage=50)
    channels = exr_channels(summary["image"])
    layer = "ViewLayer."
    for p in ("Combined", *final_render.PASS_NAMES):
        for c in "RGB":
            assert f"{layer}{p}.{c}" in channels, sorted(channels)
    combined = np.stack([channels[f"{layer}Combined.{c}"] for c in "RGB"], -1)
    assert np.all(np.isfinite(combined)) and combined.mean() > 0
    if f"{layer}{final_render.NOISY_PASS}.R" in channels:  # a denoised example (the showcase)
        combined = np.stack([channels[f"{layer}{final_render.NOISY_PASS}.{c}"] for c in "RGB"], -1)
        for p in (final_render.ALBEDO_PASS, final_render.NORMAL_PASS):
            assert any(k.startswith(f"{layer}{p}.") for k in channels), p
    # The component passes sum to the combined image (hybrid integrator; the Raman pass
    # where Raman scattering is on).
    names = final_render.PASS_NAMES[:3] + ((final_render.RAMAN_PASS,)
                                           if f"{layer}{final_render.RAMAN_PASS}.R" in channels else ())
    parts = sum(np.stack([channels[f"{layer}{p}.{c}"] for c in "RGB"], -1) for p in names)
    np.testing.assert_allclose(parts, combined[..., :3], rtol=1e-4, atol=1e-6)
    assert np.all(np.stack([channels[f"{layer}Photic Variance.{c}"] for c in "RGB"]) >= 0)
    if has_radiometers:
        csv = Path(summary["tables"][0])
        assert csv.is_file() and csv.name == f"{name}_0001_radiometers.csv"
        rows = [line for line in csv.read_text().splitlines() if not line.startswith("#")]
        # header + 3 depths x (Ed, Eou, radiance); the meadow: Ed at 16 points under and over,
        # 3 bands
        assert len(rows) == 1 + {"canonical_problem2": 9, "seagrass_meadow": 96}[name]
        assert final_render.LAST_RADIOMETERS[bpy.context.scene.name]["rows"]


def test_canonical_blend_exports_exactly_the_scene_file_and_renders_the_same_values(tmp_path):
    """The .blend and canonical_problem2.json (written from the problem's definition) are the
    same scene; rendered with the same seed they give the same numbers, bit for bit."""
    ensure_registered()
    bpy.ops.wm.open_mainfile(filepath=str(BLENDS / "canonical_problem2.blend"))
    exported, _ = export_current()
    reference = load_scene(BLENDS / "canonical_problem2.json")
    assert exported.to_dict() == reference.to_dict()

    n = 16384
    direct = Renderer(reference, samples=1, radiometer_samples=n).run()
    summary = render_blend(BLENDS / "canonical_problem2.blend", out_dir=tmp_path, samples=1,
                           radiometer_samples=n)
    import json
    table = json.loads(Path(summary["tables"][1]).read_text())
    assert [r["name"] for r in table["radiometers"]] == [r.name for r in direct.radiometers]
    for r_blend, r_direct in zip(table["radiometers"], direct.radiometers):
        assert r_blend["value"] == r_direct.mean.tolist()
        assert r_blend["stderr"] == r_direct.stderr.tolist()


def test_target_error_from_blender_is_the_engines(tmp_path):
    """Target Error in the Render panel: exported as settings.target_error, imported back, and
    a batch render with a target gives the numbers of the engine's adaptive render of the same
    scene, bit for bit, with the target's fields in the JSON table."""
    import json
    ensure_registered()
    bpy.ops.wm.open_mainfile(filepath=str(BLENDS / "canonical_problem2.blend"))
    p = bpy.context.scene.photic
    assert not p.use_target_error and export_current()[0].settings.target_error is None
    p.use_target_error, p.target_error = True, 2.5
    exported, _ = export_current()
    assert exported.settings.target_error == 0.025
    path = tmp_path / "t.json"
    photic.scene.save_scene(exported, path)
    p.use_target_error = False
    assert bpy.ops.photic.import_scene(filepath=str(path)) == {"FINISHED"}
    assert bpy.context.scene.photic.use_target_error
    assert bpy.context.scene.photic.target_error == pytest.approx(2.5)

    summary = render_blend(BLENDS / "canonical_problem2.blend", out_dir=tmp_path, samples=1,
                           radiometer_samples=1 << 16, target_error=0.02)
    assert summary["stats"]["target_error"] == 0.02
    reference = load_scene(BLENDS / "canonical_problem2.json")
    direct = Renderer(reference, samples=1, radiometer_samples=1 << 16, target_error=0.02).run()
    table = json.loads(Path(summary["tables"][1]).read_text())
    for r_blend, r_direct in zip(table["radiometers"], direct.radiometers):
        assert r_blend["value"] == r_direct.mean.tolist()
        assert r_blend["target_error"] == 0.02
        assert r_blend["target_reached"] == r_direct.target_reached
    assert summary["stats"]["target_reached"] == direct.stats["target_reached"] > 0


def test_noise_threshold_from_blender_is_the_engines(tmp_path):
    """Noise Threshold and Min Samples in the Render panel: exported as settings.noise_threshold
    and adaptive_min_samples, imported back, and a batch render with a threshold gives the
    engine's adaptive image of the same scene (per-pixel samples in the EXR's summary)."""
    ensure_registered()
    bpy.ops.wm.open_mainfile(filepath=str(BLENDS / "stepped_pool.blend"))
    p = bpy.context.scene.photic
    assert not p.use_noise_threshold and export_current()[0].settings.noise_threshold is None
    p.use_noise_threshold, p.noise_threshold, p.adaptive_min_samples = True, 4.0, 8
    exported, _ = export_current()
    assert exported.settings.noise_threshold == pytest.approx(0.04)
    assert exported.settings.adaptive_min_samples == 8
    path = tmp_path / "t.json"
    photic.scene.save_scene(exported, path)
    p.use_noise_threshold = False
    assert bpy.ops.photic.import_scene(filepath=str(path)) == {"FINISHED"}
    q = bpy.context.scene.photic
    assert q.use_noise_threshold and q.noise_threshold == pytest.approx(4.0) and q.adaptive_min_samples == 8

    bpy.ops.wm.open_mainfile(filepath=str(BLENDS / "stepped_pool.blend"))
    bpy.context.scene.photic.adaptive_min_samples = 4
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "pool.blend"))
    summary = render_blend(tmp_path / "pool.blend", out_dir=tmp_path, samples=32, radiometer_samples=1024,
                           resolution_percentage=25, noise_threshold=0.2)
    st = summary["stats"]
    assert st["noise_threshold"] == 0.2 and st["adaptive_min_samples"] == 4
    (cam, mean_spp), = st["pixel_samples_mean"].items()
    assert 4 < mean_spp < 32 and 0 < st["pixels_converged"][cam] <= 1


def test_canonical_blend_reproduces_problem_2(zscore):
    """The .blend's radiometer array against the published mean of the models (Mobley et al.
    1993), with the tolerance of `photic problems` and fewer samples."""
    from photic.problems import TAUS, reference_table
    ensure_registered()
    bpy.ops.wm.open_mainfile(filepath=str(BLENDS / "canonical_problem2.blend"))
    scene, _ = export_current()
    res = Renderer(scene, radiometer_samples=65536).run()
    refs = reference_table()
    names = {"Ed": "Ed", "Eou": "Eou", "radiance": "Lu"}
    for i, tau in enumerate(TAUS):
        for q in ("Ed", "Eou", "radiance"):
            r = res.radiometer(f"profile[{i}].{q}")
            ref, cv = refs[(2, 0.9, tau, names[q])]
            value, se = float(r.mean[0, 0]), float(r.stderr[0, 0])
            zscore(f"problem 2 .blend tau {tau:g} {names[q]} (ref: model mean)", value, ref, se)
            assert abs(value - ref) <= (2 * cv + 0.005) * ref + 3 * se, (tau, q, value, ref, se)


# ------------------------------------------------------------------------------------------
# Streaming, progress and cancel
# ------------------------------------------------------------------------------------------

def test_render_streams_updates_into_the_render_result(empty):
    """A render of 3 s or more through the RenderEngine streams at least 3 updates."""
    scene = empty
    scene.render.resolution_x, scene.render.resolution_y = 160, 120
    scene.photic.samples = 512
    scene.photic.integrator = "PATH"
    scene.photic.threads = 1
    add_sea(depth=4.0).photic.scattering = 0.5
    add_box("Rock", 1.0, (0, 0, -3.5))
    add_camera((0, -5, 1), (math.radians(80), 0, 0))
    add_sun(30)
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()
    summary = final_render.LAST_RENDER
    assert summary["error"] is None
    assert summary["time_s"] >= 3.0, summary["time_s"]
    assert summary["updates"] >= 3, summary
    gaps = np.diff(summary["update_times"])
    assert gaps.max() <= 2.0, gaps  # streaming keeps going (passes double up to 16 spp)
    assert summary["samples"] == 512
    print(f"{summary['updates']} updates in a {summary['time_s']:.1f} s render, largest gap "
          f"{gaps.max():.2f} s")


class StandInEngine:
    """The RenderEngine methods FinalRender uses; Esc is 'pressed' after ``break_after_s``."""

    def __init__(self, break_after_s):
        self.break_after_s = break_after_s
        self.t0 = time.perf_counter()
        self.updates, self.reports, self.progress = 0, [], []
        self.final_pixels = None

    def test_break(self):
        return time.perf_counter() - self.t0 > self.break_after_s

    def begin_result(self, x, y, w, h):
        class Pass:
            rect = None

        passes = {name: Pass() for name in ("Combined", *final_render.PASS_NAMES)}

        class Layer:
            pass

        layer = Layer()
        layer.passes = passes

        class Result:
            layers = [layer]

        return Result()

    def update_result(self, result):
        self.updates += 1

    def end_result(self, result):
        self.final_pixels = result.layers[0].passes["Combined"].rect

    def update_progress(self, f):
        self.progress.append(f)

    def update_stats(self, stats, info):
        self.stats = info

    def report(self, kind, message):
        self.reports.append((kind, message))

    def error_set(self, message):
        self.reports.append(({"ERROR"}, message))


def test_cancel_is_honoured_within_half_a_second_and_keeps_the_partial_image(empty):
    scene = empty
    scene.render.resolution_x, scene.render.resolution_y = 200, 150
    scene.photic.samples = 100000
    scene.photic.threads = 1
    add_sea(depth=4.0).photic.scattering = 0.5
    add_box("Rock", 1.0, (0, 0, -3.5))
    add_camera((0, -5, 1), (math.radians(80), 0, 0))
    add_sun(30)
    engine = StandInEngine(break_after_s=2.0)
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["cancelled"] and summary["error"] is None
    assert summary["cancel_latency_s"] <= 0.5, summary["cancel_latency_s"]
    assert summary["updates"] >= 2
    assert 0 < summary["samples"] < 100000
    pixels = np.asarray(engine.final_pixels).reshape(-1, 4)
    assert pixels.shape[0] == 200 * 150 and pixels[:, :3].mean() > 0
    assert engine.progress[-1] < 1.0 or summary["cancelled"]
    print(f"cancel latency {1000 * summary['cancel_latency_s']:.0f} ms after "
          f"{summary['samples']} samples; {summary['updates']} updates")


# ------------------------------------------------------------------------------------------
# Export: cameras, instances, speed
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("fit, size, shift, ortho", [
    ("AUTO", (64, 48), (0.0, 0.0), False), ("AUTO", (48, 64), (0.1, -0.05), False),
    ("VERTICAL", (64, 48), (0.2, 0.1), False), ("HORIZONTAL", (40, 80), (-0.1, 0.3), False),
    ("AUTO", (64, 48), (0.1, 0.2), True), ("VERTICAL", (48, 64), (0.0, 0.1), True)])
def test_camera_projection_matches_blender(empty, fit, size, shift, ortho):
    """Points seen by the exported camera land where Blender's own projection puts them."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
    scene = empty
    scene.render.resolution_x, scene.render.resolution_y = size
    cam = add_camera((1.0, -4.0, 2.0), (math.radians(70), math.radians(5), math.radians(20)))
    cam.data.sensor_fit, cam.data.lens = fit, 35.0
    cam.data.shift_x, cam.data.shift_y = shift
    if ortho:
        cam.data.type, cam.data.ortho_scale = "ORTHO", 5.0
    add_sun(30)
    exported, _ = export_current()
    c = exported.cameras[0]
    fwd = c.direction / np.linalg.norm(c.direction)
    right = np.cross(fwd, c.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    aspect = size[1] / size[0]
    rng = np.random.default_rng(3)
    for _ in range(20):
        p = np.array(cam.matrix_world.translation) + 6 * fwd + rng.normal(0, 1.0, 3)
        u_b, v_b, _ = world_to_camera_view(scene, cam, Vector(p))
        d = p - c.position
        if ortho:
            half = c.ortho_width / 2
            x, y = d @ right / half, d @ up / half
        else:
            t = math.tan(math.radians(c.fov_deg) / 2)
            x, y = (d @ right) / (d @ fwd) / t, (d @ up) / (d @ fwd) / t
        u = (x - 2 * c.shift[0] + 1) / 2
        v = ((y - 2 * c.shift[1]) / aspect + 1) / 2
        assert abs(u - u_b) < 1e-5 and abs(v - v_b) < 1e-5, (u, u_b, v, v_b)


def test_instances_are_grouped_by_mesh_and_transformed(empty):
    add_camera()
    add_sun(30)
    rock = add_box("Rock", 1.0)
    for i in range(5):  # linked duplicates share the mesh
        dup = rock.copy()
        dup.location = (2.0 * i, 0, -1)
        dup.scale = (1, 1, 2)
        bpy.context.scene.collection.objects.link(dup)
    scene, info = export_current()
    assert info.meshes_evaluated == 1
    # one box and a transform per copy (tests/test_addon_instancing.py)
    assert len(scene.meshes) == 1 and scene.meshes[0].copies == 6
    assert len(scene.meshes[0].flattened().mesh.triangles) == 6 * 12
    v = scene.meshes[0].flattened().mesh.vertices
    assert v[:, 0].max() == pytest.approx(8.5) and v[:, 2].min() == pytest.approx(-2.0)


def test_million_triangle_scene_with_1000_instances_exports(empty):
    """1,000,000+ triangles: a 500k-triangle terrain and 1000 instances of a 512-triangle rock
    (collection instances), exported from the evaluated depsgraph, each mesh evaluated once.
    Its time is printed, not asserted (wall-time limits belong in benchmarks: under a loaded
    machine the best of two took over 3 s)."""
    scene = empty
    add_camera()
    add_sun(30)
    n = 500
    g = np.linspace(-50, 50, n + 1)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    verts = np.stack([xx.ravel(), yy.ravel(), (0.3 * np.sin(xx) * np.cos(yy)).ravel()], 1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    quads = np.stack([a, a + n + 1, a + n + 2, a + 1], 1)
    mesh = bpy.data.meshes.new("terrain")
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.astype(np.float32).ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.astype(np.int32).ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    if "loop_total" in mesh.polygons[0].bl_rna.properties and not mesh.polygons[0].bl_rna.properties["loop_total"].is_readonly:
        mesh.polygons.foreach_set("loop_total", np.full(len(quads), 4, np.int32))
    mesh.update()
    terrain = bpy.data.objects.new("terrain", mesh)
    scene.collection.objects.link(terrain)
    coll = bpy.data.collections.new("rocks")
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=17, radius=0.5)
    rock = bpy.context.object
    for c in rock.users_collection:
        c.objects.unlink(rock)
    coll.objects.link(rock)
    rng = np.random.default_rng(1)
    for k in range(1000):
        inst = bpy.data.objects.new(f"rock{k}", None)
        inst.instance_type = "COLLECTION"
        inst.instance_collection = coll
        inst.location = (*rng.uniform(-45, 45, 2), 0.3)
        scene.collection.objects.link(inst)
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        exported, info = export_current()
        times.append(time.perf_counter() - t0)
    tris = sum(m.copies * len(m.mesh.triangles) for m in exported.meshes)
    assert tris == info.triangles >= 1_000_000
    assert info.meshes_evaluated == 2
    assert info.instanced_meshes == 1 and info.instanced_copies == 1000  # the rocks
    print(f"export of {tris} triangles ({info.instances} instances): "
          f"{min(times):.2f} s (best of 2), {times}")


# ------------------------------------------------------------------------------------------
# Bad scenes: a clear message naming the object and the property, never a traceback
# ------------------------------------------------------------------------------------------

def _no_camera(scene):
    add_sun(30)
    add_sea()


def _open_water_body(scene):
    add_camera()
    v = [(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)]
    f = [(0, 3, 2, 1), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]  # no lid
    add_mesh("Pool", v, f).photic.role = "WATER_BODY"


def _negative_iop(scene):
    add_camera()
    add_sea().photic.absorption_bands = "0.1, -0.2, 0.3"


def _nan_iop(scene):
    add_camera()
    add_sea().photic.scattering_bands = "nan"


def _band_count(scene):
    add_camera()
    add_sea().photic.absorption_bands = "0.1, 0.2"


def _sun_below(scene):
    add_camera()
    add_sea()
    add_sun(120)


def _empty(scene):
    add_camera()


def _array_empty(scene):
    add_camera()
    add_sea()
    arr = bpy.data.objects.new("Profile", None)
    scene.collection.objects.link(arr)
    arr.photic.role, arr.photic.array_count = "RADIOMETER_ARRAY", 0


def _array_no_quantity(scene):
    add_camera()
    add_sea()
    arr = bpy.data.objects.new("Profile", None)
    scene.collection.objects.link(arr)
    arr.photic.role, arr.photic.quantities = "RADIOMETER_ARRAY", set()


def _two_suns(scene):
    add_camera()
    add_sea()
    add_sun(30, name="Sun")
    add_sun(40, name="Sun2")


def _bad_bands(scene):
    add_camera()
    add_sea()
    scene.photic.bands, scene.photic.custom_bands = "CUSTOM", "450:20, green"


def _panoramic(scene):
    add_camera().data.type = "PANO"
    add_sea()


def _sun_too_large(scene):
    add_camera()
    add_sea()
    add_sun(30).data.angle = math.radians(45)


def _downward_patch(scene):
    add_camera()
    sea = add_sea()
    sea.photic.surface_shape = "MESH"
    sea.rotation_euler = (math.pi, 0, 0)  # upside down: normals point down


def _bad_reflectance(scene):
    add_camera()
    add_sea(depth=5.0)
    mat = bpy.data.materials.new("Sand")
    mat.photic.use_override, mat.photic.reflectance_bands = True, "0.3, 1.5, 0.2"
    bpy.data.objects["Sea"].photic.bottom_material = mat


def _pixel_aspect(scene):
    add_camera()
    add_sea()
    scene.render.pixel_aspect_x = 2.0


BAD_SCENES = [
    (_no_camera, ["Scene", "Camera", "no camera"]),
    (_open_water_body, ["Object 'Pool'", "not closed"]),
    (_negative_iop, ["Object 'Sea'", "Absorption per Band", "band 2", ">= 0"]),
    (_nan_iop, ["Object 'Sea'", "Scattering per Band", "nan"]),
    (_band_count, ["Object 'Sea'", "Absorption per Band", "2 values", "3 bands"]),
    (_sun_below, ["Light 'Sun'", "Rotation", "below the horizon"]),
    (_empty, ["Scene", "empty"]),
    (_array_empty, ["Object 'Profile'", "Layout", "no elements"]),
    (_array_no_quantity, ["Object 'Profile'", "Quantities", "at least one quantity"]),
    (_two_suns, ["Light 'Sun2'", "one sun lamp"]),
    (_bad_bands, ["Scene", "Bands", "band 2", "'green'"]),
    (_panoramic, ["Object 'Camera'", "Type", "panoramic"]),
    (_sun_too_large, ["Light 'Sun'", "Angle", "20"]),
    (_downward_patch, ["Object 'Sea'", "surface.triangles", "upwards"]),
    (_bad_reflectance, ["Material 'Sand'", "Reflectance per Band", "above 1"]),
    (_pixel_aspect, ["Scene", "Aspect", "non-square"]),
]


@pytest.mark.parametrize("build, expected", BAD_SCENES, ids=[b.__name__[1:] for b, _ in BAD_SCENES])
def test_bad_scene_gives_a_clear_message(empty, build, expected):
    build(empty)
    with pytest.raises(export.ExportError) as info:
        export_current()
    message = str(info.value)
    for text in expected:
        assert text in message, message


@pytest.mark.parametrize("build, expected", [BAD_SCENES[2], BAD_SCENES[5]],
                         ids=["negative_iop", "sun_below"])
def test_bad_scene_render_reports_and_blender_keeps_running(empty, build, expected):
    """Through the RenderEngine: the message is reported, no traceback reaches the user."""
    build(empty)
    final_render.LAST_RENDER.clear()
    try:
        bpy.ops.render.render()
    except RuntimeError as exc:  # the operator passes the engine's error report on
        assert all(t in str(exc) for t in expected[:2]), str(exc)
    assert all(t in final_render.LAST_RENDER["error"] for t in expected)
    assert "Traceback" not in final_render.LAST_RENDER["error"]
    bpy.ops.wm.read_homefile(use_empty=True)  # Blender is still usable


def test_addon_registers_and_explains_when_the_engine_is_missing(tmp_path):
    """Registration never needs the compiled core; the reason reaches the UI."""
    import subprocess
    import sys
    code = """
import sys
sys.modules['photic._core'] = None   # as if the compiled core failed to import
import bpy
from photic.cli import load_addon
addon = load_addon()
addon.register()
from photic_blender import engine_loader
assert engine_loader.load_engine() is None
msg = engine_loader.engine_error()
assert 'could not be imported' in msg and 'photic._core' in msg, msg
print('OK', msg)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "OK" in out.stdout


def test_scene_file_import_then_export_round_trips(empty, tmp_path):
    """File > Import then File > Export: the stepped pool survives the round trip (up to
    Blender's float32 geometry)."""
    from photic.scene import save_scene
    from photic.scenes import stepped_pool
    src = tmp_path / "pool.json"
    save_scene(stepped_pool(), src)
    assert bpy.ops.photic.import_scene(filepath=str(src)) == {"FINISHED"}
    out = tmp_path / "roundtrip.json"
    assert bpy.ops.photic.export_scene(filepath=str(out)) == {"FINISHED"}
    a, b = load_scene(src), load_scene(out)
    assert [w.name for w in a.water] == [w.name for w in b.water]
    ca, cb = a.cameras[0], b.cameras[0]
    np.testing.assert_allclose(ca.position, cb.position, atol=1e-6)
    np.testing.assert_allclose(ca.direction, cb.direction, atol=1e-6)
    assert cb.fov_deg == pytest.approx(ca.fov_deg, abs=1e-5)
    np.testing.assert_array_equal(a.water[0].iops.absorption, b.water[0].iops.absorption)
    np.testing.assert_array_equal(a.materials["tile"].reflectance, b.materials["tile"].reflectance)
    np.testing.assert_allclose(a.water[0].mesh.vertices, b.water[0].mesh.vertices, atol=1e-6)
    assert a.sun.zenith_deg == b.sun.zenith_deg and a.sun.azimuth_deg == b.sun.azimuth_deg
    np.testing.assert_allclose(a.sun.irradiance, b.sun.irradiance, rtol=1e-6)
    assert sum(len(m.mesh.triangles) for m in a.meshes) == sum(len(m.mesh.triangles) for m in b.meshes)


def test_export_reports_progress_and_can_be_cancelled(empty):
    add_camera()
    add_sun(30)
    rock = add_box("Rock", 0.2)
    for i in range(2500):
        dup = rock.copy()
        dup.location = (0.3 * (i % 50), 0.3 * (i // 50), 0)
        bpy.context.scene.collection.objects.link(dup)
    seen = []
    scene, info = export_current(progress=lambda f, text: seen.append(f))
    assert len(seen) >= 3 and seen[-1] == 1.0 and info.meshes_evaluated == 1
    calls = []

    def stop():
        calls.append(1)
        return len(calls) >= 2

    with pytest.raises(export.ExportCancelled):
        export_current(test_break=stop)
    assert len(calls) == 2  # polled every thousand instances, stopped at the second poll


def test_pure_water_iops_from_the_model(empty):
    """IOPs 'Pure Water + Additions': Pope & Fry absorption and pure-water scattering per band,
    plus the object's coefficients as a second (particle) component."""
    from photic.iop_models import pure_water_absorption, pure_seawater_scattering
    add_camera()
    sea = add_sea()
    sea.photic.iop_source = "PURE_WATER"
    sea.photic.absorption, sea.photic.scattering = 0.0, 0.1
    scene, _ = export_current()
    iops = scene.water[0].iops
    bands = [(b.center_nm, b.width_nm) for b in scene.bands]
    np.testing.assert_allclose(iops.absorption, pure_water_absorption(bands))
    assert iops.scattering[0].phase.type == "pure_water"
    np.testing.assert_allclose(iops.scattering[0].b, pure_seawater_scattering(bands))
    np.testing.assert_allclose(iops.scattering[1].b, 0.1)
    assert iops.absorption[0] > iops.absorption[2]  # red (620 nm) absorbed more than blue
    empty.photic.bands, empty.photic.custom_bands = "CUSTOM", "350:10"
    with pytest.raises(export.ExportError, match="outside the Pope & Fry"):
        export_current()


def test_wave_model_surface_previews_animates_and_exports(empty):
    """Surface shape 'Wave Model': the mesh previews the generated patch, follows the frame,
    and the export carries the model (at the frame's time) and the sub-pixel roughness."""
    scene = empty
    add_camera((0, -5, 3), (math.radians(60), 0, 0))
    add_sun(40)
    sea = add_sea()
    p = sea.photic
    p.wave_resolution, p.wave_patch_size, p.wind_speed = 16, 20.0, 6.0
    p.surface_shape = "WAVES"
    assert len(sea.data.vertices) == 17 * 17
    z0 = np.array([v.co.z for v in sea.data.vertices])
    assert z0.std() > 0.01
    scene.frame_set(25)
    z1 = np.array([v.co.z for v in sea.data.vertices])
    assert np.abs(z1 - z0).max() > 1e-3  # the waves moved
    p.use_roughness = True
    exported, _ = export_current()
    surf = exported.water[0].surface
    assert surf.kind == "waves" and surf.waves.resolution == (16, 16)
    assert surf.waves.time_s == pytest.approx(25 / scene.render.fps)
    assert surf.roughness.wind_speed == 6.0
    s2u, s2c, _ = surf.slope_variances(1.34)
    assert 0 < s2u + s2c < 0.003 + 5.12e-3 * 6.0  # Cox-Munk less the resolved slopes
    scene.photic.integrator, scene.photic.samples = "PATH", 1
    res = Renderer(exported, samples=1).run()
    assert np.isfinite(res.images["Camera"].mean).all() and res.images["Camera"].mean.mean() > 0
    # Mesh Refinement: exported with the model; the viewport keeps the grid's mesh
    p.wave_mesh_refinement = 4
    scene.frame_set(26)
    assert len(sea.data.vertices) == 17 * 17
    exported, _ = export_current()
    assert exported.water[0].surface.waves.mesh_refinement == 4
    assert len(exported.water[0].surface.patch()[0].triangles) == 2 * 64 * 64


def test_switching_wave_model_off_gives_the_object_its_mesh_back(empty):
    """Surface Shape Flat -> Wave Model -> Flat (and Mesh Patch): the object's own mesh, its
    vertices and its material, comes back; the preview mesh is removed; twice over."""
    sea = add_sea()
    mat = bpy.data.materials.new("SeaMat")
    sea.data.materials.append(mat)
    own = sea.data
    before = [tuple(v.co) for v in own.vertices]
    p = sea.photic
    p.wave_resolution, p.wave_patch_size = 8, 20.0
    for back in ("FLAT", "MESH"):
        p.surface_shape = "WAVES"
        assert sea.data is not own and len(sea.data.vertices) == 9 * 9
        assert list(sea.data.materials) == [mat]
        preview = sea.data.name
        p.wave_seed += 1  # a wave setting: the preview is regenerated, the own mesh kept
        assert sea.data.name == preview and [tuple(v.co) for v in own.vertices] == before
        p.surface_shape = back
        assert sea.data == own and [tuple(v.co) for v in sea.data.vertices] == before
        assert preview not in bpy.data.meshes and not own.use_fake_user
        assert p.flat_mesh is None


class RecordingLayout:
    """A stand-in UILayout that records prop() calls with the active state of their row."""

    def __init__(self, log=None, active=True):
        self.log = [] if log is None else log
        self.active, self.enabled = active, True
        self.use_property_split = False
        self.alignment = "EXPAND"

    def _sub(self, *a, **k):
        return RecordingLayout(self.log, self.active)

    column = row = box = split = _sub

    def __setattr__(self, name, value):
        if name == "active" and "log" in self.__dict__ and self.__dict__.get("active") is False:
            value = False  # a sub-layout of an inactive one stays inactive
        object.__setattr__(self, name, value)

    def prop(self, data, name, **k):
        self.log.append(("prop", name, self.active, k.get("text")))

    def label(self, text="", **k):
        self.log.append(("label", text, self.active, None))

    def operator(self, *a, **k):
        return type("Op", (), {})()


def test_per_band_lists_grey_out_the_value_they_override_and_show_the_band_order(empty):
    from photic_blender import ui
    sea = add_sea()
    q = sea.photic
    layout = RecordingLayout()
    ui._draw_iops(layout, q, "iop_source", "iop_model", "")
    active = {name: act for kind, name, act, _ in layout.log if kind == "prop"}
    assert active["absorption"] and active["scattering"]
    assert any(kind == "label" and "band order: 620, 550, 460 nm" in text for kind, text, _, _ in layout.log)
    q.absorption_bands = "0.1, 0.2, 0.3"
    layout = RecordingLayout()
    ui._draw_iops(layout, q, "iop_source", "iop_model", "")
    active = {name: act for kind, name, act, _ in layout.log if kind == "prop"}
    assert not active["absorption"] and active["scattering"]


def test_physical_properties_show_their_units_in_the_ui(empty):
    """Every property with a physical unit says it in its label (or has Blender's own unit)."""
    from photic_blender import properties as props
    wanted = {props.PhoticObjectProperties: {"absorption": "m\u207b\u00b9", "scattering": "m\u207b\u00b9",
                                             "absorption_bands": "m\u207b\u00b9", "wind_speed": "m/s",
                                             "unit_absorption": "m\u207b\u00b9", "chl_peak": "mg m\u207b\u00b3"},
              props.PhoticSceneProperties: {"band_center_nm": "nm", "band_width_nm": "nm", "custom_bands": "nm"},
              props.PhoticWorldProperties: {"radiance": "W m\u207b\u00b2 sr\u207b\u00b9"},
              props.PhoticLightProperties: {"irradiance_bands": "W m\u207b\u00b2"}}
    for cls, names in wanted.items():
        for name, unit in names.items():
            label = cls.bl_rna.properties[name].name
            assert unit in label, (cls.__name__, name, label)
    for name in ("wave_patch_size", "fetch", "wave_depth", "bottom_depth", "chl_peak_depth"):
        assert props.PhoticObjectProperties.bl_rna.properties[name].unit == "LENGTH", name


def test_wave_model_sinusoids_and_their_errors(empty):
    add_camera()
    sea = add_sea()
    p = sea.photic
    p.wave_resolution, p.wave_patch_size = 32, 20.0
    p.wave_spectrum, p.wave_sinusoids = "sinusoids", "0.05:10:0:0, 0.02:5:90"
    p.surface_shape = "WAVES"
    exported, _ = export_current()
    assert exported.water[0].surface.waves.sinusoids == ((0.05, 10.0, 0.0, 0.0), (0.02, 5.0, 90.0, 0.0))
    z = np.array([v.co.z for v in sea.data.vertices])
    assert z.max() == pytest.approx(0.07, abs=0.005)
    p.wave_sinusoids = "0.05:ten"
    with pytest.raises(export.ExportError, match="Sinusoids.*wave 1"):
        export_current()
    p.wave_sinusoids = "0.05:7"  # does not repeat over the 20 m patch
    with pytest.raises(export.ExportError, match="Object 'Sea'"):
        export_current()


def test_iop_model_description_on_a_water_object(empty):
    add_camera()
    sea = add_sea()
    sea.photic.iop_source = "MODEL"
    sea.photic.iop_model = '{"model": "cdom", "a_ref": 0.1, "slope": 0.014}'
    scene, _ = export_current()
    from photic.iop_models import iops_from_model
    expected = iops_from_model({"model": "cdom", "a_ref": 0.1, "slope": 0.014}, scene.bands)
    np.testing.assert_allclose(scene.water[0].iops.absorption, expected.absorption)
    sea.photic.iop_model = '{"model": "cdom", "a_ref": -1}'
    with pytest.raises(export.ExportError, match=r"Object 'Sea'.*IOP Model.*a_ref"):
        export_current()
    sea.photic.iop_model = '{"model": cdom}'
    with pytest.raises(export.ExportError, match="not valid JSON"):
        export_current()


class FakeLayout:
    """Records what a panel draws; every property it shows must exist on its data."""

    def __init__(self, shown):
        self.shown = shown
        self.use_property_split = False
        self.active = True
        self.alert = False

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, (data, name)
        self.shown.append(name)

    def column(self, **kw):
        return FakeLayout(self.shown)

    row = box = column

    def label(self, **kw):
        pass

    def operator(self, idname, **kw):
        category, name = idname.split(".")
        assert hasattr(getattr(bpy.ops, category), name), idname
        self.shown.append(idname)


@pytest.mark.parametrize("role", ["WATER_BODY", "WATER_SURFACE", "RADIOMETER", "RADIOMETER_ARRAY"])
def test_panels_draw_every_property_they_name(empty, role):
    from types import SimpleNamespace

    from photic_blender import ui
    add_camera()
    obj = add_sea()
    obj.photic.role = role
    mat = bpy.data.materials.new("M")
    world = bpy.data.worlds.new("W")
    empty.world = world
    shown = []
    for source, shape, quantity in (("VALUES", "FLAT", "radiance"), ("MODEL", "WAVES", "radiance_distribution"),
                                    ("PURE_WATER", "MESH", "Ed")):
        obj.photic.iop_source, obj.photic.quantity = source, quantity
        if role == "WATER_SURFACE":
            obj.photic.surface_shape = shape
        context = SimpleNamespace(engine="PHOTIC", scene=empty, object=obj, material=mat, world=world,
                                  light=bpy.data.lights.new("L", "SUN"))
        for cls in ui.classes:
            if cls.poll(context):
                cls.draw(SimpleNamespace(layout=FakeLayout(shown)), context)
    assert "role" in shown and "integrator" in shown and "sky_model" in shown
    assert "irradiance_bands" in shown and "auto_exposure" in shown


def test_unknown_variances_stay_infinite_in_the_display_passes():
    """A pixel with fewer than 2 samples has variance inf: the Variance pass shows inf in the
    channels its bands weigh in, never NaN (inf times a zero weight)."""
    from photic_blender.bands import bands_to_rgba
    bands = [(f"{c}", float(c), 10.0) for c in range(400, 701, 30)]
    var = np.full((2, 3, len(bands)), 0.01)
    var[0, 1, :] = np.inf
    out = bands_to_rgba(var, bands, variance=True)
    assert not np.any(np.isnan(out))
    assert np.all(np.isinf(out[0, 1, :3])) and np.all(np.isfinite(out[1, :, :3]))


def test_sun_panel_per_band_irradiance_and_clear_sky_helper(empty):
    """The Light tab shows a Photic Sun panel (irradiance with its unit, colour, a per-band
    list that overrides both, the band order, the angular diameter, the Clear-Sky Sun helper);
    the per-band list is what exports; the helper points the lamp at the sun of a place and time
    with the clear sky's band-averaged direct irradiance (photic.solar)."""
    from datetime import datetime, timedelta, timezone

    from photic import solar
    from photic_blender import ui
    assert ui.PHOTIC_PT_light.bl_context == "data" and hasattr(bpy.types, "PHOTIC_PT_light")
    add_camera()
    obj = add_sun()
    bpy.context.view_layer.objects.active = obj
    light = obj.data
    light.energy, light.color = 2.0, (1.0, 0.5, 0.25)
    sun = export_current()[0].sun
    assert np.allclose(sun.irradiance, [2.0, 1.0, 0.5], rtol=1e-6)  # R, G, B bands
    light.photic.irradiance_bands = "1.3, 1.4, 1.5"
    assert np.allclose(export_current()[0].sun.irradiance, [1.3, 1.4, 1.5])
    light.photic.irradiance_bands = "1.3, x"
    with pytest.raises(export.ExportError, match=r"Irradiance per Band .*item 2"):
        export_current()
    light.photic.irradiance_bands = ""
    assert bpy.ops.photic.clear_sky_sun(latitude=43.3, longitude=5.4, year=2026, month=6, day=21,
                                        hour_utc=11.0, aerosol_beta=0.05) == {"FINISHED"}
    when = datetime(2026, 6, 21, tzinfo=timezone.utc) + timedelta(hours=11.0)
    zenith, azimuth = solar.solar_position(43.3, 5.4, when)
    sun = export_current()[0].sun
    assert sun.zenith_deg == pytest.approx(zenith, abs=1e-3)
    assert sun.azimuth_deg == pytest.approx(azimuth, abs=1e-3)
    assert sun.angular_diameter_deg == pytest.approx(0.53, abs=1e-4)
    expected = [np.mean(solar.clear_sky_direct(np.linspace(c - w / 2, c + w / 2, 9), zenith, 0.05,
                                               day_of_year=172))
                for c, w in ((620.0, 80.0), (550.0, 60.0), (460.0, 80.0))]
    assert np.allclose(sun.irradiance, expected, rtol=1e-3)
    # a sun spectrum that Strength and Color cannot hold (five bands) imports into the list
    empty.photic.bands, empty.photic.custom_bands = "CUSTOM", "420, 470, 520, 570, 620"
    with pytest.raises(export.ExportError, match="has 3 values but the scene has 5 bands"):
        export_current()  # the helper's list was for the three RGB bands
    light.photic.irradiance_bands = ""
    sc = export_current()[0]
    sc.sun.irradiance = np.array([1.1, 1.2, 1.3, 1.25, 1.15])
    path = Path(bpy.app.tempdir) / "sun_bands.json"
    photic.scene.save_scene(sc, path)
    bpy.data.objects.remove(obj)
    assert bpy.ops.photic.import_scene(filepath=str(path)) == {"FINISHED"}
    suns = [o for o in bpy.data.objects if o.type == "LIGHT"]
    assert len(suns) == 1 and suns[0].data.photic.irradiance_bands.strip()
    assert np.allclose(export_current()[0].sun.irradiance, [1.1, 1.2, 1.3, 1.25, 1.15])


def test_auto_exposure_sets_the_display_not_the_values(empty, tmp_path):
    """Auto Exposure (on by default): after a render the scene's display exposure shows the
    image's key (geometric-mean luminance) as mid-grey, whatever the sun's strength, and the
    saved EXR holds the same radiometric values as with it off."""
    import OpenEXR

    from photic_blender.bands import auto_exposure
    assert auto_exposure(np.full((4, 4, 3), 0.18)) == 0.0
    assert auto_exposure(np.full((4, 4, 3), 0.045)) == 2.0
    assert auto_exposure(np.zeros((4, 4, 3))) is None
    assert empty.photic.auto_exposure
    add_camera()
    add_mesh("Ground", [(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [(0, 1, 2, 3)])
    sun = add_sun()
    empty.photic.samples = 2
    empty.render.image_settings.file_format = "OPEN_EXR"
    values = {}
    for energy, auto in ((0.01, True), (100.0, True), (0.01, False)):
        sun.data.energy = energy
        empty.photic.auto_exposure = auto
        empty.view_settings.exposure = 0.0
        empty.render.filepath = str(tmp_path / f"e{energy}_{auto}_")
        bpy.ops.render.render(write_still=True)
        values[(energy, auto)] = empty.view_settings.exposure
        exr = next(tmp_path.glob(f"e{energy}_{auto}_*.exr"))
        with OpenEXR.File(str(exr)) as f:
            ch = f.parts[0].channels
            key = next(k for k in ch if "Combined" in k or k in ("RGBA", "R"))
            values[("exr", energy, auto)] = np.asarray(ch[key].pixels, float)
    assert values[(0.01, True)] > 5.0 and values[(100.0, True)] < -5.0
    assert values[(0.01, True)] - values[(100.0, True)] == pytest.approx(math.log2(1e4), abs=0.2)
    assert values[(0.01, False)] == 0.0
    assert np.array_equal(values[("exr", 0.01, True)], values[("exr", 0.01, False)])


def add_radiometer(name, location, quantity="Ed"):
    obj = bpy.data.objects.new(name, None)
    obj.location = location
    obj.photic.role, obj.photic.quantity = "RADIOMETER", quantity
    bpy.context.scene.collection.objects.link(obj)
    return obj


def radiometer_only_file(tmp_path, empty):
    """A sea 5 m deep under a sun, two Ed radiometers, no camera, saved as a .blend."""
    add_sea(depth=5.0)
    add_sun()
    add_radiometer("Ed1", (0.0, 0.0, -1.0))
    add_radiometer("Ed3", (0.0, 0.0, -3.0))
    empty.photic.radiometer_samples = 4096
    path = tmp_path / "rads.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_render_radiometers_without_a_camera(empty, tmp_path):
    """Render > Render Radiometers on a scene without a camera (F12 refuses it): the engine's
    numbers for the same scene, tables beside the .blend as <file>_<frame>_radiometers (the
    output path being Blender's temporary folder), the results panel filled; with an output
    path, beside the image's stem; the headless equivalents (batch, photic blend)."""
    from photic.cli import main
    from photic_blender.final_render import LAST_RADIOMETERS, table_stem
    path = radiometer_only_file(tmp_path, empty)
    frame = empty.frame_current
    assert empty.camera is None
    assert bpy.ops.photic.render_radiometers() == {"FINISHED"}
    csv = tmp_path / f"rads_{frame:04d}_radiometers.csv"
    assert csv.exists(), list(tmp_path.iterdir())
    rows = LAST_RADIOMETERS[empty.name]["rows"]
    direct = Renderer(export_current()[0]).run()
    assert [r["value"] for r in rows] == [r.mean[0].tolist() for r in direct.radiometers]
    empty.render.filepath = "//out/run_####"
    assert table_stem(empty) == (tmp_path / "out", f"run_{frame:04d}")
    summary = render_blend(path, out_dir=tmp_path / "b", radiometer_samples=2048)
    assert summary["image"] is None and summary["radiometers"] == 2
    assert Path(summary["tables"][0]).name == f"rads_{frame:04d}_radiometers.csv"
    assert main(["blend", str(path), "--out", str(tmp_path / "c"), "--radiometer-samples", "1024",
                 "--quiet"]) == 0
    assert (tmp_path / "c" / f"rads_{frame:04d}_radiometers.json").exists()


def test_a_cancelled_render_writes_no_empty_tables(empty, tmp_path):
    """Cancelled before any radiometer took a sample: no tables (they would read 0 +- 0), a
    warning; the engine leaves such radiometers out of its result; a partial result's CSV
    says CANCELLED."""
    from types import SimpleNamespace

    from photic_blender.final_render import write_radiometer_results
    radiometer_only_file(tmp_path, empty)
    scene = export_current()[0]
    scene.cameras = []
    r = Renderer(scene, radiometer_samples=1 << 20)
    r.cancel()
    res = r.run()
    assert res.cancelled and res.radiometers == []
    messages = []
    assert write_radiometer_results(photic, res, empty, lambda lvl, t: messages.append(t)) == []
    assert messages and "cancelled before any radiometer" in messages[0]
    done = Renderer(scene, radiometer_samples=1024).run()
    done.cancelled = True
    empty.render.filepath = str(tmp_path / "part_####")
    paths = write_radiometer_results(photic, done, empty, lambda lvl, t: None)
    assert Path(paths[0]).read_text().startswith("# CANCELLED")


def test_a_table_that_cannot_be_written_is_kept_elsewhere_and_said(empty, tmp_path):
    """Issue 49, kind 2: a folder where the JSON table goes: the CSV and derived tables are
    written, the JSON into a rescue folder, and the warning says where."""
    from photic_blender.final_render import write_radiometer_results
    radiometer_only_file(tmp_path, empty)
    scene = export_current()[0]
    scene.cameras = []
    done = Renderer(scene, radiometer_samples=1024).run()
    empty.render.filepath = str(tmp_path / "out" / "t_####")
    from photic_blender.final_render import table_stem
    out_dir, stem = table_stem(empty)
    (Path(out_dir) / f"{stem}_radiometers.json").mkdir(parents=True)
    messages = []
    paths = write_radiometer_results(photic, done, empty, lambda lvl, t: messages.append((lvl, t)))
    assert any(p.endswith("_radiometers.csv") for p in paths)
    kept = [p for p in paths if "photic-rescue-" in p]
    assert len(kept) == 1 and kept[0].endswith(f"{stem}_radiometers.json") and Path(kept[0]).is_file()
    assert any(lvl == "WARNING" and f"kept in {kept[0]}" in text for lvl, text in messages), messages


def test_noise_figure_matches_the_measured_error():
    """The stats line's error is the image's RMS standard error over its mean: at 16 spp on the
    stepped pool it matches the error measured between two independent renders (RMS of their
    difference / sqrt 2, over the mean) within the band of honest errors, where the old median
    over pixels said 0 %; with 1 sample per pixel it says it cannot tell."""
    from photic.render import render
    from photic.scenes import stepped_pool
    from photic_blender.final_render import image_relative_error
    sc = stepped_pool(resolution=(48, 48))
    sc.cameras = [c for c in sc.cameras if c.name == "under"]
    a = render(sc, samples=16, seed=1, threads=2).images["under"]
    b = render(sc, samples=16, seed=2, threads=2).images["under"]
    measured = float(np.sqrt(np.mean((a.mean - b.mean) ** 2) / 2) / np.mean(0.5 * (a.mean + b.mean)))
    reported = image_relative_error(a)
    assert 0.7 <= reported / measured <= 1.5, (reported, measured)
    assert image_relative_error(render(sc, samples=1, seed=1, threads=2).images["under"]) is None


# ------------------------------------------------------------------------------------------
# docs/blender.md's tutorial, step by step
# ------------------------------------------------------------------------------------------

def test_the_tutorial_from_an_empty_scene(tmp_path):
    """The tutorial's ten steps through bpy, as the UI does them (the default file with its
    cube; operators where the UI uses them), at 96 x 54 and 4 spp: a denoised image with
    its passes and radiometer tables beside the output."""
    ensure_registered()
    bpy.ops.wm.read_homefile()                       # 1. File > New > General (the cube stays)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 96, 54
    scene.render.resolution_percentage = 100
    for o in [o for o in scene.objects if o.type in ("CAMERA", "LIGHT")]:
        bpy.data.objects.remove(o)                   # (the tutorial adds its own)
    bpy.ops.mesh.primitive_plane_add(size=20)        # 2. the sea surface
    sea = bpy.context.object
    p = sea.photic
    p.role = "WATER_SURFACE"
    p.surface_shape = "WAVES"
    p.wave_spectrum, p.wind_speed, p.wave_patch_size, p.wave_resolution = "jonswap", 6.0, 20.0, 64
    assert len(sea.data.vertices) == 65 * 65
    p.absorption, p.scattering, p.phase_function = 0.05, 0.15, "petzold"
    p.use_bottom, p.bottom_depth = True, 6.0
    sand = bpy.data.materials.new("Sand")            # 3. sand and objects
    sand.diffuse_color = (0.45, 0.40, 0.30, 1.0)
    if sand.node_tree is None:  # (Blender 5 materials have their nodes from the start)
        sand.use_nodes = True
    if sand.node_tree is not None:
        bsdf = next(n for n in sand.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
        bsdf.inputs["Base Color"].default_value = (0.45, 0.40, 0.30, 1.0)
    sea.data.materials.append(sand)
    p.bottom_material = sand
    bpy.data.objects["Cube"].location.z = -5.0
    bpy.ops.object.light_add(type="SUN")              # 4. the sun, clear sky at a place and time
    sun = bpy.context.object
    assert bpy.ops.photic.clear_sky_sun(latitude=43.3, longitude=5.4, month=6, day=21,
                                        hour_utc=11.0) == {"FINISHED"}
    assert sun.data.photic.irradiance_bands.count(",") == 2
    sun.data.angle = math.radians(0.53)
    if scene.world is None:                          # 5. the sky
        scene.world = bpy.data.worlds.new("World")
    scene.world.photic.sky_model = "CARDIOIDAL"
    bpy.ops.object.camera_add(location=(0, -8, -3), rotation=(math.radians(80), 0, 0))
    scene.camera = bpy.context.object                # 6. the camera under water
    bpy.ops.object.empty_add(location=(3, 0, -2))     # 7. radiometers
    bpy.context.object.photic.role = "RADIOMETER"
    bpy.context.object.photic.quantity = "Ed"
    bpy.ops.object.empty_add(location=(3, 0, -0.5))
    arr = bpy.context.object.photic
    arr.role, arr.quantities, arr.array_layout = "RADIOMETER_ARRAY", {"Ed", "Eu", "Eo"}, "LINE"
    arr.array_count, arr.array_spacing = 5, 1.0
    q = scene.photic                                  # 8. render settings
    q.integrator, q.samples, q.radiometer_samples, q.denoise, q.auto_exposure = "HYBRID", 4, 4096, True, True
    scene.render.filepath = str(tmp_path / "tutorial_")
    final_render.LAST_RENDER.clear()
    bpy.ops.render.render()                           # 9. F12
    summary = dict(final_render.LAST_RENDER)
    assert summary["error"] is None, summary
    assert summary.get("denoise_s", 0) > 0
    rows = final_render.LAST_RADIOMETERS[scene.name]["rows"]
    assert len(rows) == 1 + 5 * 3
    ed = [r for r in rows if r["quantity"] == "Ed"]
    assert all(v > 0 for r in ed for v in r["value"])
    assert all(r["medium"] == "Plane" for r in rows)  # (the medium is named after its object)
    tables = sorted(tmp_path.glob("tutorial_*_radiometers.csv"))
    assert tables, list(tmp_path.iterdir())
    image = tmp_path / "tutorial.exr"                 # 10. save, every pass
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    bpy.data.images["Render Result"].save_render(filepath=str(image), scene=scene)
    channels = exr_channels(image)
    for name in ("Combined", "Noisy Image", "Denoising Albedo", "Photic Beam Surface", "Photic Variance"):
        assert f"ViewLayer.{name}.R" in channels or f"ViewLayer.{name}.X" in channels, (name, sorted(channels))
    combined = np.stack([channels[f"ViewLayer.Combined.{c}"] for c in "RGB"], -1)
    assert np.isfinite(combined).all() and combined.mean() > 0


def test_photic_blend_is_the_add_on_packages_command(tmp_path, capsys):
    """photic blend hands its arguments to the add-on package's photic-blend (the engine
    imports no Blender): help, and a radiometers-only render of an example."""
    from photic.cli import main
    with pytest.raises(SystemExit) as e:
        main(["blend", "--help"])
    assert e.value.code == 0 and "photic-blend" in capsys.readouterr().out
    assert main(["blend", str(BLENDS / "canonical_problem2.blend"), "--out", str(tmp_path),
                 "--radiometer-samples", "1024", "--radiometers-only", "--quiet"]) == 0
    assert any(p.name.endswith("_radiometers.csv") for p in tmp_path.iterdir())


# Blender property -> (parameter, scale from the property's unit to the parameter's, and why
# Blender's own range may be narrower than the declared one)
ADDON_PARAMETERS = [
    ("PhoticSceneProperties", "samples", "settings.samples", 1.0, None),
    ("PhoticSceneProperties", "radiometer_samples", "settings.radiometer_samples", 1.0, "int32"),
    ("PhoticSceneProperties", "seed", "settings.seed", 1.0, "int32"),
    ("PhoticSceneProperties", "threads", "settings.threads", 1.0, None),
    ("PhoticSceneProperties", "max_depth", "settings.max_depth", 1.0, None),
    ("PhoticSceneProperties", "beam_max_level", "settings.beam_max_level", 1.0, None),
    ("PhoticSceneProperties", "adaptive_min_samples", "settings.adaptive_min_samples", 1.0, None),
    ("PhoticSceneProperties", "forward_cone_angle", "settings.forward_cone_deg", 180.0 / math.pi, None),
    ("PhoticSceneProperties", "target_error", "settings.target_error", 0.01, "percent"),
    ("PhoticSceneProperties", "noise_threshold", "settings.noise_threshold", 0.01, "percent"),
    ("PhoticObjectProperties", "ior", "water.ior", 1.0, None),
    ("PhoticSceneProperties", "band_center_nm", "band.center_nm", 1.0, None),
    ("PhoticSceneProperties", "band_width_nm", "band.width_nm", 1.0, None),
    ("PhoticMaterialProperties", "reflectance", "material.reflectance", 1.0, None),
    ("PhoticObjectProperties", "absorption", "iops.absorption", 1.0, "float max"),
    ("PhoticObjectProperties", "scattering", "scattering_component.b", 1.0, "float max"),
    ("PhoticObjectProperties", "unit_absorption", "iops.absorption", 1.0, "float max"),
    ("PhoticObjectProperties", "unit_scattering", "scattering_component.b", 1.0, "float max"),
    ("PhoticGridField", "unit_absorption", "iops.absorption", 1.0, "float max"),
    ("PhoticGridField", "unit_scattering", "scattering_component.b", 1.0, "float max"),
    ("PhoticObjectProperties", "hg_g", "phase.g", 1.0, None),
    ("PhoticObjectProperties", "unit_hg_g", "phase.g", 1.0, None),
    ("PhoticGridField", "unit_hg_g", "phase.g", 1.0, None),
    ("PhoticObjectProperties", "ff_backscatter", "phase.backscatter_fraction", 1.0, None),
    ("PhoticObjectProperties", "unit_ff_backscatter", "phase.backscatter_fraction", 1.0, None),
    ("PhoticGridField", "unit_ff_backscatter", "phase.backscatter_fraction", 1.0, None),
    ("PhoticObjectProperties", "bottom_depth", "bottom.depth", 1.0, "open end"),
    # one wind for the roughness (0-50 m/s, Cox-Munk's fit) and the waves (any speed)
    ("PhoticObjectProperties", "wind_speed", "surface.roughness.wind_speed", 1.0, None),
    ("PhoticObjectProperties", "wind_speed", "surface.wind_speed", 1.0, "shared with roughness"),
    ("PhoticObjectProperties", "wave_patch_size", "surface.patch_size_m", 1.0, "a preview"),
    ("PhoticObjectProperties", "wave_resolution", "surface.resolution", 1.0, "a preview"),
    ("PhoticObjectProperties", "wave_seed", "surface.seed", 1.0, "int32"),
    ("PhoticObjectProperties", "wave_mesh_refinement", "surface.mesh_refinement", 1.0, None),
    ("PhoticObjectProperties", "choppiness", "surface.choppiness", 1.0, "folds beyond"),
    ("PhoticObjectProperties", "fetch", "surface.fetch_m", 1.0, "open end"),
    ("PhoticObjectProperties", "wave_depth", "surface.water_depth_m", 1.0, "0 is deep water"),
    ("PhoticWorldProperties", "radiance", "sky.radiance", 1.0, None),
    ("PhoticObjectProperties", "half_angle", "radiometer.half_angle_deg", 180.0 / math.pi, None),
    ("PhoticObjectProperties", "polar_bins", "radiometer.polar_bins", 1.0, "a table"),
    ("PhoticObjectProperties", "azimuth_bins", "radiometer.azimuth_bins", 1.0, "a table"),
]


@pytest.mark.parametrize("cls, prop, key, scale, narrower", ADDON_PARAMETERS,
                         ids=[f"{a[1]}-{a[2]}" for a in ADDON_PARAMETERS])
def test_addon_property_limits_agree_with_the_declared_parameters(empty, cls, prop, key, scale, narrower):
    """The add-on's hard limits equal the declaration (photic/parameters.py): a value Blender
    takes that the engine refuses is a bug. Where there is a reason (Blender's 32-bit integers,
    a percentage, an open end Blender cannot hold, no upper limit where Blender's float has
    one, a preview regenerated on every edit) they lie inside it instead; 'deep water' is a
    0 that means 'none'. Defaults equal where both have one."""
    from photic.parameters import PARAMETERS
    from photic_blender import properties as props
    from photic_blender.export_values import blender_float
    p = PARAMETERS[key]
    rna = getattr(props, cls).bl_rna.properties[prop]
    # (as the export reads them: float32 to the 7 digits typed; 90 degrees in radians is not)
    lo, hi = (blender_float(x * scale) if rna.type == "FLOAT" else x * scale
              for x in (rna.hard_min, rna.hard_max))
    if narrower is None:
        assert lo == pytest.approx(p.lo, rel=1e-6) and hi == pytest.approx(p.hi, rel=1e-6), (prop, lo, hi, p)
    elif narrower == "0 is deep water":
        assert lo == 0 and p.contains(hi), (prop, lo, hi, p)
    elif narrower == "float max":  # no upper limit: Blender's largest float
        assert lo == pytest.approx(p.lo) and p.hi is None and hi > 1e38, (prop, lo, hi, p)
    else:
        assert p.contains(lo) and p.contains(hi), (prop, lo, hi, p)
    if p.default is not None and not isinstance(p.default, str) and narrower != "percent":
        default = p.default[0] if isinstance(p.default, list) else p.default  # a square patch
        assert rna.default * scale == pytest.approx(default, rel=1e-6), (prop, rna.default, p.default)


# ------------------------------------------------------------------------------------------
# Transforms and texts that are not numbers (issue 49, kind 8)
# ------------------------------------------------------------------------------------------

NAN = float("nan")  # (Blender stores an infinity as the largest float: a size, not a NaN)


@pytest.mark.parametrize("what, attr, value, field", [
    ("box", "scale", (NAN, 1, 1), "Scale (scale)"),
    ("box", "scale", (1, NAN, 1), "Scale (scale)"),
    ("box", "location", (0, NAN, 0), "Location (location)"),
    ("box", "rotation_euler", (NAN, 0, 0), "Rotation (rotation_euler)"),
    ("box", "delta_scale", (1, 1, NAN), "Delta Scale (delta_scale)"),
    ("sea", "scale", (NAN, NAN, NAN), "Scale (scale)"),
    ("sun", "rotation_euler", (NAN, 0, 0), "Rotation (rotation_euler)"),
    ("sun", "scale", (NAN, 1, 1), "Scale (scale)"),
    ("camera", "rotation_euler", (0, NAN, 0), "Rotation (rotation_euler)"),
    ("camera", "location", (NAN, 0, 0), "Location (location)"),
])
def test_a_transform_that_is_not_a_number_names_its_field(empty, what, attr, value, field):
    """A NaN scale dropped the object silently ('zero-area triangles'); a NaN sun rotation
    said 'Scale: is zero'. Now the error names the object and the transform field."""
    cam = add_camera()
    sea = add_sea()
    sun = add_sun()
    box = add_box("Rock", location=(0, 0, -2))
    target = {"box": box, "sea": sea, "sun": sun, "camera": cam}[what]
    setattr(target, attr, value)
    with pytest.raises(export.ExportError) as info:
        export_current()
    message = str(info.value)
    owner = f"Light '{target.name}'" if what == "sun" else f"Object '{target.name}'"
    assert owner in message and field in message and "not a finite number" in message, message
    assert "zero" not in message, message


def test_a_child_of_a_parent_with_a_nan_scale_names_the_parent(empty):
    add_camera()
    add_sea()
    parent = add_box("Parent", location=(0, 0, -3))
    child = add_box("Child", location=(1, 0, -3))
    child.parent = parent
    parent.scale = (NAN, 1, 1)
    with pytest.raises(export.ExportError, match=r"Object '(Parent|Child)'.*not a finite number"):
        export_current()


@pytest.mark.parametrize("depth", [200, 5000, 100000])
def test_a_deeply_nested_iop_model_text_is_a_clear_error(empty, depth):
    add_camera()
    sea = add_sea()
    sea.photic.iop_source = "MODEL"
    sea.photic.iop_model = '{"model": "cdom", "a_ref": ' + "[" * depth + "]" * depth + "}"
    with pytest.raises(export.ExportError) as info:
        export_current()
    message = str(info.value)
    assert "Object 'Sea'" in message and "IOP Model" in message, message
    assert "RecursionError" not in message and "internal error" not in message, message


def test_opening_a_photic_file_imports_the_engine_ahead():
    """A file whose scene renders with Photic starts the engine's import in the background
    (the first viewport image or render then does not wait for it); a file that renders with
    another engine does not. In a fresh process, where nothing imported the core yet."""
    import subprocess
    import sys
    code = f"""
import sys
import bpy
from photic.cli import load_addon
addon = load_addon()
addon.register()
from photic_blender import engine_loader
assert 'photic._core' not in sys.modules
bpy.ops.wm.read_homefile(use_empty=True)   # another engine: nothing imported
assert bpy.context.scene.render.engine != 'PHOTIC'
assert engine_loader._warming is None and 'photic._core' not in sys.modules
bpy.ops.wm.open_mainfile(filepath={str(BLENDS / "stepped_pool.blend")!r})
assert engine_loader._warming is not None
engine_loader._warming.join(60)
assert 'photic._core' in sys.modules and engine_loader.load_engine() is not None
print('OK')
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "OK" in out.stdout
