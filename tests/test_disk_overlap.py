"""The sun-disk blur's kernel: the area of a triangle within the unit disk (what a blurred
prism's irradiance at a point is made of) against an independent polygon clipping, and the
fast arctangent it uses against numpy's."""
import numpy as np
import pytest

from photic._core import Scene

pytestmark = pytest.mark.gate  # the beams' geometry (tests/test_gate.py)


def clipped_area(tri: np.ndarray, n: int = 40000) -> float:
    """Area of the triangle within the unit disk: the disk as an n-gon whose area is pi (its
    radius scaled up), clipped by the triangle's three half-planes (Sutherland-Hodgman,
    vectorised). The polygon's boundary strays from the circle by ~pi^2 / (3 n^2) ~ 2e-9."""
    phi = 2 * np.pi * np.arange(n) / n
    r = np.sqrt(2 * np.pi / (n * np.sin(2 * np.pi / n)))
    poly = np.stack([r * np.cos(phi), r * np.sin(phi)], axis=1)
    if np.cross(tri[1] - tri[0], tri[2] - tri[0]) < 0:
        tri = tri[::-1]
    for j in range(3):
        a, b = tri[j], tri[(j + 1) % 3]
        if len(poly) == 0:
            return 0.0
        side = np.cross(b - a, poly - a)  # >= 0: inside
        nxt = np.roll(poly, -1, axis=0)
        side_n = np.roll(side, -1)
        inside, inside_n = side >= 0, side_n >= 0
        with np.errstate(divide="ignore", invalid="ignore"):
            f = side / (side - side_n)
            cut = poly + f[:, None] * (nxt - poly)  # (used only where the ends differ in side)
        # per polygon edge: the crossing (when its ends are on two sides), then its end (if inside)
        pts = np.stack([cut, nxt], axis=1)
        keep = np.stack([inside != inside_n, inside_n], axis=1)
        poly = pts[keep]
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def test_triangle_within_the_unit_disk_matches_polygon_clipping():
    rng = np.random.default_rng(7)
    tris = [rng.uniform(-1.6, 1.6, size=(3, 2)) for _ in range(40)]
    tris += [np.array([[-10.0, -10.0], [10.0, -10.0], [0.0, 10.0]]),  # holds the disk: pi
             np.array([[0.2, 0.1], [0.5, 0.2], [0.1, 0.6]]),  # within the disk: its own area
             np.array([[2.0, 2.0], [3.0, 2.0], [2.0, 3.0]]),  # outside: 0
             np.array([[0.5, -5.0], [0.5, 5.0], [9.0, 0.0]]),  # a half-plane x > 0.5 (segment)
             np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]]),  # a quarter disk
             np.array([[-3.0, 0.999], [3.0, 0.999], [0.0, 3.0]])]  # a sliver of a cap
    for tri in tris:
        got = Scene.unit_disk_triangle_overlap(tri[:, 0].tolist(), tri[:, 1].tolist())
        want = clipped_area(tri)
        assert abs(got - want) < 2e-7, (tri.tolist(), got, want)
    # closed forms
    seg = np.arccos(0.5) - 0.5 * np.sqrt(1 - 0.25)  # the circular segment beyond x = 0.5
    half_plane = np.array([[0.5, -5.0], [0.5, 5.0], [9.0, 0.0]])
    assert Scene.unit_disk_triangle_overlap(half_plane[:, 0].tolist(), half_plane[:, 1].tolist()) == pytest.approx(seg, abs=1e-13)
    assert Scene.unit_disk_triangle_overlap([0, 5, 0], [0, 0, 5]) == pytest.approx(np.pi / 4, abs=1e-13)


def test_fast_arctangent_matches_numpy_to_1e_13():
    rng = np.random.default_rng(3)
    n = 200000
    y = rng.normal(size=n) * rng.choice([1e-9, 1.0, 1e9], n)
    x = rng.normal(size=n) * rng.choice([1e-9, 1.0, 1e9], n)
    y = np.concatenate([y, [0.0, 0.0, 1.0, -1.0, 1.0, -1.0, 0.0]])
    x = np.concatenate([x, [1.0, -1.0, 0.0, 0.0, 1.0, -1.0, 0.0]])
    assert np.max(np.abs(Scene.atan2_fast(y, x) - np.arctan2(y, x))) < 1e-13
