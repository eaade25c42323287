"""Distributed rendering (photic.distributed, `photic batch`): work units merge exactly, the
same job gives the same numbers bit for bit in one process and on a local Dask cluster of two
worker processes, also when a worker is killed mid-job, and a restarted job redoes no
finished unit."""
from __future__ import annotations

import json
import logging
import os
import signal
from pathlib import Path

import numpy as np
import pytest

from photic.distributed import JobError, load_job, parse_job, run_job
from photic.distributed.job import rounds_needed
from photic.distributed.store import UnitStore
from photic.distributed.units import ItemMerger, merge_order, plan_round, tile_rects
from photic.render import render

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "coastal_shelf.json"

# Two items (sun zenith 20 and 50 deg) of the coastal shelf at a small size: 24 x 16 pixels,
# 4 samples per pixel (camera passes of 1, 2 and 1 samples: 3 units), 12 radiometers of
# 8,192 samples (8 hybrid passes, 4 per unit): 27 units of ~0.05-0.2 s per item.
JOB = {"photic_job": 1, "name": "tiny",
       "inputs": [str(EXAMPLE)],
       "set": {"cameras.diver.resolution": [24, 16]},
       "sweep": {"sun.zenith_deg": [20, 50]},
       "samples": 4, "radiometer_samples": 8192, "seed": 11,
       "units": {"radiometer_passes": 4}}


def _job(**changes):
    doc = json.loads(json.dumps(JOB))
    doc.update(changes)
    return parse_job(doc, ROOT)


def _arrays(out: Path) -> dict:
    """Every number of a batch's merged results, from its unit files: {key: array}."""
    job = _job()
    store = UnitStore(out)
    found = {}
    for item in job.items:
        merger = ItemMerger(item)
        for u in merge_order(plan_round(item, job, 0)):
            res = store.read(u, item.fingerprint)
            assert res is not None, f"unit {u.id} of {item.name} missing or invalid"
            merger.add(u, res, job)
        result = merger.result()
        for name, img in result.images.items():
            found[f"{item.name}/{name}/mean"] = img.mean
            found[f"{item.name}/{name}/variance"] = img.variance
        for r in result.radiometers:
            found[f"{item.name}/{r.name}/mean"] = r.mean
            found[f"{item.name}/{r.name}/stderr"] = r.stderr
    return found


def _assert_identical(a: dict, b: dict) -> None:
    assert a.keys() == b.keys() and a
    for k in a:
        assert np.array_equal(a[k], b[k]), f"{k} differs"


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    """The job run in this process (no Dask): the reference of the cluster runs."""
    out = tmp_path_factory.mktemp("serial")
    report = run_job(_job(), out, workers=0, progress=False)
    assert report.ok and not report.skipped
    return out, report, _arrays(out)


@pytest.fixture(scope="module")
def cluster():
    pytest.importorskip("distributed")
    from photic.distributed.runner import _local_cluster
    client, cl = _local_cluster(2)  # the cluster `photic batch` starts
    yield client, cl
    client.close()
    cl.close()


def test_units_equal_plain_render(serial):
    """Merged units are the renderer's own sums: bit for bit equal to `photic render`."""
    out, report, arrays = serial
    job = _job()
    assert len(report.computed) == sum(len(plan_round(it, job, 0)) for it in job.items) == 54
    for item in job.items:
        ref = render(item.scene, samples=item.samples, radiometer_samples=item.radiometer_samples,
                     seed=item.seed, threads=2)
        img = ref.images["diver"]
        assert img.mean.any()
        assert np.array_equal(img.mean, arrays[f"{item.name}/diver/mean"])
        assert np.array_equal(img.variance, arrays[f"{item.name}/diver/variance"])
        for r in ref.radiometers:
            assert np.array_equal(r.mean, arrays[f"{item.name}/{r.name}/mean"]), r.name
            assert np.array_equal(r.stderr, arrays[f"{item.name}/{r.name}/stderr"]), r.name
    # The outputs are written per item, and the summary lists them.
    summary = json.loads((out / "summary.json").read_text())
    assert [s["status"] for s in summary["items"]] == ["done", "done"]
    for s in summary["items"]:
        assert any(f.endswith("_diver.exr") for f in s["files"])
        assert all(Path(f).is_file() for f in s["files"])


def test_local_cluster_identical_to_one_process(serial, cluster, tmp_path):
    client, _ = cluster
    pids = set(client.run(os.getpid).values())
    used = set()
    report = run_job(_job(), tmp_path, client=client, progress=False,
                     on_unit_done=lambda u, r: used.add(r["meta"]["pid"]))
    assert report.ok and len(report.computed) == 54
    assert used == pids and len(pids) == 2  # both worker processes rendered units
    _assert_identical(serial[2], _arrays(tmp_path))
    # The tables written from the merge are the same files.
    for f in (serial[0] / "results").rglob("*.csv"):
        assert f.read_text() == (tmp_path / f.relative_to(serial[0])).read_text()


def test_killed_worker_still_identical(serial, cluster, tmp_path):
    """SIGKILL a worker process while it renders: Dask reruns its units elsewhere (and on
    the restarted worker), each unit is stored and merged once, the numbers do not change."""
    client, _ = cluster
    client.wait_for_workers(2, timeout=60)
    pids = client.run(os.getpid)  # worker address -> pid
    killed = {}

    def kill_one(unit, result):
        if killed or len(done) < 4:
            done.append(unit)
            return
        busy = {w: keys for w, keys in client.processing().items() if keys and w in pids}
        victim = sorted(busy)[0]  # a worker with units assigned: it is running one of them
        os.kill(pids[victim], signal.SIGKILL)
        killed[victim] = len(busy[victim])

    done: list = []
    report = run_job(_job(), tmp_path, client=client, progress=False, on_unit_done=kill_one)
    assert killed, "no worker was killed: the job finished too early"
    assert report.ok and not report.failed
    assert len(report.computed) == len(set(report.computed)) == 54
    _assert_identical(serial[2], _arrays(tmp_path))
    # The restarted worker logs only critical messages too (a Ctrl-C's closed connections
    # made the workers print tracebacks to the terminal: issue 49).
    client.wait_for_workers(2, timeout=60)
    levels = client.run(lambda: logging.getLogger("distributed.worker").getEffectiveLevel())
    assert set(client.run(os.getpid).values()) != set(pids.values())
    assert len(levels) == 2 and set(levels.values()) == {logging.CRITICAL}, levels


def test_resume_redoes_no_finished_unit(serial, tmp_path):
    job = _job()
    calls = []

    class Stop(Exception):
        pass

    def interrupt(unit, result):
        calls.append(unit)
        if len(calls) == 20:
            raise Stop()

    with pytest.raises(Stop):
        run_job(job, tmp_path, workers=0, progress=False, on_unit_done=interrupt)
    store = UnitStore(tmp_path)
    units = [u for it in job.items for u in plan_round(it, job, 0)]
    finished = {f"{u.item}/{u.id}" for u in units
                if store.valid(u, next(it for it in job.items if it.name == u.item).fingerprint)}
    assert len(finished) == 20
    # A half-written file (a unit interrupted while its result was written) is never taken:
    # results are renamed into place complete; a stray temporary file is ignored.
    left = next(u for u in units if f"{u.item}/{u.id}" not in finished)
    (store.root / left.item / f".{left.id}.npz.1.tmp").write_bytes(b"partial")
    again = run_job(_job(), tmp_path, workers=0, progress=False)
    assert again.ok
    assert set(again.skipped) == finished
    assert not finished & set(again.computed)
    assert len(again.computed) + len(again.skipped) == len(units) == 54
    _assert_identical(serial[2], _arrays(tmp_path))
    # A third run has nothing left to do.
    third = run_job(_job(), tmp_path, workers=0, progress=False)
    assert third.computed == [] and len(third.skipped) == 54


def test_stored_unit_of_another_job_is_recomputed(tmp_path):
    """Resume trusts a file only for the same item fingerprint (seed, samples, scene...)."""
    small = dict(JOB, sweep={}, samples=1, radiometer_samples=4096,
                 set={"cameras.diver.resolution": [8, 6], "radiometer_arrays": []}, units={})
    assert len(run_job(parse_job(small, ROOT), tmp_path, workers=0, progress=False).computed) == 4
    changed = run_job(parse_job(dict(small, seed=12), ROOT), tmp_path, workers=0, progress=False)
    assert changed.ok and not changed.skipped and len(changed.computed) == 4
    # A damaged file is computed again too.
    victim = next((tmp_path / "units").rglob("*rad0*.npz"))
    victim.write_bytes(victim.read_bytes()[:-100])
    again = run_job(parse_job(dict(small, seed=12), ROOT), tmp_path, workers=0, progress=False)
    assert again.computed == [f"coastal_shelf/{victim.stem}"] and len(again.skipped) == 3


def _image_plane(cam, px, row, fx, fy):
    """Where the core's camera model sends pixel (px, row) offset by (fx, fy): the ray's
    right and up components per unit forward (perspective)."""
    W, H = cam.resolution
    t = np.tan(np.radians(cam.fov_deg) / 2)
    sx = 2.0 * ((px + 0.5 + fx) / W) - 1.0 + 2.0 * cam.shift[0]
    sy = (1.0 - 2.0 * ((row + 0.5 + fy) / H)) * H / W + 2.0 * cam.shift[1]
    return sx * t, sy * t


def test_tile_cameras_see_the_image_pixels():
    from photic.distributed.units import _tile_scene
    from photic.scene import load_scene

    scene = load_scene(EXAMPLE)
    scene.cameras[0].shift = (0.1, -0.05)
    cam = scene.cameras[0]
    rng = np.random.default_rng(1)
    for x0, y0, w, h in tile_rects(*cam.resolution, 48):
        tile = _tile_scene(scene, 0, (x0, y0, w, h), 5, 0)[0].cameras[0]
        assert tile.resolution == (w, h) and tile.position.tolist() == cam.position.tolist()
        px, row, fx, fy = rng.integers(0, w, 50), rng.integers(0, h, 50), rng.random(50) - 0.5, rng.random(50) - 0.5
        np.testing.assert_allclose(_image_plane(tile, px, row, fx, fy),
                                   _image_plane(cam, x0 + px, y0 + row, fx, fy), rtol=0, atol=1e-12)


def test_tiles_cover_the_image(tmp_path):
    """Tiled cameras: the tiles' rays are the image's (an independent random stream, so a
    different but consistent estimate); deterministic whatever the scheduling."""
    assert tile_rects(24, 16, 10) == [(0, 0, 10, 10), (10, 0, 10, 10), (20, 0, 4, 10),
                                      (0, 10, 10, 6), (10, 10, 10, 6), (20, 10, 4, 6)]
    doc = dict(JOB, sweep={}, samples=16, radiometer_samples=1, units={"tile": 10, "camera_passes": 4})
    doc["set"] = {"cameras.diver.resolution": [24, 16], "radiometers": [], "radiometer_arrays": []}
    job = parse_job(doc, ROOT)
    report = run_job(job, tmp_path, workers=0, progress=False)
    assert report.ok and len(report.computed) == 6 * 2  # 6 tiles x passes (1, 2, 4, 8, 1) in 2 units
    item = job.items[0]
    merger = ItemMerger(item)
    for u in merge_order(plan_round(item, job, 0)):
        merger.add(u, UnitStore(tmp_path).read(u, item.fingerprint), job)
    tiled = merger.result().images["diver"]
    whole = render(item.scene, samples=16, radiometer_samples=1, seed=item.seed).images["diver"]
    assert tiled.samples == 16
    # Same picture: pixel by pixel within a few standard errors, and a matching mean.
    diff = tiled.mean - whole.mean
    se = np.sqrt(tiled.variance + whole.variance)
    assert np.mean(np.abs(diff) <= 4 * se + 1e-12) > 0.97
    assert abs(tiled.mean.mean() / whole.mean.mean() - 1) < 0.05


def test_target_rel_stderr_adds_rounds(tmp_path):
    """A target standard error adds rounds (fresh seeds) until the radiometers reach it;
    the number of rounds follows from the merged numbers, so it is deterministic too."""
    assert rounds_needed(1, 0.02, 0.01, 16) == 3 and rounds_needed(4, 0.009, 0.01, 16) == 0
    assert rounds_needed(15, 0.5, 0.01, 16) == 1
    doc = {"photic_job": 1, "name": "target",
           "inputs": [{"scene": str(ROOT / "examples/problems/mobley1993_problem2_omega0.9.json")}],
           "set": {"radiometers": [{"name": "Ed1", "quantity": "Ed", "position": [0, 0, -1]}]},
           "radiometer_samples": 4096, "target_rel_stderr": 0.008, "max_rounds": 8}
    job = parse_job(doc, ROOT)
    report = run_job(job, tmp_path, workers=0, progress=False)
    s = report.items[job.items[0].name]
    assert report.ok and s["rounds"] > 1 and s["target_met"]
    assert s["worst_rel_stderr"] <= 0.008 and s["rounds"] < 8
    table = json.loads(next((tmp_path / "results").rglob("*_radiometers.json")).read_text())
    assert table["radiometers"][0]["samples"] == 4096 * s["rounds"]


def test_job_errors():
    with pytest.raises(JobError, match="unknown keys"):
        parse_job(dict(JOB, sample=3), ROOT)
    with pytest.raises(JobError, match="no entry named 'nobody'"):
        parse_job(dict(JOB, set={"cameras.nobody.resolution": [8, 8]}), ROOT)
    with pytest.raises(JobError, match="invalid scene"):
        parse_job(dict(JOB, set={"settings.max_depth": 0}), ROOT)
    with pytest.raises(JobError, match="photic_job"):
        parse_job({"inputs": ["x.json"]}, ROOT)


def test_cli_batch_and_resume(tmp_path, capsys):
    from photic.cli import main

    doc = dict(JOB, sweep={}, samples=1, radiometer_samples=4096,
               set={"cameras.diver.resolution": [8, 6], "radiometer_arrays": []}, units={})
    path = tmp_path / "job.json"
    path.write_text(json.dumps(doc))
    assert main(["batch", str(path), "--workers", "0", "--quiet", "--out", str(tmp_path / "o")]) == 0
    first = capsys.readouterr().out
    assert "done" in first and "4 units computed, 0 reused" in first
    assert load_job(path).items[0].name == "coastal_shelf"
    assert main(["batch", str(path), "--workers", "0", "--quiet", "--out", str(tmp_path / "o")]) == 0
    assert "0 units computed, 4 reused" in capsys.readouterr().out


def test_instanced_scene_in_a_batch_on_the_local_cluster(cluster, tmp_path):
    """An instanced mesh (its copies a .npy file beside the scene) goes to the workers as its
    mesh and transforms, never flattened: the cluster's merged results equal one process's,
    bit for bit, and the item's fingerprint follows the transforms."""
    doc = json.loads(EXAMPLE.read_text())
    block = next(m for m in doc["meshes"] if m["name"] == "block")
    centre = np.mean(np.asarray(block["vertices"], float), axis=0)
    x = np.zeros((4, 3, 4))
    for k in range(4):
        x[k, :, :3] = np.eye(3) * (0.3 + 0.1 * k)
        x[k, :, 3] = (1.0 - 0.3 - 0.1 * k) * centre + (0.8 * (k - 1.5), 1.5, 0.3)
    np.save(tmp_path / "copies.npy", x)
    doc["meshes"].append(dict(block, name="copies", instances="copies.npy"))
    (tmp_path / "shelf.json").write_text(json.dumps(doc))
    small = {"photic_job": 1, "name": "copies", "inputs": [str(tmp_path / "shelf.json")],
             "set": {"cameras.diver.resolution": [16, 12], "radiometer_arrays": []},
             "samples": 2, "radiometer_samples": 4096, "seed": 3}
    job = parse_job(small, ROOT)
    scene = job.items[0].scene
    assert scene.meshes[-1].copies == 4 and len(scene.meshes[-1].mesh.triangles) == len(block["triangles"])
    client, _ = cluster
    run_job(job, tmp_path / "one", workers=0, progress=False)
    report = run_job(parse_job(small, ROOT), tmp_path / "dask", client=client, progress=False)
    assert report.ok and report.computed
    for f in (tmp_path / "one" / "units").rglob("*.npz"):
        a, b = np.load(f), np.load(tmp_path / "dask" / f.relative_to(tmp_path / "one"))
        assert all(np.array_equal(a[k], b[k]) for k in a.files if k != "__meta__"), f
    x[0, 0, 3] += 0.01
    np.save(tmp_path / "copies.npy", x)
    assert parse_job(small, ROOT).items[0].fingerprint != job.items[0].fingerprint
