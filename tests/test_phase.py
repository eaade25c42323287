"""Phase functions: normalisation, agreement with their source functions, and chi-square
tests of every sampler against its own density (value == pdf for the exact samplers)."""
import numpy as np
import pytest
from scipy import stats

from photic import phase
from analytic import trapezoid

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

CASES = {
    "isotropic": ("isotropic", {}),
    "hg_-0.5": ("henyey_greenstein", {"g": -0.5}),
    "hg_0.3": ("henyey_greenstein", {"g": 0.3}),
    "hg_0.9": ("henyey_greenstein", {"g": 0.9}),
    "hg_0.995": ("henyey_greenstein", {"g": 0.995}),
    "pure_water": ("pure_water", {}),
    "petzold": ("petzold", {}),
    "ff_0.0183": ("fournier_forand", {"backscatter_fraction": 0.0183}),
    "ff_0.005": ("fournier_forand", {"backscatter_fraction": 0.005}),
}


def x_grid():
    """Quadrature nodes in x = 1 - cos(psi), dense in the forward peak."""
    return np.unique(np.concatenate([[0.0], np.logspace(-16, np.log10(2.0), 200001)]))


def integral(p, x):
    v = p.eval(x)
    return 2 * np.pi * np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(x))


@pytest.mark.parametrize("case", list(CASES))
def test_normalised(case):
    p = phase.make_core_phase(*CASES[case])
    assert integral(p, x_grid()) == pytest.approx(1.0, abs=2e-4)


@pytest.mark.parametrize("case", list(CASES))
def test_sampler_chi_square(case):
    """Histogram of 400k samples in equal-probability bins of the density vs. expectation."""
    p = phase.make_core_phase(*CASES[case])
    rng = np.random.default_rng(12345)
    n = 400_000
    xs = p.sample_x(rng.random(n))
    assert np.all((xs >= 0) & (xs <= 2))
    # Expected bin probabilities from the density by quadrature (independent of the sampler).
    x = x_grid()
    v = p.eval(x)
    cdf = np.concatenate([[0.0], np.cumsum(2 * np.pi * 0.5 * (v[1:] + v[:-1]) * np.diff(x))])
    cdf /= cdf[-1]
    nbins = 100
    edges = np.interp(np.linspace(0, 1, nbins + 1), cdf, x)
    edges[0], edges[-1] = 0.0, 2.0
    edges = np.unique(edges)
    expected = np.diff(np.interp(edges, x, cdf)) * n
    observed = np.histogram(xs, bins=edges)[0]
    keep = expected > 5
    chi2 = np.sum((observed[keep] - expected[keep]) ** 2 / expected[keep])
    pval = stats.chi2.sf(chi2, keep.sum() - 1)
    assert pval > 1e-3, f"{case}: chi2={chi2:.1f} dof={keep.sum() - 1} p={pval:.2e}"


@pytest.mark.parametrize("g", [-0.7, 0.0, 0.5, 0.9, 0.99])
def test_hg_closed_form(g):
    p = phase.make_core_phase("henyey_greenstein", {"g": g})
    psi = np.linspace(0, np.pi, 50)
    ref = (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * np.cos(psi)) ** 1.5)
    assert np.allclose(p.eval(1 - np.cos(psi)), ref, rtol=1e-10)


def test_pure_water_closed_form():
    p = phase.make_core_phase("pure_water", {})
    psi = np.linspace(0, np.pi, 7)
    assert np.allclose(p.eval(1 - np.cos(psi)), 0.06225 * (1 + 0.835 * np.cos(psi) ** 2), rtol=2e-4)


@pytest.mark.parametrize("ptype,params", [("petzold", {}), ("fournier_forand", {"backscatter_fraction": 0.0183})])
def test_tables_follow_their_source(ptype, params):
    """Tables equal the source function (renormalised) within 1 % from 1e-3 deg to 180 deg."""
    p = phase.make_core_phase(ptype, params)
    src = phase.phase_callable(ptype, params)
    psi = np.radians(np.logspace(-3, np.log10(179.9), 400))
    t = p.eval(phase.psi_to_x(psi))
    norm = 2 * np.pi * trapezoid(src(phase.table_grid_psi()) * np.sin(phase.table_grid_psi()), phase.table_grid_psi())
    assert np.allclose(t, src(psi) / norm, rtol=1e-2)


def test_petzold_backscatter_fraction_and_mean_cosine():
    p = phase.make_core_phase("petzold", {})
    x = x_grid()
    v = p.eval(x)
    w = 2 * np.pi * 0.5 * (v[1:] + v[:-1]) * np.diff(x)
    xm = 0.5 * (x[1:] + x[:-1])
    assert w[xm > 1].sum() == pytest.approx(0.0183, abs=3e-4)
    assert np.sum(w * (1 - xm)) == pytest.approx(0.924, abs=0.01)


def test_fournier_forand_parameters_from_backscatter():
    n, mu = phase.ff_parameters(0.0183)
    assert mu == pytest.approx(3.5835, abs=2e-3) and n == pytest.approx(1.10, abs=1e-3)
    for bb in (1e-4, 1e-3, 0.01, 0.1):
        n, mu = phase.ff_parameters(bb)
        assert phase.ff_backscatter_fraction(n, mu) == pytest.approx(bb, rel=1e-6)
    # Closed form integrates to one.
    psi = np.concatenate([np.radians(np.logspace(-6, 0, 20000)), np.linspace(np.radians(1.0001), np.pi, 20000)])
    n, mu = phase.ff_parameters(0.0183)
    assert 2 * np.pi * trapezoid(phase.fournier_forand(psi, n, mu) * np.sin(psi), psi) == pytest.approx(1.0, abs=2e-3)


def test_pure_water_iops_spot_values():
    """Pope & Fry 1997 table values and the Morel/Smith & Baker power law (per band: centre,
    width in nm)."""
    from photic.iop_models import pure_seawater_scattering, pure_water_absorption

    def a(centre, width=0.0):
        return float(pure_water_absorption([(centre, width)])[0])
    assert a(440.0) == pytest.approx(0.00635, abs=1e-9)
    assert a(550.0) == pytest.approx(0.0565, abs=1e-9)
    assert a(401.25) == pytest.approx((0.00663 + 0.00579) / 2, abs=1e-9)
    # a band average lies between the table's extremes over the band
    assert a(520.0) < a(550.0, 60.0) < a(580.0)
    assert pure_seawater_scattering([(500.0, 0.0)])[0] == pytest.approx(0.00288)
    assert pure_seawater_scattering([(400.0, 0.0)])[0] == pytest.approx(0.0076, rel=0.01)
    with pytest.raises(ValueError, match="750"):
        a(750.0)
