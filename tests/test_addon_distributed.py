"""Blender renders sent to a Dask scheduler (Scene.photic.dask_scheduler): the merged result
streams into the render view and equals a render on this computer bit for bit."""
from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pytest

import bpy  # noqa: F401  (a requirement, as in test_addon.py)

from photic.cli import load_addon

load_addon()
from photic_blender import final_render  # noqa: E402
from photic_blender.batch import ensure_registered  # noqa: E402

distributed = pytest.importorskip("distributed")


class Engine:
    """The RenderEngine methods FinalRender calls (no Esc)."""

    def __init__(self):
        self.updates, self.reports, self.final = 0, [], None

    def test_break(self):
        return False

    def begin_result(self, x, y, w, h):
        class Pass:
            rect = None

        class Layer:
            passes = {name: Pass() for name in ("Combined", *final_render.PASS_NAMES)}

        class Result:
            layers = [Layer()]

        return Result()

    def update_result(self, result):
        self.updates += 1

    def end_result(self, result):
        self.final = {n: np.array(p.rect) for n, p in result.layers[0].passes.items()}

    def update_progress(self, f):
        pass

    def update_stats(self, stats, info):
        self.stats = info

    def report(self, kind, message):
        self.reports.append((kind, message))

    def error_set(self, message):
        self.reports.append(({"ERROR"}, message))


def _scene():
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 48, 32
    scene.render.resolution_percentage = 100
    p = scene.photic
    p.samples, p.radiometer_samples, p.seed, p.write_tables = 16, 8192, 5, False
    mesh = bpy.data.meshes.new("Sea")
    mesh.from_pydata([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [], [(0, 1, 2, 3)])
    sea = bpy.data.objects.new("Sea", mesh)
    scene.collection.objects.link(sea)
    sea.photic.role = "WATER_SURFACE"
    sea.photic.scattering = 0.5
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -5, 1), (math.radians(80), 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.rotation_euler = (math.radians(30), 0, math.radians(90))
    scene.collection.objects.link(sun)
    rad = bpy.data.objects.new("Ed", None)
    rad.location = (0, 0, -1)
    scene.collection.objects.link(rad)
    rad.photic.role = "RADIOMETER"
    rad.photic.quantity = "Ed"
    return scene


def test_render_on_a_dask_scheduler_streams_and_equals_a_local_render(tmp_path, monkeypatch):
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))  # the add-on's unit cache
    scene = _scene()
    local_engine = Engine()
    local = final_render.FinalRender(local_engine, bpy.context.evaluated_depsgraph_get()).run()
    assert local["error"] is None
    local_rows = final_render.LAST_RADIOMETERS[scene.name]["rows"]

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, silence_logs=logging.CRITICAL) as cluster:
        scene.photic.dask_scheduler = cluster.scheduler_address
        scene.update_tag()  # F12 evaluates a fresh depsgraph; this one must see the change
        engine = Engine()
        summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["error"] is None, engine.reports
    assert summary["distributed"]["computed"] == summary["distributed"]["units"] > 3
    assert summary["samples"] == local["samples"] == 16
    assert summary["updates"] >= 1  # merged units streamed into the render view
    for name, pixels in local_engine.final.items():
        assert np.array_equal(pixels, engine.final[name]), name
    rows = final_render.LAST_RADIOMETERS[scene.name]["rows"]
    assert rows == local_rows and rows[0]["value"][0] > 0

    # A scheduler that cannot be reached is reported, and Blender goes on.
    monkeypatch.setattr(final_render, "DASK_CONNECT_TIMEOUT_S", 1.0)
    scene.photic.dask_scheduler = "tcp://127.0.0.1:9"
    scene.update_tag()
    engine = Engine()
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert summary["error"] and "Dask scheduler" in summary["error"]

    # Another machine over plain tcp:// only with the user's consent; tls:// and a tunnel
    # to 127.0.0.1 need none; a web address is refused at once.
    refusal = final_render.remote_scheduler_refusal
    assert "Allow Unencrypted Remote Scheduler" in refusal("tcp://10.0.0.5:8786", False)
    assert refusal("tcp://10.0.0.5:8786", True) is None
    assert refusal("tls://10.0.0.5:8786", False) is None
    assert refusal("tcp://127.0.0.1:8786", False) is None and refusal("localhost:8786", False) is None
    assert "web address" in refusal("http://127.0.0.1:8787", False)
    scene.photic.dask_scheduler = "tcp://10.0.0.5:8786"
    scene.update_tag()
    engine = Engine()
    summary = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    assert "Allow Unencrypted Remote Scheduler" in summary["error"]


def test_job_with_blend_frames_exports_each_frame_as_f12_would(tmp_path):
    """A .blend input of a job: each frame exported through the render engine (here in this
    process), then rendered from the plain scene like any other item."""
    from photic.distributed import parse_job, run_job
    from photic.scene import load_scene

    blends = Path(__file__).resolve().parents[1] / "example_blends"
    doc = {"photic_job": 1, "name": "blend", "samples": 1, "radiometer_samples": 4096,
           "inputs": [{"blend": "canonical_problem2.blend", "frames": [1, 2]}]}
    job = parse_job(doc, blends)
    assert [it.name for it in job.items] == ["canonical_problem2_f0001", "canonical_problem2_f0002"]
    reference = load_scene(blends / "canonical_problem2.json")
    for item in job.items:
        assert [r.name for r in item.scene.all_radiometers()] == [r.name for r in reference.all_radiometers()]
        assert item.scene.water == reference.water and item.scene.sun == reference.sun
    report = run_job(job, tmp_path, workers=0, progress=False)
    assert report.ok and all((tmp_path / "results" / it.name).is_dir() for it in job.items)
