"""A sea-surface patch is a single-valued height field covering its period exactly once (issue
49, kind 4): a patch with a hole or with two stacked sheets rendered with exit 0 and Ed at 1 m
49 % / 26 % of the right value; now the loader refuses it, naming surface.triangles and
saying what is wrong. Property-based: any height field on any grid (shared or separate
vertices, any split of the quads) loads; removing triangles or adding a sheet never does."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photic.scene import Scene, SceneError

from test_robustness import small


def grid_patch(nx, ny, lx, ly, heights, flip=None, shared=True, origin=(0.0, 0.0)):
    """A height-field patch: (nx + 1) x (ny + 1) grid over [0, lx] x [0, ly] + origin, heights
    (nx + 1, ny + 1); each quad split along either diagonal (``flip``); ``shared=False`` gives
    every triangle its own three vertices."""
    xs = origin[0] + np.linspace(0.0, lx, nx + 1)
    ys = origin[1] + np.linspace(0.0, ly, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.asarray(heights, float).ravel()], axis=1)
    idx = lambda i, j: i * (ny + 1) + j
    tri = []
    for i in range(nx):
        for j in range(ny):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            tri += [[a, b, d], [b, c, d]] if flip is not None and flip[i][j] else [[a, b, c], [a, c, d]]
    tri = np.array(tri)
    if not shared:
        v, tri = v[tri.ravel()], np.arange(3 * len(tri)).reshape(-1, 3)
    return v, tri


def surface(v, tri, lx, ly) -> dict:
    return {"kind": "patch", "vertices": np.asarray(v).tolist(), "triangles": np.asarray(tri).tolist(),
            "period": [lx, ly]}


def load(surf) -> Scene:
    d = small()
    d["water"][0]["surface"] = surf
    return Scene.from_dict(d)


def refused(surf, text: str) -> str:
    with pytest.raises(SceneError) as e:
        load(surf)
    msg = str(e.value)
    assert "surface.triangles" in msg and text in msg, msg
    return msg


@st.composite
def height_fields(draw):
    nx, ny = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    lx, ly = draw(st.sampled_from([1e-3, 0.5, 2.0, 37.0, 1e4])), draw(st.sampled_from([1e-3, 1.0, 50.0]))
    amp = draw(st.sampled_from([0.0, 1e-4, 0.1])) * min(lx, ly)
    heights = draw(st.lists(st.floats(-1.0, 1.0), min_size=(nx + 1) * (ny + 1),
                            max_size=(nx + 1) * (ny + 1)))
    flip = [[draw(st.booleans()) for _ in range(ny)] for _ in range(nx)]
    origin = (draw(st.sampled_from([0.0, -3.5, 1e3])), draw(st.sampled_from([0.0, 2.25])))
    v, tri = grid_patch(nx, ny, lx, ly, amp * np.reshape(heights, (nx + 1, ny + 1)), flip,
                        draw(st.booleans()), origin)
    return v, tri, lx, ly


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(height_fields())
def test_any_height_field_over_one_period_loads(patch):
    v, tri, lx, ly = patch
    load(surface(v, tri, lx, ly))


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(height_fields(), st.data())
def test_a_patch_with_triangles_missing_is_refused(patch, data):
    v, tri, lx, ly = patch
    if len(tri) < 2:
        return
    k = data.draw(st.integers(1, len(tri) - 1))
    drop = data.draw(st.lists(st.integers(0, len(tri) - 1), min_size=k, max_size=k, unique=True))
    kept = np.delete(tri, drop, axis=0)
    with pytest.raises(SceneError, match="surface.triangles"):
        load(surface(v, kept, lx, ly))


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(height_fields(), st.sampled_from([-0.5, -1e-3, 0.0, 0.25]), st.data())
def test_a_patch_with_a_second_sheet_or_a_copied_triangle_is_refused(patch, dz, data):
    v, tri, lx, ly = patch
    if data.draw(st.booleans()):  # a whole second sheet below (or on) the first
        v2 = np.concatenate([v, v + [0.0, 0.0, dz * max(lx, ly)]])
        tri2 = np.concatenate([tri, tri + len(v)])
    else:  # one triangle twice
        i = data.draw(st.integers(0, len(tri) - 1))
        v2, tri2 = v, np.concatenate([tri, tri[i:i + 1]])
    with pytest.raises(SceneError, match="surface.triangles"):
        load(surface(v2, tri2, lx, ly))


def test_the_issues_hole_and_stacked_sheets_are_named():
    v, tri = grid_patch(8, 8, 2.0, 2.0, np.zeros((9, 9)))
    holed = np.delete(tri, [40, 41, 42, 43], axis=0)  # two quads in the middle
    refused(surface(v, holed, 2.0, 2.0), "a hole")
    stacked_v = np.concatenate([v, v - [0, 0, 0.5]])
    refused(surface(stacked_v, np.concatenate([tri, tri + len(v)]), 2.0, 2.0), "more than one sheet")


def test_a_hole_balanced_by_an_overlap_is_refused_by_its_open_edges():
    """The area alone balances: two triangles removed in one place, the same area added
    again (twice over one quad) in another; the hole's edges inside the period give it away."""
    v, tri = grid_patch(6, 6, 3.0, 3.0, np.zeros((7, 7)))
    tri = np.concatenate([np.delete(tri, [14, 15], axis=0), tri[30:32]])
    with pytest.raises(SceneError, match="surface.triangles") as e:
        load(surface(v, tri, 3.0, 3.0))
    assert "hole" in str(e.value) or "more than two" in str(e.value), str(e.value)
