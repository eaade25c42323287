"""docs/tutorial-cli.md runs as written.

The tutorial's fenced blocks are taken in document order, by their info string:

- ```` ```json file=NAME ````: written to NAME in the working folder;
- ```` ```bash run ```` and ```` ```python run ````: run there (bash -e; the environment's
  python), with PHOTIC_REPO set to this repository and its .venv/bin first on PATH, as after
  the tutorial's first step; each must exit with status 0;
- ```` ```text output ````: what the run block before it printed. A line with values
  ``V +- E`` is found in the real output by the words before its first value and every pair
  must agree with the real one within 4 combined standard errors (5 where either is flagged
  '?'); any other line must appear in the output (spaces normalised; a line ending in "..."
  as a prefix; a line "..." skips);
- ```` ```text files ````: every path listed must exist after the run block before it.

Blocks with any other info string are prose. Then the claims the prose makes in words are
checked: Ed in the air equals E_sun cos(theta_s) + E_sky within 4 standard errors (render and
every item of the sweep), the exact mode leaves a radiometer short of its target, the tables'
columns are those the text names. Runs in a temporary folder, about 30 s on 2 cores.
"""
from __future__ import annotations

import csv
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TUTORIAL = REPO / "docs" / "tutorial-cli.md"
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.S | re.M)
PAIR = re.compile(r"(-?[0-9][0-9.]*(?:e[-+]?[0-9]+)?) \+- ([0-9][0-9.]*(?:e[-+]?[0-9]+)?)")


def blocks(text: str) -> list[tuple[str, str]]:
    """(info string, body) of every fenced block, in order."""
    return [(m.group(1).strip(), m.group(2)) for m in FENCE.finditer(text)]


def _norm(s: str) -> str:
    return " ".join(s.split())


def check_output(shown: str, real: str) -> list[str]:
    """Problems of a ```text output block against what the command printed."""
    problems = []
    real_lines = [_norm(line) for line in real.splitlines()]
    real_text = "\n".join(real_lines)
    for line in shown.splitlines():
        line = _norm(line)
        if not line or line == "...":
            continue
        pairs = list(PAIR.finditer(line))
        if not pairs:
            want = line[:-3].rstrip() if line.endswith("...") else line
            if want not in real_text:
                problems.append(f"not in the output: {line!r}")
            continue
        key = line[:pairs[0].start()]
        match = [r for r in real_lines if r.startswith(key) and PAIR.search(r)]
        if len(match) != 1:
            problems.append(f"{len(match)} output lines start with {key!r}")
            continue
        got = list(PAIR.finditer(match[0]))
        if len(got) != len(pairs):
            problems.append(f"{line!r} against {match[0]!r}: other number of values")
            continue
        flagged = "?" in line or "?" in match[0]
        for a, b in zip(pairs, got):
            va, ea, vb, eb = (float(a.group(1)), float(a.group(2)), float(b.group(1)), float(b.group(2)))
            z = abs(va - vb) / max(math.hypot(ea, eb), 1e-300)
            if z > (5.0 if flagged else 4.0):
                problems.append(f"{key.strip()}: shown {va} +- {ea}, ran {vb} +- {eb} (z = {z:.1f})")
    return problems


@pytest.fixture(scope="module")
def tutorial_run(tmp_path_factory):
    """Runs the tutorial once; returns the folder and the outputs of its run blocks."""
    work = tmp_path_factory.mktemp("tutorial")
    env = dict(os.environ)
    venv_bin = REPO / ".venv" / "bin"
    bindir = venv_bin if venv_bin.is_dir() else Path(sys.executable).parent
    env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
    env["PHOTIC_REPO"] = str(REPO)
    env.pop("PYTHONPATH", None)
    python = str(bindir / "python") if (bindir / "python").exists() else sys.executable
    outputs = []
    last = None
    problems = []
    for info, body in blocks(TUTORIAL.read_text()):
        words = info.split()
        if not words:
            continue
        lang, tags = words[0], words[1:]
        if lang == "json" and tags and tags[0].startswith("file="):
            (work / tags[0][5:]).write_text(body)
        elif lang in ("bash", "python") and "run" in tags:
            cmd = ["bash", "-e", "-c", body] if lang == "bash" else [python, "-c", body]
            p = subprocess.run(cmd, cwd=work, env=env, capture_output=True, text=True, timeout=300)
            last = p.stdout + p.stderr
            outputs.append((lang, body, last))
            assert p.returncode == 0, f"tutorial block failed ({p.returncode}):\n{body}\n{last}"
        elif lang == "text" and "output" in tags:
            assert last is not None, "an output block before any run block"
            problems += check_output(body, last)
        elif lang == "text" and "files" in tags:
            for name in body.split():
                if not (work / name).exists():
                    problems.append(f"file not written: {name}")
    return work, outputs, problems


def test_every_block_runs_and_prints_what_the_text_shows(tutorial_run):
    work, outputs, problems = tutorial_run
    assert len(outputs) >= 8, "the tutorial's run blocks were not found"
    assert not problems, "\n".join(problems)


def _analytic_ed_air(scene: dict) -> list[float]:
    """E_sun cos(theta_s) + E_sky per band: Ed above the water (docs/physics.md)."""
    sun, sky = scene["sun"], scene["sky"]
    mu = math.cos(math.radians(sun["zenith_deg"]))
    return [e * mu + s for e, s in zip(sun["irradiance"], sky["irradiance"])]


def test_ed_in_air_is_sun_plus_sky(tutorial_run):
    work = tutorial_run[0]
    scene = json.loads((work / "bay.json").read_text())
    table = json.loads((work / "out" / "bay_radiometers.json").read_text())
    r = next(r for r in table["radiometers"] if r["name"] == "Ed_air")
    for k, ref in enumerate(_analytic_ed_air(scene)):
        assert abs(r["value"][0][k] - ref) <= 4 * r["stderr"][0][k], (k, r["value"], ref)
    summary = json.loads((work / "sweep" / "summary.json").read_text())
    assert len(summary["items"]) == 3
    for item in summary["items"]:
        s = dict(scene, sun=dict(scene["sun"], zenith_deg=item["params"]["sun.zenith_deg"]))
        ed = item["radiometers"]["Ed_air"]
        for k, ref in enumerate(_analytic_ed_air(s)):
            assert abs(ed["value"][k] - ref) <= 4 * ed["stderr"][k], (item["name"], k, ref)


def test_the_claims_about_the_tables(tutorial_run):
    work = tutorial_run[0]
    text = TUTORIAL.read_text()
    with open(work / "out" / "bay_radiometers.csv") as f:
        first = f.readline()
        columns = next(csv.reader([f.readline()]))
    assert first.startswith("# photic")
    for col in ("name", "quantity", "x_m", "y_m", "z_m", "medium", "band", "center_nm", "bin",
                "value", "stderr", "stderr_trusted", "stderr_note", "value_beam_volume",
                "stderr_path", "samples", "units"):
        assert col in columns and f"`{col}`" in text, col
    # Both target-error renders reach the target everywhere with trusted errors (the text says
    # so), the exact mode with more samples than the forward cone's.
    exact = json.loads((work / "exact" / "bay_radiometers.json").read_text())
    assert all(r["target_reached"] for r in exact["radiometers"])
    cone = json.loads((work / "cone" / "bay_radiometers.json").read_text())
    assert sum(r["samples"] for r in exact["radiometers"]) > sum(r["samples"] for r in cone["radiometers"])
    eu = [r["samples"] for r in exact["radiometers"] if r["quantity"] == "Eu"]
    assert min(eu) > max(r["samples"] for r in exact["radiometers"] if r["quantity"] == "Ed")
    assert all(r["target_reached"] for r in cone["radiometers"])
    assert all(all(all(row) for row in r["stderr_trusted"]) for r in cone["radiometers"])
    assert cone["stats"]["forward_cone_deg"] == 3.0
    # "The values agree with the exact mode's within their error bars."
    for re_, rc in zip(exact["radiometers"], cone["radiometers"]):
        for k in range(2):
            ve, ee = re_["value"][0][k], re_["stderr"][0][k]
            vc, ec = rc["value"][0][k], rc["stderr"][0][k]
            assert abs(ve - vc) <= 5 * math.hypot(ee, ec), (re_["name"], k, ve, ee, vc, ec)


def test_check_output_catches_a_wrong_number():
    real = "cast[1].Ed Ed sea 450 1.62727 +- 0.007 0.43%\nsome line\n"
    assert check_output("cast[1].Ed Ed sea 450 1.62 +- 0.007 0.43%\nsome line", real) == []
    assert check_output("cast[1].Ed Ed sea 450 1.70 +- 0.007 0.43%", real)
    assert check_output("another line", real)
    assert check_output("some ...", real) == []
