"""The engine never imports Blender: rendering a scene file, the command line and a batch job
run in a process where ``bpy`` cannot be imported, and leave neither ``bpy`` nor the add-on in
``sys.modules`` (issue 29, step 1's guard; ``photic blend`` and ``.blend`` job inputs are the
add-on's and are not exercised here)."""
from __future__ import annotations

import json
import subprocess
import sys

from test_robustness import small

CHILD = r"""
import json, sys
sys.modules["bpy"] = None  # importing bpy now raises ImportError: Blender is not importable
from photic.cli import main
from photic.distributed import parse_job, run_job
out, scene = sys.argv[1], sys.argv[2]
assert main(["render", scene, "--out", out + "/render", "--quiet"]) == 0
job = parse_job({"photic_job": 1, "name": "j", "inputs": [scene], "samples": 1,
                 "radiometer_samples": 256}, out)
report = run_job(job, out + "/batch", workers=0, progress=False)
assert all(s["status"] == "done" for s in report.items.values()), report.items
import photic.render, photic.denoise, photic.output, photic.scene  # noqa: E401
loaded = sorted(m for m in sys.modules if m == "bpy" or m.startswith(("bpy.", "photic_blender")))
assert sys.modules["bpy"] is None and loaded == ["bpy"], loaded
print("OK")
"""


def test_engine_runs_without_blender_importable(tmp_path):
    scene = tmp_path / "s.json"
    scene.write_text(json.dumps(small()))
    p = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path), str(scene)], capture_output=True,
                       text=True, timeout=600)
    assert p.returncode == 0 and p.stdout.strip().endswith("OK"), p.stderr[-3000:]
