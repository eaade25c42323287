"""What a user types must not crash Photic, lose a result or give silent garbage: each test is
a reproducer of a bad input (issue 28) that crashed the process, gave a wrong number, a
traceback or a misleading message, and checks the clear error (naming object and field) or
the right behaviour that replaced it."""
from __future__ import annotations

import json

import numpy as np
import pytest

from photic.cli import main
from photic.render import Renderer, render, render_memory
from photic.scene import MAX_COORDINATE_M, Scene, SceneError, load_scene

from test_scene import valid_dict


def small(**changes) -> dict:
    d = valid_dict()
    d["water"] = d["water"][:1]
    d["settings"].update(samples=1, radiometer_samples=256, threads=1)
    d["cameras"][0]["resolution"] = [8, 6]
    for k, v in changes.items():
        d[k] = v
    return d


def refused(d, *, field: str, text: str, obj: str | None = None):
    with pytest.raises(SceneError) as e:
        Scene.from_dict(d)
    msg = str(e.value)
    assert text in msg and field in msg, msg
    if obj is not None:
        assert obj in msg, msg
    return msg


# ---- crashes of the process ---------------------------------------------------------------

@pytest.mark.parametrize("where, value, field", [
    ("camera", [1e19, 0, 0], "position"),
    ("radiometer", [1e20, 0, 0], "position"),
    ("radiometer", [0, -4, -1e308], "position"),
])
def test_coordinates_beyond_single_precision_are_refused(where, value, field):
    d = small()
    if where == "camera":
        d["cameras"][0]["position"] = value
        d["cameras"][0]["look_at"] = [0, 0, 0]
    else:
        d["radiometers"][0]["position"] = value
    msg = refused(d, field=field, text="single precision")
    assert f"{MAX_COORDINATE_M:.0e}" in msg


def test_huge_ortho_width_and_scaled_meshes_are_refused():
    d = small()
    d["cameras"][0].update(type="orthographic", ortho_width=1e25)
    refused(d, field="ortho_width", text="(0, 2000000]", obj="cam")
    d = small()
    d["meshes"][0]["vertices"] = (np.array(d["meshes"][0]["vertices"]) * 1e13).tolist()
    refused(d, field="vertices[0]", text="single precision", obj="rock")
    d = small()
    d["meshes"][0]["vertices"][1] = [1e308, 0, 0]  # said "zero-area triangle ... 0.125 m^2"
    msg = refused(d, field="vertices[1]", text="single precision")
    assert "zero-area" not in msg


def test_radiance_distribution_bins_are_bounded_by_their_product():
    d = small(radiometers=[{"name": "L", "quantity": "radiance_distribution", "position": [0, 0, -1],
                            "polar_bins": 65536, "azimuth_bins": 65536}])
    msg = refused(d, field="azimuth_bins", text="polar_bins x azimuth_bins must be at most")
    assert "4,294,967,296" in msg
    d["radiometers"][0].update(polar_bins=65536, azimuth_bins=65537)
    refused(d, field="azimuth_bins", text="at most")
    d["radiometers"][0].update(polar_bins=100, azimuth_bins=10000)  # 1e6: allowed
    Scene.from_dict(d)


# ---- wrong numbers without a word -----------------------------------------------------------

def test_henyey_greenstein_near_one_is_bounded_and_finite_at_the_bound():
    d = small()
    d["water"][0]["iops"]["scattering"][2]["phase"]["g"] = 0.999999999
    refused(d, field="g", text="-0.9999")
    d["water"][0]["iops"]["scattering"][2]["phase"]["g"] = 0.9999
    d["settings"]["integrator"] = "hybrid"
    res = render(Scene.from_dict(d), samples=2, radiometer_samples=512)
    assert np.isfinite(res.images["cam"].mean).all()
    assert all(np.isfinite(r.mean).all() for r in res.radiometers)


def test_absurd_source_strengths_are_refused():
    d = small()
    d["sun"]["irradiance"] = [1e38, 1.0]
    refused(d, field="irradiance[0]", text="[0, 100000000]", obj="sun")


def test_duplicate_json_keys_are_refused(tmp_path):
    p = tmp_path / "dup.json"
    text = json.dumps(small())
    p.write_text('{"photic_scene": 1, ' + text[1:])  # a second photic_scene
    with pytest.raises(SceneError, match="'photic_scene' appears twice"):
        load_scene(p)


def test_a_radiometer_on_a_water_boundary_is_refused():
    d = small()
    d["radiometers"] = [{"name": "on_top", "quantity": "Ed", "position": [0.3, 0.2, 0.0]}]
    with pytest.raises(SceneError) as e:
        render(Scene.from_dict(d), radiometer_samples=64)
    msg = str(e.value)
    assert "on_top" in msg and "boundary between" in msg and "sea" in msg, msg
    d["radiometers"][0]["position"] = [0.3, 0.2, -0.01]  # a centimetre below: fine
    res = render(Scene.from_dict(d), radiometer_samples=64)
    assert res.radiometers[0].medium == "sea"


def test_cameras_whose_names_map_to_one_file_write_two_files(tmp_path):
    d = small()
    cam = d["cameras"][0]
    d["cameras"] = [dict(cam, name="cam\u20ac"), dict(cam, name="cam\u00a3")]
    p = tmp_path / "two.json"
    p.write_text(json.dumps(d))
    assert main(["render", str(p), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    exrs = sorted((tmp_path / "out").glob("*.exr"))
    assert len(exrs) == 2, exrs


# ---- tracebacks instead of messages ---------------------------------------------------------

@pytest.mark.parametrize("seed", ["-1", str(2**64)])
def test_bad_seeds_are_clear_errors(tmp_path, capsys, seed):
    p = tmp_path / "s.json"
    p.write_text(json.dumps(small()))
    assert main(["render", str(p), "--out", str(tmp_path), "--quiet", "--seed", seed]) == 2
    err = capsys.readouterr().err
    assert "seed" in err and "9223372036854775807" in err, err


def test_deep_nesting_and_huge_indices_are_clear_errors(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text('{"photic_scene": 1, "bands": ' + "[" * 100000 + "]" * 100000 + "}")
    with pytest.raises(SceneError, match="nested too deeply"):
        load_scene(p)
    d = small()
    d["meshes"][0]["triangles"] = [[0, 1, 2**64]]
    refused(d, field="triangles", text="beyond 2^63 - 1", obj="rock")


def test_grid_file_that_is_a_npy_is_a_clear_error(tmp_path):
    np.save(tmp_path / "density.npy", np.ones((2, 2, 2)))
    d = small()
    iops = d["water"][0].pop("iops")
    d["water"][0]["iop_grid"] = {"base": {"iops": iops}, "unit": {"iops": iops}, "origin": [-1, -1, -2],
                                 "size": [2, 2, 2], "file": "density.npy"}
    with pytest.raises(SceneError) as e:
        Scene.from_dict(d, base_dir=tmp_path)
    assert "iop_grid.file" in str(e.value) and ".npz" in str(e.value), str(e.value)


def test_tiny_band_widths_and_patch_sizes_are_refused():
    d = small()
    d["bands"][0]["width_nm"] = 1e-14
    refused(d, field="width_nm", text="0.001")
    d = small()
    d["water"][0]["surface"] = {"kind": "waves", "spectrum": "pierson_moskowitz", "wind_speed": 5,
                                "patch_size_m": [1e-300, 1e-300], "resolution": [8, 8]}
    refused(d, field="patch_size_m[", text="0.001")  # (the schema may name either entry)


def test_mesh_files_that_are_folders_or_devices_say_so(tmp_path):
    d = small()
    d["meshes"][0] = {"name": "rock", "material": "sand", "file": str(tmp_path)}
    with pytest.raises(SceneError, match="is a folder, not a mesh file"):
        Scene.from_dict(d)
    d["meshes"][0]["file"] = "/dev/zero"
    with pytest.raises(SceneError, match="not a regular file"):
        Scene.from_dict(d)


# ---- memory and time ----------------------------------------------------------------------

def test_renders_larger_than_the_machine_are_refused_with_the_estimate():
    d = small()
    d["cameras"][0]["resolution"] = [16384, 16384]
    sc = Scene.from_dict(d)
    need = sum(render_memory(sc).values())
    assert need > 30 * 2**30  # 16384^2 pixels x 2 bands of float64 sums
    with pytest.raises(SceneError) as e:
        Renderer(sc)
    msg = str(e.value)
    assert "GiB" in msg and "16384 x 16384" in msg and "this machine has" in msg, msg


def test_huge_radiometer_arrays_are_refused():
    d = small()
    d["radiometer_arrays"][0]["line"]["count"] = 10**9
    with pytest.raises(SceneError, match="1000000"):
        Scene.from_dict(d)


# ---- results lost ---------------------------------------------------------------------------

def test_a_bad_output_location_fails_before_rendering(tmp_path, capsys):
    p = tmp_path / "s.json"
    p.write_text(json.dumps(small()))
    a_file = tmp_path / "file"
    a_file.write_text("x")
    for out, why in ((a_file, "is a file"), (a_file / "sub", "cannot write")):
        assert main(["render", str(p), "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert why in err and "--out" in err, err


def test_exr_is_written_atomically_and_marks_a_cancelled_render(tmp_path):
    from photic.output import write_outputs
    r = Renderer(Scene.from_dict(small()), samples=1 << 18)
    import threading
    t = threading.Thread(target=lambda: setattr(r, "res", r.run()))
    t.start()
    while r.total_sums("cam") is None:
        pass
    r.cancel()
    t.join()
    assert r.res.cancelled
    written = write_outputs(tmp_path, r.res)
    exr = written["images"][0]
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporaries left
    import OpenEXR
    with OpenEXR.File(str(exr)) as f:
        header = dict(f.header())  # (a copy: the file's header is emptied when it closes)
    assert str(header.get("photic:cancelled", "")).startswith("1"), (exr, sorted(header))


# ---- distributed ----------------------------------------------------------------------------

@pytest.mark.parametrize("address, text", [
    ("notanaddress", "expected tcp://HOST:PORT"),
    ("http://127.0.0.1:8787", "web address"),
    ("ftp://host:21", "unknown scheme"),
    ("tcp://host:99999", "expected tcp://HOST:PORT"),
])
def test_scheduler_addresses_are_checked(address, text):
    from photic.distributed import SchedulerError, check_scheduler_address
    with pytest.raises(SchedulerError, match=text):
        check_scheduler_address(address)
    assert check_scheduler_address("10.0.0.5:8786") == ("tcp", "10.0.0.5", 8786)


def _serve(handler):
    """A TCP server on a free local port that runs handler(conn) per connection."""
    import socket
    import threading
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)

    def loop():
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            threading.Thread(target=handler, args=(conn,), daemon=True).start()

    threading.Thread(target=loop, daemon=True).start()
    return srv, srv.getsockname()[1]


@pytest.mark.parametrize("kind", ["http400", "silent", "closed"])
def test_peers_that_are_no_dask_scheduler_give_a_message_not_a_hang(kind, tmp_path, capsys):
    import socket
    import time

    def http400(conn):
        conn.recv(1024)
        conn.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")
        time.sleep(5)
        conn.close()

    def silent(conn):
        time.sleep(30)
        conn.close()

    if kind == "closed":
        s = socket.socket()
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        s.close()  # nothing listens there
        srv = None
    else:
        srv, port = _serve(http400 if kind == "http400" else silent)
    from photic.distributed import SchedulerError
    from photic.distributed.runner import connect_scheduler
    t0 = time.perf_counter()
    with pytest.raises(SchedulerError):
        connect_scheduler(f"tcp://127.0.0.1:{port}", 2.0)
    assert time.perf_counter() - t0 < 15
    if srv is not None:
        srv.close()


def test_negative_workers_are_refused(tmp_path, capsys):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(small()))
    job = tmp_path / "job.json"
    job.write_text(json.dumps({"photic_job": 1, "name": "j", "inputs": [str(scene)]}))
    assert main(["batch", str(job), "--workers", "-1", "--quiet", "--out", str(tmp_path / "o")]) == 2
    assert "workers must be 0" in capsys.readouterr().err


# ---- cost that follows the band -----------------------------------------------------------

def test_a_band_of_huge_scattering_does_not_slow_the_others(zscore):
    """b = [1e5, 0.1]: the bands render in separate groups, so the clear band costs what it
    costs alone (it took 45 s for 512 samples when its paths followed the turbid band's
    majorant) and gives the same value as a render of that band alone (z-score)."""
    import time
    from photic.compile import band_groups, scene_band_groups
    d = small(cameras=[])
    d["water"][0]["iops"] = {"absorption": [0.1, 0.1], "b": [1e5, 0.1], "phase": {"type": "isotropic"}}
    d["radiometers"] = [{"name": "Ed", "quantity": "Ed", "position": [0, 0, -1]}]
    d.pop("radiometer_arrays")
    sc = Scene.from_dict(d)
    assert scene_band_groups(sc) == [slice(0, 1), slice(1, 2)]
    t0 = time.perf_counter()
    both = render(sc, radiometer_samples=4096, threads=2)
    t_both = time.perf_counter() - t0
    one = dict(d, bands=[d["bands"][1]])
    one["water"] = [dict(d["water"][0], iops={"absorption": [0.1], "b": [0.1], "phase": {"type": "isotropic"}})]
    one["materials"] = {k: dict(m, reflectance=[m["reflectance"][1]] if isinstance(m["reflectance"], list)
                                else m["reflectance"]) for k, m in d["materials"].items()}
    one["sun"] = dict(d["sun"], irradiance=[d["sun"]["irradiance"][1]])
    one["sky"] = dict(d["sky"], irradiance=[d["sky"]["irradiance"][1]])
    alone = render(Scene.from_dict(one), radiometer_samples=4096, threads=2, seed=99)
    a, b = both.radiometers[0], alone.radiometers[0]
    z = zscore("clear band beside a 1e5 band vs alone", a.mean[0, 1], b.mean[0, 0],
               float(np.hypot(a.stderr[0, 1], b.stderr[0, 0])))
    assert abs(z) < 4
    assert t_both < 30, t_both
    # Ordinary scenes keep their groups (and so their numbers).
    assert scene_band_groups(Scene.from_dict(small())) == band_groups(2)


def test_a_wave_patch_too_large_for_the_machine_is_refused_at_once():
    """waves resolution [4096, 4096] ran 300 s without a word: its 33.5 M triangles and their
    beams need more than this machine has (the estimate says so before anything is built)."""
    import time
    d = small()
    d["settings"]["integrator"] = "hybrid"
    d["water"][0]["surface"] = {"kind": "waves", "spectrum": "pierson_moskowitz", "wind_speed": 5,
                                "patch_size_m": [50, 50], "resolution": [4096, 4096]}
    sc = Scene.from_dict(d)
    need = render_memory(sc)
    key = next(k for k in need if "wave patch" in k)
    assert "33,554,432 triangles" in key and need[key] > 30 * 2**30
    t0 = time.perf_counter()
    with pytest.raises(SceneError, match="wave patch"):
        Renderer(sc)
    assert time.perf_counter() - t0 < 5
