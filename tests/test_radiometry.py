"""End-to-end statistical checks of the path tracer against closed forms and conservation
laws. Every comparison uses the estimator's own standard error (z-scores, fixed seeds)."""
import numpy as np
import pytest

from analytic import simpson, transmitted_uniform_sky
from photic.render import render
from photic.scene import Scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

N_W = 1.34
Z_MAX = 4.0  # |z| above this fails: ~6e-5 false alarms per check, a real bias fails


def ocean_scene(a, b=0.0, phase=None, sky=None, sun=None, radiometers=(), bottom=None, **settings):
    iops = {"absorption": [a], "scattering": [{"b": [b], "phase": phase or {"type": "petzold"}}]}
    water = {"name": "sea", "type": "ocean", "ior": N_W, "surface": {"kind": "flat", "z": 0.0}, "iops": iops}
    d = {"photic_scene": 1, "name": "test", "water": [water],
         "sky": sky or {"type": "uniform", "radiance": [1.0]},
         "radiometers": list(radiometers),
         "settings": {"seed": 11, "radiometer_samples": 100000, **settings}}
    if bottom:
        water["bottom"] = bottom
        d["materials"] = {"floor": {"type": "lambertian", "reflectance": [0.3]}}
    if sun:
        d["sun"] = sun
    return Scene.from_dict(d)


def rad(name, q, z, **kw):
    return {"name": name, "quantity": q, "position": [0.0, 0.0, z], **kw}


def test_uniform_sky_through_flat_surface_matches_quadrature(zscore):
    """b = 0: Ed(z), Eo(z) and zenith radiance equal the quadrature of the refracted sky
    (Fresnel, n^2 law, the critical-angle cone) times exp(-a z / mu)."""
    a = 0.4
    depths = [0.05, 1.0, 3.0]
    rads = []
    for z in depths:
        rads += [rad(f"Ed_{z}", "Ed", -z), rad(f"Eo_{z}", "Eo", -z),
                 rad(f"L_{z}", "radiance", -z, direction=[0, 0, 1], half_angle_deg=20.0)]
    res = render(ocean_scene(a, radiometers=rads), radiometer_samples=200_000)
    for z in depths:
        for q, w, extra in (("Ed", "Ed", {}), ("Eo", "Eo", {}), ("L", "L", {"mu_min": np.cos(np.radians(20))})):
            r = res.radiometer(f"{q}_{z}")
            ref = transmitted_uniform_sky(z, a, weight=w, **extra)
            if q == "L":
                ref /= 2 * np.pi * (1 - np.cos(np.radians(20)))
            assert r.medium == "sea"
            zs = zscore(f"{q}(z={z} m)", r.mean[0, 0], ref, r.stderr[0, 0])
            assert abs(zs) < Z_MAX


def test_ed_above_water_is_sun_plus_sky(zscore):
    """Ed(0+) = E_sun cos(theta_s) + pi L_sky, above a flat sea."""
    e_sun, l_sky, zen = 2.0, 0.3, 30.0
    sc = ocean_scene(0.2, 0.5, sky={"type": "uniform", "radiance": [l_sky]},
                     sun={"zenith_deg": zen, "azimuth_deg": 40.0, "irradiance": [e_sun]},
                     radiometers=[rad("Ed_air", "Ed", 0.2), rad("Eod_air", "Eod", 0.2)])
    res = render(sc, radiometer_samples=50_000)
    r = res.radiometer("Ed_air")
    assert r.medium == "air"
    ref = e_sun * np.cos(np.radians(zen)) + np.pi * l_sky
    assert abs(zscore("Ed(0+)", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
    assert r.stderr[0, 0] / ref < 0.01
    r = res.radiometer("Eod_air")
    alpha = np.radians(0.53) / 2  # scalar irradiance of a uniform disk: L * solid angle
    ref = e_sun * 2 * (1 - np.cos(alpha)) / np.sin(alpha) ** 2 + 2 * np.pi * l_sky
    assert abs(zscore("Eod(0+)", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX


def test_gershun_law_holds_at_five_depths(zscore):
    """Uniform sky, a = 0.2, b = 0.8 (Petzold): (Ed - Eu)(z1) - (Ed - Eu)(z2) = a * int Eo dz
    between consecutive depths of 1..5 m (Simpson on Eo at 0.25 m steps)."""
    a, b = 0.2, 0.8
    depths = [1.0, 2.0, 3.0, 4.0, 5.0]
    eo_depths = np.arange(1.0, 5.0001, 0.25)
    rads = [rad(f"Ed_{z}", "Ed", -z) for z in depths] + [rad(f"Eu_{z}", "Eu", -z) for z in depths]
    rads += [rad(f"Eo_{z}", "Eo", -z) for z in eo_depths]
    res = render(ocean_scene(a, b, radiometers=rads), radiometer_samples=400_000)
    val = lambda n: (res.radiometer(n).mean[0, 0], res.radiometer(n).stderr[0, 0])
    for z1, z2 in zip(depths[:-1], depths[1:]):
        (ed1, sd1), (eu1, su1), (ed2, sd2), (eu2, su2) = val(f"Ed_{z1}"), val(f"Eu_{z1}"), val(f"Ed_{z2}"), val(f"Eu_{z2}")
        zs = [z for z in eo_depths if z1 - 1e-9 <= z <= z2 + 1e-9]
        eo = np.array([val(f"Eo_{z}") for z in zs])
        w = np.ones(len(zs)); w[1:-1:2] = 4; w[2:-1:2] = 2; w *= 0.25 / 3
        lhs = (ed1 - eu1) - (ed2 - eu2)
        rhs = a * np.sum(w * eo[:, 0])
        se = np.sqrt(sd1**2 + su1**2 + sd2**2 + su2**2 + (a**2) * np.sum((w * eo[:, 1]) ** 2))
        assert abs(rhs - a * simpson(eo[:, 0], 0.25)) < 1e-12
        assert abs(zscore(f"Gershun {z1:.0f}-{z2:.0f} m", lhs, rhs, se)) < Z_MAX
        assert se / rhs < 0.03


def test_camera_and_radiance_distribution_under_flat_surface(zscore):
    """An orthographic camera looking straight up from 2 m depth sees n^2 T(0) L exp(-a z) in
    every pixel; a radiance distribution's bins inside Snell's window match the quadrature and
    those outside it (total internal reflection of black deep water) are exactly zero."""
    a, z, n = 0.25, 2.0, N_W
    sc = ocean_scene(a, radiometers=[rad("dist", "radiance_distribution", -z, polar_bins=18, azimuth_bins=4)])
    sc.cameras.append(__import__("photic.scene", fromlist=["Camera"]).Camera(
        "up", "orthographic", np.array([0.0, 0.0, -z]), np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]),
        ortho_width=1.0, resolution=(8, 6)))
    res = render(sc, samples=256, radiometer_samples=72 * 4000)
    from photic import _core
    ref = n * n * (1 - _core.fresnel(1.0, n, 1.0)) * np.exp(-a * z)
    img = res.images["up"]
    # Each sample is n^2 L e^{-az} (transmitted, probability T) or 0 (reflected down, lost).
    se = np.sqrt(img.variance.sum()) / img.mean.size
    assert abs(zscore("camera L looking up", img.mean.mean(), ref, se)) < Z_MAX
    dist = res.radiometer("dist")
    mu_c = np.sqrt(1 - 1 / n**2)
    for ip in range(18):
        th0, th1 = np.radians(10 * ip), np.radians(10 * (ip + 1))
        # Look direction polar angle th from +z: looking up into Snell's window when cos th > mu_c.
        lo, hi = np.cos(th1), np.cos(th0)
        omega = 2 * np.pi * (hi - lo)
        if lo >= mu_c:
            from analytic import transmitted_uniform_sky as q
            ref_bin = (q(z, a, weight="L", mu_min=lo) - q(z, a, weight="L", mu_min=hi)) / omega
        elif hi <= mu_c:
            ref_bin = 0.0
        else:
            continue  # the bin straddles the critical angle
        for ia in range(4):
            v, se = dist.mean[ip * 4 + ia, 0], dist.stderr[ip * 4 + ia, 0]
            if ref_bin == 0.0:
                assert v == 0.0
            elif ia == 0:
                assert abs(zscore(f"L bin {10 * ip}-{10 * ip + 10} deg", v, ref_bin, se)) < Z_MAX
            else:
                assert abs((v - ref_bin) / se) < Z_MAX


def test_bands_rendered_together_equal_bands_rendered_alone(zscore):
    """Three bands with different a, b and mixture weights share one geometric path (spectral
    delta tracking, lazy absorption, mixture sampling); each band alone must give the same."""
    a = [0.05, 0.3, 0.8]
    b_part, b_water = [0.6, 0.3, 0.05], [0.02, 0.2, 0.4]
    rads = [rad("Ed", "Ed", -2.0), rad("Eu", "Eu", -2.0), rad("Eo", "Eo", -4.0)]

    def make(idx):
        bands = [{"name": f"b{i}", "center_nm": 400 + 100 * i, "width_nm": 10} for i in idx]
        d = {"photic_scene": 1, "name": "spectral", "bands": bands,
             "water": [{"name": "sea", "type": "ocean", "surface": {"kind": "flat", "z": 0.0},
                        "iops": {"absorption": [a[i] for i in idx], "scattering": [
                            {"b": [b_part[i] for i in idx], "phase": {"type": "petzold"}},
                            {"b": [b_water[i] for i in idx], "phase": {"type": "pure_water"}}]}}],
             "sky": {"type": "uniform", "radiance": [1.0] * len(idx)},
             "radiometers": rads, "settings": {"seed": 21}}
        return render(Scene.from_dict(d), radiometer_samples=200_000)

    together = make([0, 1, 2])
    for i in range(3):
        alone = make([i])
        for name in ("Ed", "Eu", "Eo"):
            t, s = together.radiometer(name), alone.radiometer(name)
            se = np.hypot(t.stderr[0, i], s.stderr[0, 0])
            assert abs(zscore(f"band {i} {name}: together vs alone", t.mean[0, i], s.mean[0, 0], se)) < Z_MAX
