"""The command line as a user runs it: render a scene, get an EXR and radiometer tables."""
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "coastal_shelf.json"


def run(*args):
    return subprocess.run([sys.executable, "-m", "photic", *map(str, args)], capture_output=True, text=True)


def test_render_writes_exr_and_tables(tmp_path):
    p = run("render", EXAMPLE, "--out", tmp_path, "--samples", "2", "--radiometer-samples", "2000",
            "--threads", "2", "--quiet")
    assert p.returncode == 0, p.stderr
    assert "profile[0].Ed" in p.stdout and "+-" in p.stdout
    exr = tmp_path / "coastal_shelf_diver.exr"
    with OpenEXR.File(str(exr)) as f:
        ch = f.channels()
        hdr = f.header()
        assert set(ch) >= {"radiance.450", "radiance.550", "radiance.650", "variance.550", "samples"}
        img = ch["radiance.550"].pixels
        assert img.shape == (120, 160) and np.isfinite(img).all() and img.mean() > 0
        assert float(ch["samples"].pixels[0, 0]) == 2.0
        assert "W m^-2 sr^-1" in hdr["photic:units.radiance"]
    rows = list(csv.DictReader(line for line in open(tmp_path / "coastal_shelf_radiometers.csv")
                               if not line.startswith("#")))
    assert {r["name"] for r in rows} >= {"profile[2].Eo", "Lu_1m"}
    assert all(float(r["stderr"]) >= 0 for r in rows)
    doc = json.loads((tmp_path / "coastal_shelf_radiometers.json").read_text())
    assert doc["radiometers"][0]["units"].startswith("W m^-2")


def test_bad_scene_is_a_clear_error_not_a_traceback(tmp_path):
    bad = json.loads(EXAMPLE.read_text())
    bad["water"][0]["iops"]["absorption"][1] = -0.5
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(bad))
    p = run("render", f, "--out", tmp_path)
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    assert "sea" in p.stderr and "absorption" in p.stderr


def test_help_documents_commands():
    p = run("--help")
    assert p.returncode == 0 and "render" in p.stdout and "bench" in p.stdout
    p = run("render", "--help")
    assert "--samples" in p.stdout and "--seed" in p.stdout and "--threads" in p.stdout


def test_integrator_and_cone_overrides(tmp_path):
    p = run("render", EXAMPLE, "--out", tmp_path, "--samples", "1", "--radiometer-samples", "1000",
            "--integrator", "path", "--quiet")
    assert p.returncode == 0, p.stderr
    assert "path;" in p.stdout
    p = run("render", EXAMPLE, "--out", tmp_path, "--samples", "1", "--radiometer-samples", "1000",
            "--forward-cone", "45", "--quiet")
    assert p.returncode == 2 and "forward_cone_deg" in p.stderr and "Traceback" not in p.stderr
