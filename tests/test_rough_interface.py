"""Rough air-water interface BSDF (engine/src/core/rough_interface.*): chi-square tests of the
sampler against pdf(), normalisation of D and of the pdf, consistency of Smith's Lambda with D,
reciprocity and adjointness, energy (directional albedo by Monte Carlo and by quadrature),
the smooth (Fresnel) limit, and the Cox-Munk glint closed form."""
import numpy as np
import pytest
from scipy import stats

from photic import _core, surface

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

ETA = surface.N_WATER


def direction(theta_deg, from_water=False, azimuth_deg=0.0):
    t, p = np.radians(theta_deg), np.radians(azimuth_deg)
    return np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), (-1 if from_water else 1) * np.cos(t)])


def uniforms(n, seed):
    rng = np.random.default_rng(seed)
    return rng.random(n), rng.random(n), rng.random(n)


def iface(U, aniso=False, wind_az=0.0):
    return surface.rough_interface(U, anisotropic=aniso, wind_azimuth=wind_az)


# (wind speed, incidence deg, from water, anisotropic, wind azimuth rad)
CHI2_CASES = {
    "air_U2_0": (2.0, 0.0, False, False, 0.0),
    "air_U7_30": (7.0, 30.0, False, False, 0.0),
    "air_U15_60": (15.0, 60.0, False, False, 0.0),
    "air_U7_80_aniso": (7.0, 80.0, False, True, 0.7),
    "air_U2_85": (2.0, 85.0, False, False, 0.0),
    "water_U2_0": (2.0, 0.0, True, False, 0.0),
    "water_U7_30": (7.0, 30.0, True, False, 0.0),
    "water_U7_45": (7.0, 45.0, True, False, 0.0),
    "water_U15_60_aniso": (15.0, 60.0, True, True, 2.0),
    "water_U2_75": (2.0, 75.0, True, False, 0.0),
}


def expected_bins(r, wi):
    """Bins of the reflected and the transmitted hemisphere (polar x azimuth, refined around
    each lobe) and their probabilities from pdf() by quadrature: (grids, probabilities)."""
    theta_r, theta_t, phi_c = surface.lobe_centres(wi, r.eta)
    grids, probs = [], []
    for theta_c, same_side in ((theta_r, True), (theta_t, False)):
        te, pe = surface.lobe_grid(theta_c, surface.lobe_width(r), n_theta=30, n_phi=24, n_fine=16)
        d, w, idx = surface.hemisphere_quadrature(te, pe, (wi[2] > 0) == same_side, phi_c, sub=2, order=3)
        nb = (len(te) - 1) * (len(pe) - 1)
        probs.append(np.bincount(idx, weights=r.pdf(wi, d) * w, minlength=nb))
        grids.append((te, pe, phi_c))
    return grids, probs


@pytest.mark.parametrize("case", list(CHI2_CASES))
def test_sampler_chi_square(case):
    """Histogram of sampled directions (reflected and transmitted lobes binned separately, plus
    one bin for failed samples) against pdf() integrated over the bins."""
    U, theta, from_water, aniso, waz = CHI2_CASES[case]
    r = iface(U, aniso, waz)
    wi = direction(theta, from_water, azimuth_deg=25.0)
    n = 200_000
    wo, weight, pdf, refl = r.sample(wi, *uniforms(n, 7))
    ok = pdf > 0
    same = wo[:, 2] * wi[2] > 0
    assert np.array_equal(refl[ok], same[ok]), "is_reflection must say which side wo is on"
    assert np.all(weight[~ok] == 0)
    assert np.allclose(np.linalg.norm(wo[ok], axis=1), 1.0, atol=1e-12)
    grids, probs = expected_bins(r, wi)
    obs = []
    for k, mask in enumerate((ok & same, ok & ~same)):
        obs.append(np.bincount(surface.hemisphere_bin(wo[mask], *grids[k]), minlength=probs[k].size))
    mass = probs[0].sum() + probs[1].sum()
    expected = np.concatenate([probs[0], probs[1], [max(0.0, 1.0 - mass)]]) * n
    observed = np.concatenate([obs[0], obs[1], [np.sum(~ok)]])
    small = expected < 5  # pool sparse bins into one (as Mitsuba's chi2 test does)
    exp_b = np.concatenate([expected[~small], [expected[small].sum()]])
    obs_b = np.concatenate([observed[~small], [observed[small].sum()]])
    if exp_b[-1] < 5:
        exp_b, obs_b = exp_b[:-1], obs_b[:-1]
        assert observed.sum() - obs_b.sum() <= 15, "samples where the pdf says there are ~none"
    chi2 = np.sum((obs_b - exp_b) ** 2 / exp_b)
    pval = stats.chi2.sf(chi2, len(exp_b) - 1)
    print(f"{case}: chi2={chi2:.1f} dof={len(exp_b) - 1} p={pval:.3f} reflected={np.mean(ok & same):.4f} "
          f"transmitted={np.mean(ok & ~same):.4f} failed={np.mean(~ok):.4f}")
    assert pval > 1e-3, f"{case}: chi2={chi2:.1f} dof={len(exp_b) - 1} p={pval:.2e}"


@pytest.mark.parametrize("case", ["air_U7_30", "air_U2_85", "water_U7_45", "water_U15_60_aniso"])
def test_pdf_integrates_to_sampled_mass(case):
    U, theta, from_water, aniso, waz = CHI2_CASES[case]
    r = iface(U, aniso, waz)
    wi = direction(theta, from_water, azimuth_deg=25.0)
    mass = sum(p.sum() for p in expected_bins(r, wi)[1])
    n = 200_000
    success = np.mean(r.sample(wi, *uniforms(n, 11))[2] > 0)
    assert mass <= 1 + 1e-3
    assert mass == pytest.approx(success, abs=4 * np.sqrt(success * (1 - success) / n) + 1e-3)
    if theta == 30.0:
        assert mass == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("mode", ["radiance", "importance"])
def test_sample_weight_is_f_cos_over_pdf(mode):
    r = iface(7.0, True, 0.4)
    for theta, from_water in [(10, False), (70, False), (20, True), (60, True)]:
        wi = direction(theta, from_water, 40.0)
        wo, weight, pdf, refl = r.sample(wi, *uniforms(20_000, 3), mode=mode)
        ok = pdf > 0
        f = r.eval(wi, wo[ok], mode)
        assert np.allclose(weight[ok], f * np.abs(wo[ok, 2]) / pdf[ok], rtol=1e-9)
        assert np.allclose(pdf[ok], r.pdf(wi, wo[ok]), rtol=1e-9)


@pytest.mark.parametrize("U,aniso", [(2.0, False), (15.0, True)])
def test_distribution_normalised_and_lambda_consistent(U, aniso):
    """Integral of D(h) h.z is 1; integral of D(h) max(0, w.h) is |w.z| (1 + Lambda(w)), the
    identity that makes Smith's shadowing conserve energy."""
    r = iface(U, aniso, 0.9)
    te, pe = surface.lobe_grid(0.0, surface.lobe_width(r), n_theta=90, n_phi=64, n_fine=48)
    d, w, _ = surface.hemisphere_quadrature(te, pe, True, 0.0)
    D = r.distribution(d)
    assert np.sum(D * d[:, 2] * w) == pytest.approx(1.0, abs=1e-6)
    for theta in (30.0, 60.0, 80.0, 88.0):
        for az in (0.0, 50.0, 90.0):
            v = direction(theta, False, az)
            lhs = np.sum(D * np.maximum(0.0, d @ v) * w)
            lam = r.smith_lambda(v)[0]
            assert lhs == pytest.approx(v[2] * (1 + lam), rel=1e-4)
            assert r.smith_lambda(-v)[0] == lam  # same statistics seen from below


def test_reciprocity_and_adjointness():
    r = iface(7.0, True, 1.1)
    rng = np.random.default_rng(5)
    a = rng.normal(size=(10000, 3))
    b = rng.normal(size=(10000, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    n_a = np.where(a[:, 2] > 0, 1.0, ETA)
    n_b = np.where(b[:, 2] > 0, 1.0, ETA)
    fab, fba = r.eval(a, b), r.eval(b, a)
    same = a[:, 2] * b[:, 2] > 0
    assert np.count_nonzero(fab[same]) > 500 and np.count_nonzero(fab[~same]) > 300
    # reflection reciprocal; transmission with Veach's generalised reciprocity f/n(wi)^2
    assert np.allclose(fab[same], fba[same], rtol=1e-10, atol=1e-300)
    assert np.allclose(fab / n_a ** 2, fba / n_b ** 2, rtol=1e-10, atol=1e-300)
    # importance transport is the adjoint of radiance transport
    assert np.allclose(r.eval(a, b, "importance"), fba, rtol=1e-10, atol=1e-300)
    # radiance BTDF carries (n(wi) / n(wo))^2 relative to the flux form
    assert np.allclose(fab[~same], r.eval(a, b, "importance")[~same] * (n_a / n_b)[~same] ** 2, rtol=1e-12)


ALBEDO_CASES = [(U, th, fw) for U in (2.0, 15.0) for th, fw in
                [(0, False), (45, False), (75, False), (85, False), (30, True), (60, True), (85, True)]]


@pytest.mark.parametrize("U,theta,from_water", ALBEDO_CASES)
def test_albedo(U, theta, from_water):
    """R + T of the flux (importance mode) by Monte Carlo with the sampler and by quadrature of
    eval agree, never exceed 1, and fall below 1 at grazing incidence (shadowing loss)."""
    r = iface(U)
    wi = direction(theta, from_water)
    n = 100_000
    wo, weight, pdf, refl = r.sample(wi, *uniforms(n, 21), mode="importance")
    R_mc, T_mc = weight[refl].sum() / n, weight[~refl].sum() / n
    err = np.std(weight) / np.sqrt(n)
    err_R, err_T = np.std(weight * refl) / np.sqrt(n), np.std(weight * ~refl) / np.sqrt(n)
    R, T = surface.directional_albedo(r, wi, "importance")
    print(f"U={U} theta={theta} water={from_water}: R={R:.5f} T={T:.5f} R+T={R + T:.5f} "
          f"MC R+T={R_mc + T_mc:.5f} +- {err:.1e}")
    assert R + T <= 1 + 1e-4 and R_mc + T_mc <= 1 + 4 * err
    assert R_mc == pytest.approx(R, abs=4 * err_R + 1e-4)
    assert T_mc == pytest.approx(T, abs=4 * err_T + 1e-4)
    if theta >= 85:
        assert R + T < 0.98
    if theta == 0:
        assert R + T == pytest.approx(1.0, abs=2e-3)
    # radiance mode: the transmitted part carries (n(wi) / n(wo))^2
    R_rad, T_rad = surface.directional_albedo(r, wi, "radiance")
    ratio = ETA ** 2 if from_water else 1 / ETA ** 2
    assert R_rad == pytest.approx(R, rel=1e-12) and T_rad == pytest.approx(T * ratio, rel=1e-9, abs=1e-15)


def test_smooth_limit_is_fresnel():
    """sigma^2 = 1e-5: total reflectance within 1e-3 of Fresnel below 70 deg (from air) and
    R + T = 1; from water below 40 deg likewise."""
    r = _core.RoughInterface(0.5e-5, 0.5e-5, 0.0, ETA)
    worst = 0.0
    for theta in np.arange(0.0, 70.0, 5.0):
        for from_water in (False, True):
            if from_water and theta > 40:
                continue
            R, T = surface.directional_albedo(r, direction(theta, from_water, 30.0), "importance")
            n1, n2 = (ETA, 1.0) if from_water else (1.0, ETA)
            F = surface.fresnel(np.cos(np.radians(theta)), n1, n2)
            worst = max(worst, abs(R - F))
            assert R == pytest.approx(F, abs=1e-3)
            assert R + T == pytest.approx(1.0, abs=1e-3)
    print(f"largest |R - F| = {worst:.2e}")


def test_fresnel_helper_matches_core():
    for c in (0.0, 0.1, 0.5, 0.9, 1.0):
        assert surface.fresnel(c) == pytest.approx(_core.fresnel(c, 1.0, ETA), rel=1e-13)
        assert surface.fresnel(c, ETA, 1.0) == pytest.approx(_core.fresnel(c, ETA, 1.0), rel=1e-13)
    assert surface.fresnel(1.0) == pytest.approx(((ETA - 1) / (ETA + 1)) ** 2, rel=1e-12)


def test_cox_munk_variances_and_sub_pixel():
    assert surface.cox_munk_variance(5.0) == pytest.approx(0.003 + 5.12e-3 * 5)
    su, sc = surface.cox_munk_variance(10.0, anisotropic=True)
    assert (su, sc) == (pytest.approx(0.0316), pytest.approx(0.0222))
    r = surface.rough_interface(10.0, True, 0.3)
    assert (r.sigma2_up, r.sigma2_cross) == (pytest.approx(0.0316), pytest.approx(0.0222))
    r = surface.rough_interface(4.0, anisotropic=False)
    assert r.sigma2_up == r.sigma2_cross == pytest.approx(0.5 * (0.003 + 5.12e-3 * 4))
    # sub-pixel: the resolved variance is removed, with a floor
    s = surface.slope_variances(10.0, True, resolved=(0.02, 0.03))
    assert s == (pytest.approx(0.0116), surface.MIN_VARIANCE)
    r = surface.rough_interface(10.0, True, 0.0, ETA, resolved=(0.02, 0.03))
    assert (r.sigma2_up, r.sigma2_cross) == (pytest.approx(0.0116), pytest.approx(1e-6))
    with pytest.raises(ValueError, match="sigma2_up"):
        _core.RoughInterface(0.0, 0.01)
    with pytest.raises(ValueError, match="eta"):
        _core.RoughInterface(0.01, 0.01, 0.0, 1.0)
    with pytest.raises(ValueError, match="mode"):
        _core.RoughInterface(0.01, 0.01).eval([0, 0, 1], [0, 0, 1], "flux")


@pytest.mark.parametrize("aniso,waz", [(False, 0.0), (True, 0.0), (True, 1.2)])
def test_glint_closed_form_matches_bsdf(aniso, waz):
    """The 6S glint reflectance factor is pi f_r / G of the BSDF (sun = wi, view = wo)."""
    U = 7.0
    r = iface(U, aniso, waz)
    rng = np.random.default_rng(9)
    ts, tv = np.radians(rng.uniform(0, 70, 200)), np.radians(rng.uniform(0, 70, 200))
    phi = rng.uniform(0, 2 * np.pi, 200)
    s = np.stack([np.sin(ts), 0 * ts, np.cos(ts)], 1)
    v = np.stack([np.sin(tv) * np.cos(phi), np.sin(tv) * np.sin(phi), np.cos(tv)], 1)
    G = 1 / (1 + r.smith_lambda(s) + r.smith_lambda(v))
    rho = surface.glint_reflectance(ts, tv, phi, U, anisotropic=aniso, wind_azimuth=waz)
    assert np.allclose(rho, np.pi * r.eval(s, v) / G, rtol=1e-10)
    # the glint is brightest in the specular direction (phi = pi)
    assert surface.glint_reflectance(0.5, 0.5, np.pi, U) > surface.glint_reflectance(0.5, 0.5, 2.5, U)


def test_reflectance_curves_and_plot(tmp_path):
    """The plotted quantity: from air, rough reflectance is Fresnel near normal incidence and
    below it at grazing angles; the linear-axes plot helper draws the series and writes an image
    of the requested size."""
    from matplotlib.image import imread

    from photic.plots import linear_panels, save_figure
    c = surface.reflectance_curves(winds=(7.0,), angles_deg=np.array([0.0, 85.0]))
    assert c["air_7"][0] == pytest.approx(c["fresnel_air"][0], abs=1e-3)
    assert c["air_7"][1] < np.interp(85.0, c["fresnel_angles"], c["fresnel_air"]) - 0.1
    fig = linear_panels([{"title": "T", "series": [("A", c["angles"], c["air_7"], (255, 0, 0))],
                          "xlim": (0, 90), "ylim": (0, 1), "legend": True}], size=(200, 150))
    (ax,) = fig.axes
    (line,) = ax.get_lines()
    assert line.get_label() == "A" and line.get_color() == (1.0, 0.0, 0.0)
    assert np.array_equal(line.get_xdata(), c["angles"]) and np.allclose(line.get_ydata(), c["air_7"])
    assert ax.get_title() == "T" and ax.get_xlim() == (0, 90) and ax.get_ylim() == (0, 1)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["A"]
    img = imread(save_figure(fig, tmp_path / "r.png"))
    assert img.shape[:2] == (150, 200)
    red = (img[:, :, 0] > 0.9) & (img[:, :, 1] < 0.1) & (img[:, :, 2] < 0.1)
    assert red.any()
