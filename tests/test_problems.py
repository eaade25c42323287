"""Canonical problems 1 and 2 of Mobley et al. (1993) from the repository's scene files."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from photic.problems import CONFIGS, problem_scene, reference_table, run_problem
from photic.scene import Scene, load_scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

SCENES = Path(__file__).resolve().parents[1] / "examples" / "problems"


def test_scene_files_are_the_generated_ones():
    for problem, omega0 in CONFIGS:
        d = problem_scene(problem, omega0)
        assert load_scene(SCENES / f"{d['name']}.json") == Scene.from_dict(d)


@pytest.mark.parametrize("problem,omega0", [(1, 0.2), (2, 0.9)])
def test_problem_at_a_small_budget(problem, omega0):
    """Every value within (2 CV + 0.005) ref + 3 SE at 40,000 samples per radiometer."""
    scene = load_scene(SCENES / f"mobley1993_problem{problem}_omega{omega0:g}.json")
    records = run_problem(scene, problem, omega0, reference_table(), samples=40_000)
    failed = [r for r in records if not r["passed"]]
    assert not failed, failed


@pytest.mark.slow
def test_all_36_values_with_the_command():
    p = subprocess.run([sys.executable, "-m", "photic", "problems", "--json"], capture_output=True, text=True)
    records = json.loads(p.stdout)
    assert len(records) == 36, records
    failed = [r for r in records if not r["passed"]]
    assert not failed, failed
