"""Closed forms of the interface optics: Snell's law, Fresnel, total internal reflection."""
import math

import numpy as np
import pytest

from photic import _core

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

N_W = 1.34


def fresnel_ref(theta_i, n1, n2):
    s = n1 / n2 * math.sin(theta_i)
    if s >= 1:
        return 1.0
    tt = math.asin(s)
    if theta_i == 0:
        return ((n1 - n2) / (n1 + n2)) ** 2
    rs = math.sin(theta_i - tt) / math.sin(theta_i + tt)
    rp = math.tan(theta_i - tt) / math.tan(theta_i + tt)
    return 0.5 * (rs * rs + rp * rp)


def test_normal_incidence():
    assert _core.fresnel(1.0, 1.0, N_W) == pytest.approx(((N_W - 1) / (N_W + 1)) ** 2, rel=1e-12)
    assert _core.fresnel(1.0, N_W, 1.0) == pytest.approx(((N_W - 1) / (N_W + 1)) ** 2, rel=1e-12)


@pytest.mark.parametrize("deg", [5, 20, 40, 60, 75, 85, 89.5])
def test_fresnel_matches_textbook_form(deg):
    th = math.radians(deg)
    assert _core.fresnel(math.cos(th), 1.0, N_W) == pytest.approx(fresnel_ref(th, 1.0, N_W), rel=1e-9)


def test_brewster_angle_has_only_s_reflection():
    th = math.atan(N_W)
    tt = math.asin(math.sin(th) / N_W)
    rs = math.sin(th - tt) / math.sin(th + tt)
    assert _core.fresnel(math.cos(th), 1.0, N_W) == pytest.approx(0.5 * rs * rs, rel=1e-9)


def test_total_internal_reflection_beyond_critical_angle():
    crit = math.asin(1 / N_W)
    assert _core.fresnel(math.cos(crit + 1e-6), N_W, 1.0) == 1.0
    assert _core.fresnel(math.cos(crit - 1e-3), N_W, 1.0) < 1.0
    assert _core.refract((math.sin(crit + 0.01), 0, -math.cos(crit + 0.01)), (0, 0, 1), N_W, 1.0) is None


@pytest.mark.parametrize("deg", [0, 10, 30, 45, 60, 80, 89])
def test_snell_and_reciprocal_transmittance(deg):
    th = math.radians(deg)
    d = (math.sin(th), 0.0, -math.cos(th))  # going down into water
    t = np.array(_core.refract(d, (0, 0, 1), 1.0, N_W))
    assert np.linalg.norm(t) == pytest.approx(1.0, abs=1e-12)
    sin_t = math.hypot(t[0], t[1])
    assert math.sin(th) == pytest.approx(N_W * sin_t, abs=1e-12)   # n1 sin1 = n2 sin2
    assert t[2] < 0
    # Unpolarised transmittance is the same both ways along the same path.
    cos_t = -t[2]
    assert 1 - _core.fresnel(math.cos(th), 1.0, N_W) == pytest.approx(1 - _core.fresnel(cos_t, N_W, 1.0), abs=1e-12)
