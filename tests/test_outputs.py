"""Component passes in the written outputs (EXR layers, radiometer tables) and the beam
footprint mesh of `photic render --beam-mesh`."""
import csv
import json
import subprocess
import sys

import numpy as np
import OpenEXR
import pytest

from geometry import box
from photic.compile import band_groups, compile_scene
from photic.footprints import footprint_mesh, load_footprints
from photic.output import write_outputs
from photic.render import COMPONENTS, render
from photic.scene import Scene

BANDS = [{"name": "450", "center_nm": 450, "width_nm": 10}, {"name": "550", "center_nm": 550, "width_nm": 10}]


def run(*args):
    return subprocess.run([sys.executable, "-m", "photic", *map(str, args)], capture_output=True, text=True)


def base_scene(surface, bottom=4.0, name="outputs"):
    v, t = box([-0.4, -0.4, -bottom], [0.4, 0.4, -bottom + 0.8])
    return {"photic_scene": 1, "name": name, "bands": BANDS,
            "materials": {"sand": {"type": "lambertian", "reflectance": [0.4, 0.3]},
                          "rock": {"type": "lambertian", "reflectance": [0.2, 0.25]}},
            "meshes": [{"name": "rock", "material": "rock", "vertices": v, "triangles": t}],
            "water": [{"name": "sea", "type": "ocean", "surface": surface,
                       "bottom": {"depth": bottom, "material": "sand"},
                       "iops": {"absorption": [0.05, 0.08],
                                "b": [0.2, 0.15], "phase": {"type": "petzold"}}}],
            "sun": {"zenith_deg": 25.0, "azimuth_deg": 40.0, "irradiance": [1.0, 1.2],
                    "angular_diameter_deg": 0.53},
            "sky": {"type": "uniform", "irradiance": [0.3, 0.25]},
            "cameras": [{"name": "cam", "type": "perspective", "position": [1.5, -1.5, -1.0],
                         "look_at": [0, 0, -bottom + 0.4], "up": [0, 0, 1], "fov_deg": 60,
                         "resolution": [16, 12]}],
            "radiometers": [{"name": "Ed_1", "quantity": "Ed", "position": [0.8, 0.3, -1.0]},
                            {"name": "Eo_2", "quantity": "Eo", "position": [-0.7, 0.2, -2.0]},
                            {"name": "Lu_1", "quantity": "radiance", "position": [0.9, -0.6, -1.0]},
                            {"name": "Ed_air", "quantity": "Ed", "position": [0.0, 0.0, 1.0]}],
            "settings": {"integrator": "hybrid", "seed": 3, "samples": 4, "radiometer_samples": 8192,
                         "forward_cone_deg": 0}}


def wavy_patch(n=16, size=2.0, amp=0.05):
    xs = np.linspace(0.0, size, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z = amp * np.sin(2 * np.pi * X / size) * np.cos(2 * np.pi * Y / size)
    v = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    idx = lambda i, j: i * (n + 1) + j
    tri = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            tri += [[a, b, c], [a, c, d]]
    return {"kind": "patch", "vertices": v.tolist(), "triangles": tri, "period": [size, size]}


@pytest.fixture(scope="module")
def flat_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("flat")
    scene = Scene.from_dict(base_scene({"kind": "flat", "z": 0.0}))
    result = render(scene, threads=2)
    return result, write_outputs(out, result)


def test_exr_has_component_layers_that_sum_to_radiance(flat_result):
    result, written = flat_result
    assert result.stats["integrator"] == "hybrid"
    (exr,) = written["images"]
    with OpenEXR.File(str(exr)) as f:  # pixels are read lazily: copy them inside
        ch = {name: c.pixels.astype(np.float64) for name, c in f.channels().items()}
        hdr = dict(f.header())
    for band in ("450", "550"):
        total = ch[f"radiance.{band}"]
        parts = [ch[f"{c}.{band}"] for c in ("beam_surface", "beam_volume", "path")]
        assert total.shape == (12, 16) and total.mean() > 0
        assert all(p.shape == total.shape and np.isfinite(p).all() for p in parts)
        # float32 layers: each rounded to half an ulp, so the sum is off by a few ulps at most
        tol = 4 * np.finfo(np.float32).eps * (np.abs(total) + sum(np.abs(p) for p in parts)) + 1e-30
        assert (np.abs(sum(parts) - total) <= tol).all()
        assert parts[0].max() > 0 and parts[2].max() > 0  # sunlit bottom and sky both seen
    assert hdr["photic:integrator"] == "hybrid"
    assert float(hdr["photic:forward_cone_deg"]) == 0.0
    assert "underwater surfaces" in hdr["photic:component.beam_surface"]
    assert "single scattering" in hdr["photic:component.beam_volume"]
    assert "path tracing" in hdr["photic:component.path"]


def test_radiometer_tables_have_components_that_sum_to_value(flat_result):
    result, written = flat_result
    csv_path, json_path = written["tables"]
    rows = list(csv.DictReader(line for line in open(csv_path) if not line.startswith("#")))
    assert len(rows) == 4 * 2
    for r in rows:
        parts = [float(r[f"value_{c}"]) for c in COMPONENTS]
        assert all(float(r[f"stderr_{c}"]) >= 0 for c in COMPONENTS)
        assert sum(parts) == pytest.approx(float(r["value"]), rel=1e-12, abs=1e-300)
    by = {(r["name"], r["band"]): r for r in rows}
    assert float(by["Ed_1", "550"]["value_beam_direct"]) > 0  # the refracted sun reaches it
    assert float(by["Ed_air", "550"]["value_beam_direct"]) == 0  # above water: the sun is in `path`
    doc = json.loads(json_path.read_text())
    assert set(doc["components"]) == set(COMPONENTS)
    for rad in doc["radiometers"]:
        comps = rad["components"]
        assert set(comps) == set(COMPONENTS)
        total = np.array(rad["value"])
        parts = sum(np.array(comps[c]["value"]) for c in COMPONENTS)
        np.testing.assert_allclose(parts, total, rtol=1e-12, atol=1e-300)
        assert all(np.array(comps[c]["stderr"]).shape == total.shape for c in COMPONENTS)


def test_csv_rows_are_the_table_rows_cell_for_cell(tmp_path):
    """The CSV is written a column at a time (10^6 bins in seconds): it must hold exactly the
    rows of iter_radiometer_rows, also where values are not finite, not trusted, a component
    is missing, a name would be a spreadsheet formula and a radiometer has bins."""
    import copy

    from photic.output import CSV_FIELDS, _cell, iter_radiometer_rows, write_radiometer_csv

    d = base_scene({"kind": "flat", "z": 0.0})
    d["cameras"] = []
    d["radiometers"] = [{"name": "=Ed", "quantity": "Ed", "position": [0.8, 0.3, -1.0]},
                        {"name": "L", "quantity": "radiance_distribution", "position": [0.1, 0.0, -2.0],
                         "polar_bins": 6, "azimuth_bins": 8},
                        {"name": "Lu", "quantity": "radiance", "position": [0.9, -0.6, -1.0]}]
    d["settings"]["radiometer_samples"] = 512
    result = copy.deepcopy(render(Scene.from_dict(d), threads=2))
    ed, dist, lu = result.radiometers
    ed.mean[0, 1] = np.nan
    dist.stderr[5, 0] = np.inf
    dist.reliable = np.ones_like(dist.mean, bool)
    dist.reliable[7, 1] = False
    dist.notes = ["heavy tails"]
    lu.components.pop("path")
    path = write_radiometer_csv(tmp_path, result)
    got = list(csv.reader(line for line in open(path, newline="") if not line.startswith("#")))
    assert got[0] == CSV_FIELDS
    want = [[str(_cell(row.get(k, ""))) for k in CSV_FIELDS] for row in iter_radiometer_rows(result)]
    assert len(want) == (1 + 48 + 1) * 2
    assert got[1:] == want
    assert got[1][0] == "'=Ed" and got[2][CSV_FIELDS.index("value")] == ""
    assert got[1 + 2 + 7 * 2 + 1][CSV_FIELDS.index("stderr_note")] == "heavy tails"
    # built a few bins at a time: the same rows across the chunks' edges
    from photic.output import _csv_rows
    assert list(_csv_rows(dist, result.bands, chunk=5)) == list(_csv_rows(dist, result.bands))
    # the JSON's finite float tables as json.dumps writes each row (written by repr, faster)
    from photic.output import write_radiometer_json
    text = write_radiometer_json(tmp_path, result).read_text()
    for a in (dist.mean, ed.stderr, lu.mean):
        assert np.isfinite(a).all()
        assert "[" + ",".join("\n  " + json.dumps(row) for row in a.tolist()) + "]" in text
    assert json.loads(text)["radiometers"][1]["stderr"][5][0] is None  # (inf: null, the other way)


def test_beam_mesh_of_a_wavy_ocean(tmp_path):
    d = base_scene(wavy_patch(), bottom=3.0, name="wavy")
    d["meshes"] = []  # every ray reaches the bottom
    d["cameras"][0]["resolution"] = [8, 6]
    d["settings"]["samples"] = 1
    d["settings"]["radiometer_samples"] = 4096
    f = tmp_path / "wavy.json"
    f.write_text(json.dumps(d))
    ply = tmp_path / "beams" / "out.ply"
    p = run("render", f, "--out", tmp_path, "--threads", "2", "--quiet", "--beam-mesh", ply)
    assert p.returncode == 0, p.stderr
    assert "Traceback" not in p.stderr
    assert "hybrid" in p.stdout and str(ply) in p.stdout
    mesh = load_footprints(ply)
    assert len(mesh.faces) > 0

    scene = Scene.from_dict(d)
    core = compile_scene(scene, band_groups(len(scene.bands))[0], hybrid=True, forward_cone_deg=0)
    core.build_beams(tuple(scene.sun.direction), 0)
    hit = core.prism_arrays()[4]
    assert np.asarray(hit).all()  # every ray ends on the bottom
    assert len(mesh.faces) == core.beam_count
    total = core.beam_total_flux()
    assert total > 0
    assert float(mesh.face_attributes["phi"].sum()) == pytest.approx(total, rel=1e-6)
    assert (mesh.face_attributes["area"] > 0).all()
    # the footprints lie on the bottom, 3 m below the mean surface
    np.testing.assert_allclose(mesh.vertices[:, 2], -3.0, atol=1e-4)


def test_beam_mesh_leaves_out_rays_that_hit_nothing():
    d = base_scene(wavy_patch(n=4), bottom=3.0, name="bottomless")
    d["meshes"] = []
    d["water"][0]["bottom"] = None
    scene = Scene.from_dict(d)
    core = compile_scene(scene, hybrid=True, forward_cone_deg=0)
    core.build_beams(tuple(scene.sun.direction), 0)
    assert core.beam_count > 0
    assert not np.asarray(core.prism_arrays()[4]).any()  # no ray meets a surface
    assert len(footprint_mesh(core).faces) == 0


def test_beam_mesh_errors_without_beams(tmp_path):
    d = base_scene({"kind": "flat", "z": 0.0}, name="flat")
    d["cameras"][0]["resolution"] = [4, 3]
    d["settings"].update(samples=1, radiometer_samples=1024)
    f = tmp_path / "flat.json"
    f.write_text(json.dumps(d))
    p = run("render", f, "--out", tmp_path, "--quiet", "--beam-mesh", tmp_path / "m.ply")
    assert p.returncode == 1 and "Traceback" not in p.stderr
    assert "no beams" in p.stderr and not (tmp_path / "m.ply").exists()
    d["sun"] = None
    d["settings"]["integrator"] = "path"
    f.write_text(json.dumps(d))
    p = run("render", f, "--out", tmp_path, "--quiet", "--beam-mesh", tmp_path / "m.ply")
    assert p.returncode == 2 and "Traceback" not in p.stderr and "no sun" in p.stderr
