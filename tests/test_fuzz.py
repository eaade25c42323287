"""Fuzzing the scene loader and a 1-spp render with hypothesis: a valid scene with one to
three values replaced by anything JSON can hold (huge, tiny, negative, NaN-like strings,
lists, objects, nesting) must load or fail with a SceneError, never another exception; the
scenes that load must render in a process of their own without a signal, with finite
outputs or a clear error (exit status 2).

The default suite runs a short budget; ``-m slow`` a long one."""
from __future__ import annotations

import copy
import json
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photic.scene import Scene, SceneError

from test_scene import valid_dict

NUMBERS = st.one_of(
    st.integers(min_value=-2**70, max_value=2**70),
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0, -1, 1e-300, 1e300, 1e308, -1e308, 2**63, 2**64, 1e19, 0.5, 1e6, 65536]),
)
LEAVES = st.one_of(NUMBERS, st.booleans(), st.none(), st.text(max_size=12),
                   st.sampled_from(["", "nan", "inf", "-inf", "1e999", "../../etc/passwd", "/dev/zero"]))
VALUES = st.recursive(LEAVES, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                      st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                      max_leaves=8)


def _paths(d, prefix=()):
    """Every path to a value in a JSON-like document."""
    out = []
    if isinstance(d, dict):
        for k, v in d.items():
            out.append(prefix + (k,))
            out += _paths(v, prefix + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d[:4]):
            out.append(prefix + (i,))
            out += _paths(v, prefix + (i,))
    return out


BASE = valid_dict()
PATHS = _paths(BASE)


def _mutate(d, path, value):
    node = d
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return d


@st.composite
def mutated(draw, max_changes=3):
    d = copy.deepcopy(BASE)
    d["settings"].update(samples=1, radiometer_samples=64, threads=1)
    d["cameras"][0]["resolution"] = [8, 6]
    d["radiometer_arrays"][0]["line"]["count"] = 3
    for _ in range(draw(st.integers(1, max_changes))):
        paths = _paths(d)
        numeric = [p for p in paths if _is_number(_get(d, p))]
        if numeric and draw(st.booleans()):  # an extreme but typed value: more scenes load
            path = draw(st.sampled_from(numeric))
            value = _get(d, path) * draw(st.sampled_from(SCALES))
        else:
            path = draw(st.sampled_from(paths))
            value = draw(VALUES)
        try:
            _mutate(d, path, value)
        except (KeyError, IndexError, TypeError):
            pass
    return d


SCALES = [-1, 0, 1e-9, 1e-3, 0.5, 2, 10, 1e3, 1e6, 1e12]


def _get(d, path):
    for key in path:
        d = d[key]
    return d


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _load(d):
    try:
        return Scene.from_dict(d)
    except SceneError:
        return None


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(mutated())
def test_the_loader_raises_only_scene_errors(d):
    _load(d)


@pytest.mark.slow
@settings(max_examples=20000, deadline=None, suppress_health_check=list(HealthCheck))
@given(mutated(max_changes=5))
def test_the_loader_raises_only_scene_errors_long(d):
    _load(d)


RENDER = """
import json, math, sys
import numpy as np
from photic.scene import Scene, SceneError
from photic.render import render
d = json.loads(sys.stdin.read())
try:
    res = render(Scene.from_dict(d), samples=1, radiometer_samples=64, threads=1)
except SceneError as e:
    print("SCENE_ERROR", e)
    sys.exit(2)
ok = all(np.isfinite(img.mean).all() and np.isfinite(img.variance[np.isfinite(img.variance)]).all()
         for img in res.images.values())
ok = ok and all(np.isfinite(r.mean).all() for r in res.radiometers)
print("FINITE" if ok else "NOT_FINITE")
sys.exit(0 if ok else 3)
"""


def _render_in_child(d) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", RENDER], input=json.dumps(d, allow_nan=False),
                          capture_output=True, text=True, timeout=300)


def _check_render(d):
    if _load(copy.deepcopy(d)) is None:
        return
    try:
        json.dumps(d, allow_nan=False)
    except ValueError:
        return
    p = _render_in_child(d)
    assert p.returncode >= 0, f"killed by signal {-p.returncode}: {p.stderr[-2000:]}"
    assert p.returncode in (0, 2), (p.returncode, p.stdout[-500:], p.stderr[-2000:])


@settings(max_examples=8, deadline=None, suppress_health_check=list(HealthCheck))
@given(mutated(max_changes=2))
def test_a_loaded_scene_renders_without_a_signal_and_finite(d):
    _check_render(d)


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(mutated(max_changes=3))
def test_a_loaded_scene_renders_without_a_signal_and_finite_long(d):
    _check_render(d)
