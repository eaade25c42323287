"""Nothing lost after a render (issue 49, kind 2): every output is written atomically (a
temporary file beside it, renamed), the destinations are checked before the render starts,
and when a write fails anyway the other outputs are still written, the failed one is kept in
a private rescue folder, and the message says where."""
from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photic import output
from photic.cli import main
from photic.output import WriteFailure, atomic_file, write_outputs
from photic.render import render
from photic.scene import Scene, SceneError

from test_robustness import small


@pytest.fixture(scope="module")
def result():
    return render(Scene.from_dict(small()), samples=2, radiometer_samples=256)


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(old=st.one_of(st.none(), st.text(max_size=50)), new=st.text(max_size=200),
       fail_after=st.one_of(st.none(), st.integers(0, 200)))
def test_an_atomic_file_is_the_old_or_the_whole_new_one(tmp_path_factory, old, new, fail_after):
    """Whatever fails while writing (here an OSError after ``fail_after`` characters), the
    final name holds the old content (or nothing) or the whole new one, and no temporary is
    left."""
    d = tmp_path_factory.mktemp("atomic")
    path = d / "table.json"
    if old is not None:
        path.write_bytes(old.encode("utf-8"))
    failing = fail_after is not None and fail_after <= len(new)
    try:
        with atomic_file(path, "w", encoding="utf-8", newline="") as f:
            if failing:
                f.write(new[:fail_after])
                raise OSError(errno.ENOSPC, "No space left on device")
            f.write(new)
    except OSError:
        assert failing
    expected = (old if failing else new)
    assert (path.read_bytes().decode("utf-8") if path.exists() else None) == expected
    assert [p.name for p in d.iterdir()] == ([] if expected is None else ["table.json"])


def test_a_folder_in_the_way_of_an_image_is_refused_before_the_render(tmp_path, capsys):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(small()))
    out = tmp_path / "out"
    (out / "test_cam.exr").mkdir(parents=True)
    assert main(["render", str(scene), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "test_cam.exr is a folder" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["test_cam.exr"]  # nothing rendered


def _rescued(failures: list[WriteFailure]) -> None:
    for f in failures:
        assert f.kept is not None and f.kept.is_file() and f.kept.name == f.path.name, f
        assert "photic-rescue-" in str(f.kept.parent)
        assert oct(f.kept.parent.stat().st_mode & 0o777) == oct(0o700)  # private


def test_when_the_image_cannot_be_written_the_tables_still_are(tmp_path, result):
    (tmp_path / "test_cam.exr").mkdir()  # after the check: e.g. made while rendering
    written = write_outputs(tmp_path, result)
    assert [p.name for p in written["tables"]] == ["test_radiometers.csv", "test_radiometers.json",
                                                   "test_derived.csv"]
    (failure,) = written["failed"]
    assert failure.path == tmp_path / "test_cam.exr" and "folder" in failure.reason
    _rescued(written["failed"])
    assert "kept in" in str(failure)


def test_a_full_disk_keeps_the_old_table_whole_and_the_new_one_elsewhere(tmp_path, result,
                                                                        monkeypatch):
    """ENOSPC when the JSON table is flushed: the previous table under the final name stays
    as it was (it was left truncated), no temporary is left, the other files are written,
    and the new JSON is in the rescue folder."""
    old = '{"an": "older, complete table"}'
    (tmp_path / "test_radiometers.json").write_text(old)
    real_fsync = os.fsync

    def fsync(fd):
        name = os.readlink(f"/proc/self/fd/{fd}")
        if Path(name).parent == tmp_path and Path(name).name.startswith(".") and name.endswith(".json"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_fsync(fd)

    monkeypatch.setattr(output.os, "fsync", fsync)
    written = write_outputs(tmp_path, result)
    assert (tmp_path / "test_radiometers.json").read_text() == old
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    failed = {f.path.name: f for f in written["failed"]}
    assert "test_radiometers.json" in failed and failed["test_radiometers.json"].reason == "No space left on device"
    _rescued(written["failed"])
    json.loads(failed["test_radiometers.json"].kept.read_text())  # whole
    assert (tmp_path / "test_cam.exr").is_file() and (tmp_path / "test_derived.csv").is_file()


def test_the_command_says_where_a_failed_output_was_kept(tmp_path, capsys, monkeypatch):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(small()))
    out = tmp_path / "out"
    real = output.write_exr

    def write_exr(path, res, camera):
        if Path(path).parent == out:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, res, camera)

    monkeypatch.setattr(output, "write_exr", write_exr)
    assert main(["render", str(scene), "--out", str(out), "--quiet"]) == 1
    captured = capsys.readouterr()
    assert f"could not write {out / 'test_cam.exr'}: No space left on device; kept in " in captured.err
    assert "radiometer table: " in captured.out and (out / "test_radiometers.json").is_file()


@pytest.mark.parametrize("where", ["cameras", "radiometers", "bands", "name"])
def test_names_that_cannot_be_written_are_refused_when_read(where):
    """A lone surrogate ("\\ud800" in JSON) in a name made every writer fail after the
    render; now the loader names the field."""
    d = small()
    if where == "name":
        d["name"] = "sea\ud800"
    else:
        d[where][0]["name"] = "x\udfff"
    with pytest.raises(SceneError, match="UTF-8 can hold") as e:
        Scene.from_dict(d)
    str(e.value).encode("utf-8")  # the message itself can be printed


def test_an_atomic_path_is_renamed_only_when_the_writer_finished(tmp_path):
    """For writers that take a name (Blender's image saver): the final name gets the whole new
    file, or keeps the old one when the writer fails or writes nothing; no temporary is left."""
    from photic.safe_io import atomic_path

    path = tmp_path / "frame_0001.exr"
    path.write_bytes(b"old")
    with atomic_path(path) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".exr" and tmp != path
        tmp.write_bytes(b"new")
    assert path.read_bytes() == b"new"
    with pytest.raises(OSError, match="disk full"):
        with atomic_path(path) as tmp:
            tmp.write_bytes(b"half")
            raise OSError(errno.ENOSPC, "disk full")
    assert path.read_bytes() == b"new"
    with pytest.raises(OSError, match="wrote nothing"):
        with atomic_path(path):
            pass
    assert path.read_bytes() == b"new" and sorted(os.listdir(tmp_path)) == ["frame_0001.exr"]
    (tmp_path / "folder.exr").mkdir()
    with pytest.raises(IsADirectoryError, match="folder"):
        with atomic_path(tmp_path / "folder.exr"):
            pass


def test_photic_blend_saves_its_images_atomically(tmp_path, monkeypatch):
    """The EXR and PNG that `photic blend` saves through Blender go under a temporary name
    first: a save that fails half-way leaves the frame's earlier image whole."""
    pytest.importorskip("bpy")
    import types

    from photic.cli import load_addon

    load_addon()
    from photic_blender import batch

    blend = Path(__file__).resolve().parent.parent / "example_blends" / "stepped_pool.blend"
    summary = batch.render_blend(blend, out_dir=tmp_path, samples=1, resolution_percentage=10, png=True)
    image, png = Path(summary["image"]), Path(summary["png"])
    assert image.stat().st_size > 0 and png.stat().st_size > 0
    assert not [p for p in os.listdir(image.parent) if ".tmp" in p]
    before = image.read_bytes()
    saved = []

    class HalfWritten:  # Blender's saver on a disk that fills up half-way
        def save_render(self, filepath, scene=None):
            Path(filepath).write_bytes(b"trunc")
            saved.append(filepath)
            raise OSError(errno.ENOSPC, "No space left on device")

    fake = types.SimpleNamespace(data=types.SimpleNamespace(images={"Render Result": HalfWritten()}))
    monkeypatch.setattr(batch, "bpy", fake)
    with pytest.raises(OSError):
        batch._save_render(str(image), None)
    assert saved and Path(saved[0]) != image
    assert image.read_bytes() == before
    assert not [p for p in os.listdir(image.parent) if ".tmp" in p]
