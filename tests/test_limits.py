"""Field errors instead of tracebacks, and sizes refused before they grow (issue 49, kind 6):
wave-model parameters at their ends load and render or give a SceneError naming the field;
a truncated .npz and one whose header claims 256 GiB name iop_grid.file; batch sweeps and
frame ranges of 1e9 items are refused at once, naming the field; the radiometer tables of a
radiance distribution of many bins are written in bounded memory."""
from __future__ import annotations

import io
import json
import time
import tracemalloc
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photic.distributed import JobError, load_job
from photic.output import write_outputs
from photic.render import RadiometerResult, RenderResult, render
from photic.scene import Band, Scene, SceneError

from test_robustness import small

SPECTRA = ["jonswap", "pierson_moskowitz", "phillips", "flat"]


@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
@given(spectrum=st.sampled_from(SPECTRA),
       wind=st.sampled_from([0.0, 1e-300, 1e-3, 10.0, 100.0, 100.0001, 1e300]),
       gamma=st.sampled_from([1.0, 3.3, 20.0, 20.001, 1e30]),
       depth=st.sampled_from([None, 1e-300, 1e-3, 0.5, 1e6, 1e300]),
       fetch=st.sampled_from([1e-300, 1.0, 1e4, 1e300]),
       chop=st.sampled_from([0.0, 0.5, 1e300]))
def test_wave_models_at_their_limits_render_or_name_the_field(spectrum, wind, gamma, depth, fetch, chop):
    s = {"kind": "waves", "spectrum": spectrum, "wind_speed": wind, "patch_size_m": [20, 20],
         "resolution": [16, 16], "choppiness": chop}
    if spectrum == "jonswap":
        s.update(gamma=gamma, fetch_m=fetch)
    if depth is not None:
        s["water_depth_m"] = depth
    d = small()
    d["water"][0]["surface"] = s
    d["settings"]["integrator"] = "hybrid"
    try:
        res = render(Scene.from_dict(d), samples=1, radiometer_samples=64)
    except SceneError as e:
        assert "surface" in e.field, str(e)
        return
    assert all(np.isfinite(r.mean).all() for r in res.radiometers)
    assert all(np.isfinite(img.mean).all() for img in res.images.values())


def _grid_scene(file: str) -> dict:
    d = small()
    d["water"] = d["water"][:1]
    iops = d["water"][0].pop("iops")
    unit = {"absorption": 0.1, "scattering": [dict(c, b=0.0) for c in iops["scattering"]]}
    d["water"][0]["iop_grid"] = {"base": {"iops": iops}, "unit": {"iops": unit},
                                 "origin": [-1, -1, -2], "size": [2, 2, 2], "file": file}
    return d


def test_damaged_npz_files_name_the_field(tmp_path):
    good = tmp_path / "good.npz"
    np.savez(good, density=np.ones((4, 4, 4)))
    Scene.from_dict(_grid_scene("good.npz"), base_dir=tmp_path)
    data = good.read_bytes()
    for cut in (10, len(data) // 2, len(data) - 30):
        (tmp_path / "cut.npz").write_bytes(data[:cut])
        with pytest.raises(SceneError, match="iop_grid.file") as e:
            Scene.from_dict(_grid_scene("cut.npz"), base_dir=tmp_path)
        assert "cut.npz" in str(e.value)
    header = io.BytesIO()  # an array header claiming 256 GiB, and 64 bytes of data
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (65536, 65536, 8)})
    header.write(b"\0" * 64)
    with zipfile.ZipFile(tmp_path / "huge.npz", "w") as z:
        z.writestr("density.npy", header.getvalue())
    t0 = time.perf_counter()
    with pytest.raises(SceneError, match=r"iop_grid.file.*claims shape \(65536, 65536, 8\).*256 GiB"):
        Scene.from_dict(_grid_scene("huge.npz"), base_dir=tmp_path)
    assert time.perf_counter() - t0 < 5


def _job(tmp_path, **fields):
    (tmp_path / "scene.json").write_text(json.dumps(small()))
    doc = {"photic_job": 1, "name": "j", "inputs": ["scene.json"], **fields}
    (tmp_path / "job.json").write_text(json.dumps(doc))
    return tmp_path / "job.json"


@pytest.mark.parametrize("fields, text", [
    ({"sweep": {f"sun.zenith_deg": list(range(0, 89)), "sun.azimuth_deg": list(range(1000)),
                "sky.irradiance": list(range(1000)), "settings.seed": list(range(20))}},
     "'sweep' x 'cases' (89 x 1,000 x 1,000 x 20) gives 1,780,000,000 items"),
    ({"sweep": {"sun.zenith_deg": list(range(0, 80))}, "cases": [{"settings.seed": i} for i in range(2000)]},
     "gives 160,000 items"),
])
def test_huge_sweeps_are_refused_at_once_naming_the_field(tmp_path, fields, text):
    t0 = time.perf_counter()
    with pytest.raises(JobError) as e:
        load_job(_job(tmp_path, **fields))
    assert text in str(e.value) and "at most 100,000" in str(e.value), str(e.value)
    assert time.perf_counter() - t0 < 10


def test_huge_frame_ranges_are_refused_at_once(tmp_path):
    from photic.distributed.job import _frames
    t0 = time.perf_counter()
    with pytest.raises(JobError, match=r"'frames' 1..1000000000 gives 1,000,000,000 items"):
        _frames({"start": 1, "end": 10**9}, "inputs[0]")
    with pytest.raises(JobError, match="integers"):
        _frames({"start": 1, "end": 1e9}, "inputs[0]")
    assert _frames({"start": 1, "end": 5, "step": 2}, "x") == [1, 3, 5]
    assert time.perf_counter() - t0 < 1


def test_the_tables_of_a_radiance_distribution_are_written_in_bounded_memory(tmp_path):
    """3 x 10^4 bins (the limit is 10^6): the tables are written row by row; building every row
    first, and the JSON as one indented string, took more than 8 GB at 10^6 bins."""
    nbins, nbands = 30_000, 2
    rng = np.random.default_rng(1)
    r = RadiometerResult("L", "radiance_distribution", np.zeros(3), "sea", rng.random((nbins, nbands)),
                         rng.random((nbins, nbands)) * 0.01, 4096, bins=(100, 300),
                         reliable=np.ones((nbins, nbands), bool))
    res = RenderResult("dist", [Band("a", 450.0, 10.0), Band("b", 550.0, 10.0)], radiometers=[r],
                       stats={"seed": 0})
    tracemalloc.start()
    try:
        written = write_outputs(tmp_path, res)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert not written["failed"]
    assert peak < 30 * 2**20, peak  # the arrays themselves are 0.5 MB each
    doc = json.loads((tmp_path / "dist_radiometers.json").read_text())
    np.testing.assert_array_equal(np.array(doc["radiometers"][0]["value"]), r.mean)
    lines = (tmp_path / "dist_radiometers.csv").read_text().count("\n")
    assert lines == nbins * nbands + 2  # the comment line and the header


@pytest.mark.parametrize("size, origin, field", [
    ([1e-300, 2.0, 2.0], [-1, -1, -2], "iop_grid.size[0]"),
    ([2.0, 2.0, 1e-9], [-1, -1, -2], "iop_grid.size[2]"),
    ([2.0, 1e-3, 2.0], [-1, 5e5, -2], "iop_grid.size[1]"),
    ([1e300, 2.0, 2.0], [-1, -1, -2], "iop_grid.size"),
    ([2.0, 2.0, 2.0], [-1, -1, -2e6], "iop_grid.origin"),
])
def test_grid_boxes_too_small_or_too_far_name_the_field(size, origin, field):
    """A grid of size 1e-300 ended in the core's ValueError ('finite corners with hi > lo')."""
    d = _grid_scene("x.npz")
    g = d["water"][0]["iop_grid"]
    g.pop("file")
    g.update(density=np.ones((2, 2, 2)).tolist(), size=size, origin=origin)
    with pytest.raises(SceneError) as e:
        Scene.from_dict(d)
    assert e.value.field == field, str(e.value)
    g.update(size=[2.0, 2.0, 2.0], origin=[-1, -1, -2])
    render(Scene.from_dict(d), samples=1, radiometer_samples=64)
