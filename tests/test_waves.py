"""Wave models (photic.waves): realisations against their spectra, dispersion, tiling, exact
slopes, the published spectrum relations, input checks, and a "waves" scene end to end."""
import math

import numpy as np
import pytest

from photic import waves as W
from photic.render import render
from photic.scene import OceanSurface, Scene, SceneError, TriangleMesh, WaterBody, IOPs
from analytic import trapezoid

G = 9.80665


def realisation_statistics(model, seeds):
    """Mean over seeds of the realised height variance and mean square slope."""
    hv, sv = [], []
    for seed in seeds:
        f = W.generate(model.replace(seed=seed))
        hv.append(np.mean(f.height ** 2))
        sv.append(np.mean(f.slope_x ** 2 + f.slope_y ** 2))
    return float(np.mean(hv)), float(np.mean(sv))


def expected_relative_error(model, weight):
    """Standard error (relative) of one realisation's sum_k weight |H(k)|^2: |H|^2 is
    exponential for every pair (k, -k), so Var = 2 sum w^2 with w = weight E|H|^2."""
    kx, ky, energy, _ = W._grid_psi(model)
    w = weight(kx, ky) * 0.5 * (energy + W._negated(energy))
    return math.sqrt(2.0 * np.sum(w * w)) / np.sum(w)


MODELS = {
    "pierson_moskowitz": W.WaveModel("pierson_moskowitz", wind_speed=10.0, patch_size_m=(800.0, 800.0)),
    "jonswap": W.WaveModel("jonswap", wind_speed=10.0, fetch_m=50e3, patch_size_m=(400.0, 300.0),
                           resolution=(64, 48), wind_direction_deg=30.0),
    "phillips_cos2_shallow": W.WaveModel("phillips", wind_speed=8.0, patch_size_m=(400.0, 400.0),
                                         spreading="cos2", water_depth_m=5.0),
}


@pytest.mark.parametrize("name", list(MODELS))
def test_realised_variances_match_the_spectrum(name):
    """Height variance and mean square slope averaged over 300 seeds equal the grid-band
    integrals of Psi and k^2 Psi to 2 % (the expected scatter is printed; 2 % is > 4 of it)."""
    model, n = MODELS[name], 300
    hv, sv = realisation_statistics(model, range(n))
    h_theory, s_theory = W.height_variance(model), W.slope_variance(model)
    h_se = expected_relative_error(model, lambda kx, ky: 1.0 + 0 * kx * ky) / math.sqrt(n)
    s_se = expected_relative_error(model, lambda kx, ky: kx * kx + ky * ky) / math.sqrt(n)
    print(f"\n{name}: height variance {hv:.5g} / {h_theory:.5g} m^2 = {hv / h_theory:.4f} "
          f"(se {h_se:.4f}); slope variance {sv:.5g} / {s_theory:.5g} = {sv / s_theory:.4f} "
          f"(se {s_se:.4f}); Hs (grid) {4 * math.sqrt(h_theory):.3f} m")
    assert 4 * h_se < 0.02 and 4 * s_se < 0.02  # the test can tell a 2 % error
    assert hv / h_theory == pytest.approx(1.0, abs=0.02)
    assert sv / s_theory == pytest.approx(1.0, abs=0.02)
    # Per-axis slopes add up to the total; the resolved slope variance is the same integral.
    assert W.slope_variance(model, "x") + W.slope_variance(model, "y") == pytest.approx(s_theory)
    assert W.resolved_slope_variance(model) == s_theory
    assert W.subpixel_slope_variance(model, s_theory + 0.01) == pytest.approx(0.01)
    assert W.subpixel_slope_variance(model, 0.5 * s_theory) == 0.0


def phase_speed(depth, wavelength, dt=0.05):
    """Phase speed of a one-sinusoid field measured from the phase of its Fourier
    coefficient between t = 0 and t = dt."""
    model = W.WaveModel("sinusoids", patch_size_m=(4 * wavelength, wavelength),
                        resolution=(32, 16), water_depth_m=depth,
                        sinusoids=((0.1, wavelength, 0.0, 0.3),))
    c0 = np.fft.fft2(W.generate(model).height)[4, 0]
    c1 = np.fft.fft2(W.generate(model.replace(time_s=dt)).height)[4, 0]
    k = 2 * math.pi / wavelength
    return -np.angle(c1 / c0) / (k * dt)


@pytest.mark.parametrize("depth, wavelength", [(None, 10.0), (None, 100.0), (2.0, 20.0), (0.5, 50.0)])
def test_phase_speed_follows_the_dispersion_relation(depth, wavelength):
    k = 2 * math.pi / wavelength
    expected = math.sqrt(G / k * (1.0 if depth is None else math.tanh(k * depth)))
    c = phase_speed(depth, wavelength)
    print(f"\ndepth {depth} m, wavelength {wavelength} m: c = {c:.6f} m/s, omega/k = "
          f"{expected:.6f} m/s, relative error {c / expected - 1:.2e}")
    assert c == pytest.approx(expected, rel=1e-9)
    if depth is None:  # textbook deep-water value c = sqrt(g lambda / (2 pi))
        assert c == pytest.approx(math.sqrt(G * wavelength / (2 * math.pi)), rel=1e-9)
    elif k * depth < 0.1:  # shallow water: c -> sqrt(g D)
        assert c == pytest.approx(math.sqrt(G * depth), rel=0.01)


def test_random_field_moves_along_the_wind_at_the_phase_speeds():
    """Every Fourier component of a random field advances by -omega(k) dt (waves travel
    along +k); the spreading puts the energy downwind."""
    model = W.WaveModel("jonswap", wind_speed=10.0, fetch_m=2e4, patch_size_m=(100.0, 100.0),
                        resolution=(32, 32), water_depth_m=3.0, wind_direction_deg=90.0)
    dt = 0.1
    h0 = np.fft.fft2(W.generate(model).height)
    h1 = np.fft.fft2(W.generate(model.replace(time_s=dt)).height)
    kx, ky, mask = W.wavenumber_grid(model)
    omega = W.dispersion(np.hypot(kx, ky), 3.0)
    # Within 30 deg of the wind the partner travelling against it (-k) has < 1e-8 of the
    # energy, so each coefficient just turns by exp(-i omega dt).
    near = mask & (ky > np.abs(kx) * math.sqrt(3.0)) & (np.abs(h0) > 1e-6 * np.abs(h0).max())
    rel = np.abs(h1 - h0 * np.exp(-1j * omega * dt))[near] / np.abs(h0[near])
    print(f"\nphase advance of {near.sum()} downwind components: max relative error {rel.max():.1e}")
    assert rel.max() < 1e-3
    psi = W.directional_spectrum(model, kx, ky)
    assert psi[mask & (ky > 0)].sum() > 100 * psi[mask & (ky < 0)].sum()


@pytest.mark.parametrize("choppiness", [0.0, 0.8])
def test_patch_tiles_continuously(choppiness):
    model = W.WaveModel("pierson_moskowitz", wind_speed=9.0, patch_size_m=(60.0, 40.0),
                        resolution=(32, 24), seed=5, choppiness=choppiness, time_s=3.0)
    fld = W.generate(model)
    v, t, n = W.patch_mesh(fld, z=0.5)
    nx, ny = model.resolution
    assert v.shape == ((nx + 1) * (ny + 1), 3) and t.shape == (2 * nx * ny, 3)
    assert t.dtype == np.int64 and v.dtype == np.float64
    grid = v.reshape(nx + 1, ny + 1, 3)
    normals = n.reshape(nx + 1, ny + 1, 3)
    # Exactly [0, Lx] x [0, Ly]; border rows/columns repeat the opposite ones.
    assert grid[0, 0, :2].tolist() == [0.0, 0.0] and grid[-1, -1, :2].tolist() == [60.0, 40.0]
    gap_z = max(np.abs(grid[-1, :, 2] - grid[0, :, 2]).max(), np.abs(grid[:, -1, 2] - grid[:, 0, 2]).max())
    gap_n = max(np.abs(normals[-1] - normals[0]).max(), np.abs(normals[:, -1] - normals[:, 0]).max())
    print(f"\nchoppiness {choppiness}: border height gap {gap_z:.1e} m, normal gap {gap_n:.1e}")
    assert gap_z <= 1e-9 and gap_n <= 1e-9
    assert abs(v[:, 2].mean() - 0.5) < 0.1
    # Upward triangles, unit upward normals; a valid "patch" surface for the engine.
    nz = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])[:, 2]
    assert nz.min() > 0 and n[:, 2].min() > 0
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    water = WaterBody("sea", "ocean", IOPs(np.array([0.1])),
                      surface=OceanSurface("patch", mesh=TriangleMesh(v, t), period=(60.0, 40.0)))
    from photic.scene import _validate_surface
    _validate_surface("water 'sea'", water.surface)
    # The field itself is periodic: h(x) = h(x + L), at points off the grid too.
    rng = np.random.default_rng(1)
    x, y = rng.random(50) * 60.0, rng.random(50) * 40.0
    h, sx, sy = W.evaluate(model, x, y)
    for dx, dy in ((60.0, 0.0), (0.0, 40.0), (-120.0, 80.0)):
        h2, sx2, sy2 = W.evaluate(model, x + dx, y + dy)
        assert np.abs(h2 - h).max() < 1e-6 * np.abs(h).max()
        assert max(np.abs(sx2 - sx).max(), np.abs(sy2 - sy).max()) < 1e-6
    # The direct Fourier sum agrees with the FFT grid.
    hg, _, _ = W.evaluate(model, *np.meshgrid(fld.x, fld.y, indexing="ij"))
    assert np.abs(hg - fld.height).max() < 1e-9


def test_fft_slopes_equal_finite_differences():
    """The spectral slopes at the grid points against central differences (step 1 mm) of the
    band-limited field evaluated finely by its Fourier series."""
    model = W.WaveModel("jonswap", wind_speed=12.0, fetch_m=3e4, patch_size_m=(50.0, 50.0),
                        resolution=(32, 32), seed=3)
    fld = W.generate(model)
    xx, yy = np.meshgrid(fld.x, fld.y, indexing="ij")
    d = 1e-3
    fdx = (W.evaluate(model, xx + d, yy)[0] - W.evaluate(model, xx - d, yy)[0]) / (2 * d)
    fdy = (W.evaluate(model, xx, yy + d)[0] - W.evaluate(model, xx, yy - d)[0]) / (2 * d)
    err = max(np.abs(fdx - fld.slope_x).max(), np.abs(fdy - fld.slope_y).max())
    scale = np.abs(fld.slope_x).max()
    print(f"\nmax |FFT slope - finite difference| = {err:.2e} (max slope {scale:.3f})")
    assert err < 1e-6 * scale
    # Normals are (-sx, -sy, 1) normalised without choppiness.
    n = np.stack([-fld.slope_x, -fld.slope_y, np.ones_like(xx)], -1)
    assert np.allclose(fld.normals, n / np.linalg.norm(n, axis=-1, keepdims=True))


def test_choppy_single_wave_is_a_trochoid():
    """One sinusoid with choppiness lambda: x' = x0 - lambda a sin(k x0), z = a cos(k x0)
    (sharp crests); the displaced slopes and the resampled patch match it."""
    a, wavelength, lam = 0.5, 10.0, 1.2
    k = 2 * math.pi / wavelength
    model = W.WaveModel("sinusoids", patch_size_m=(20.0, 10.0), resolution=(64, 8),
                        sinusoids=((a, wavelength, 0.0, 0.0),), choppiness=lam)
    fld = W.generate(model)
    x0 = fld.x[:, None]
    assert np.allclose(fld.displacement[..., 0], -lam * a * np.sin(k * x0))
    assert np.allclose(fld.displacement[..., 1], 0.0, atol=1e-12)
    assert np.allclose(fld.jacobian, 1 - lam * a * k * np.cos(k * x0))
    slope = -a * k * np.sin(k * x0) / (1 - lam * a * k * np.cos(k * x0))
    assert np.allclose(fld.surface_slope_x, slope) and np.allclose(fld.surface_slope_y, 0.0, atol=1e-12)
    # The patch samples the trochoid at the regular x: solve x = x0 - lam a sin(k x0).
    v, _, n = W.patch_mesh(fld)
    x = v[:, 0]
    s = x.copy()
    for _ in range(100):
        s -= (s - lam * a * np.sin(k * s) - x) / (1 - lam * a * k * np.cos(k * s))
    z_err = np.abs(v[:, 2] - a * np.cos(k * s)).max()
    slope_exact = -a * k * np.sin(k * s) / (1 - lam * a * k * np.cos(k * s))
    n_exact = np.stack([-slope_exact, 0 * s, 1 + 0 * s], 1) / np.hypot(slope_exact, 1)[:, None]
    n_err = np.abs(n - n_exact).max()
    print(f"\nresampled trochoid: height error {z_err:.1e} m (a = {a} m), normal error {n_err:.1e}")
    assert z_err < 1e-3 * a and n_err < 1e-3
    with pytest.raises(W.SurfaceFoldsError):
        W.patch_mesh(W.generate(model.replace(choppiness=1.1 / (a * k))))


def moments(model):
    w = np.geomspace(0.02, 80.0, 200001)
    s = W.frequency_spectrum(model, w)
    return w, s, trapezoid(s, w)


def test_pierson_moskowitz_significant_wave_height():
    """Hs = 4 sqrt(m0) = 0.21 U19.5^2 / g and omega_p = 0.877 g / U19.5 (Stewart 2008,
    sec. 16.5), with U19.5 = 1.026 U10."""
    for u10 in (5.0, 10.0, 20.0):
        u195 = 1.026 * u10
        w, s, m0 = moments(W.WaveModel("pierson_moskowitz", wind_speed=u10))
        hs = 4 * math.sqrt(m0)
        print(f"\nPM U10 = {u10}: Hs = {hs:.4f} m, 0.21 U19.5^2/g = {0.21 * u195 ** 2 / G:.4f} m, "
              f"peak {w[np.argmax(s)]:.4f} rad/s vs {0.877 * G / u195:.4f}")
        assert hs == pytest.approx(0.21 * u195 ** 2 / G, rel=0.01)
        assert hs == pytest.approx(2 * math.sqrt(8.1e-3 / 0.74) * u195 ** 2 / G, rel=1e-4)
        assert w[np.argmax(s)] == pytest.approx(0.877 * G / u195, rel=1e-3)


def test_jonswap_fetch_relations():
    """alpha = 0.076 chi^-0.22 and omega_p = 22 (g^2 / (U F))^(1/3) (Hasselmann et al. 1973
    via Stewart 2008); m0 = alpha g^2 / (5 omega_p^4) / A_gamma with A_gamma = 1 - 0.287
    ln(gamma) (DNV-RP-C205 3.5.5.4, ~0.3 %); Hs within 35 % of the fetch-limited growth law
    g Hs / U^2 = 1.6e-3 chi^0.5 (Hasselmann et al. 1973; separate fits, not exact)."""
    for u10, fetch in ((10.0, 1e3), (10.0, 1e4), (10.0, 1e5), (20.0, 3e4)):
        chi = G * fetch / u10 ** 2
        model = W.WaveModel("jonswap", wind_speed=u10, fetch_m=fetch)
        w, s, m0 = moments(model)
        alpha, wp = 0.076 * chi ** -0.22, 22 * (G * G / (u10 * fetch)) ** (1 / 3)
        hs, growth = 4 * math.sqrt(m0), 1.6e-3 * math.sqrt(chi) * u10 ** 2 / G
        print(f"\nJONSWAP U10 = {u10}, F = {fetch:.0f} m: peak {w[np.argmax(s)]:.4f} vs {wp:.4f} "
              f"rad/s, Hs {hs:.3f} m, growth law {growth:.3f} m")
        assert w[np.argmax(s)] == pytest.approx(wp, rel=1e-3)
        assert s.max() == pytest.approx(alpha * G * G * wp ** -5 * math.exp(-1.25) * 3.3, rel=1e-6)
        assert m0 == pytest.approx(alpha * G * G / (5 * wp ** 4) / (1 - 0.287 * math.log(3.3)), rel=0.005)
        assert hs == pytest.approx(growth, rel=0.35)
    # gamma = 1 is the Pierson-Moskowitz shape exactly: m0 = alpha g^2 / (5 omega_p^4).
    model = W.WaveModel("jonswap", wind_speed=10.0, fetch_m=1e4, gamma=1.0)
    alpha, wp = W._jonswap_parameters(model)
    assert moments(model)[2] == pytest.approx(alpha * G * G / (5 * wp ** 4), rel=1e-4)
    # Beyond the fully developed fetch the peak stays at the Pierson-Moskowitz peak.
    far = W._jonswap_parameters(model.replace(fetch_m=1e8))[1]
    assert far == pytest.approx(0.877 * G / (1.026 * 10.0), rel=1e-3)


@pytest.mark.parametrize("depth", [None, 4.0])
@pytest.mark.parametrize("spreading", ["cos2s", "cos2"])
def test_directional_spectrum_integrates_to_the_frequency_spectrum(depth, spreading):
    """The wavenumber spectrum on a fine polar grid integrates to m0 = int S d omega: the
    Jacobian d omega / dk / k and the spreading normalisation are right."""
    model = W.WaveModel("jonswap", wind_speed=10.0, fetch_m=2e4, water_depth_m=depth,
                        spreading=spreading, wind_direction_deg=20.0)
    k = np.geomspace(1e-2, 100.0, 4001)
    theta = np.linspace(-math.pi, math.pi, 721)
    kk, tt = np.meshgrid(k, theta, indexing="ij")
    psi = W.directional_spectrum(model, kk * np.cos(tt), kk * np.sin(tt))
    total = trapezoid(trapezoid(psi * kk, theta, axis=1), k)
    assert total == pytest.approx(moments(model)[2], rel=1e-4)


@pytest.mark.parametrize("changes, field", [
    ({"wind_speed": -1.0}, "wind_speed"),
    ({"wind_speed": float("nan")}, "wind_speed"),
    ({"patch_size_m": (0.0, 10.0)}, "patch_size_m[0]"),
    ({"patch_size_m": (10.0, float("nan"))}, "patch_size_m[1]"),
    ({"resolution": (1, 16)}, "resolution[0]"),
    ({"resolution": (16, 2.5)}, "resolution[1]"),
    ({"choppiness": -0.1}, "choppiness"),
    ({"water_depth_m": 0.0}, "water_depth_m"),
    ({"time_s": float("inf")}, "time_s"),
    ({"spectrum": "jonswap"}, "fetch_m"),
    ({"fetch_m": 1000.0}, "fetch_m"),
    ({"spectrum": "jonswap", "fetch_m": -5.0}, "fetch_m"),
    ({"gamma": 0.5}, "gamma"),
    ({"spreading": "cos4"}, "spreading"),
    ({"spectrum": "waves"}, "spectrum"),
    ({"seed": -1}, "seed"),
    ({"mesh_refinement": 0}, "mesh_refinement"),
    ({"mesh_refinement": 2.5}, "mesh_refinement"),
    ({"mesh_refinement": 17}, "mesh_refinement"),
    ({"resolution": (16, 1024), "mesh_refinement": 8}, "mesh_refinement"),
    ({"spectrum": "sinusoids", "sinusoids": ((0.1, 7.0, 0.0, 0.0),)}, "sinusoids[0]"),
    ({"spectrum": "sinusoids", "sinusoids": ((0.1, 0.5, 0.0, 0.0),)}, "sinusoids[0]"),
    ({"spectrum": "sinusoids", "sinusoids": ((-0.1, 10.0, 0.0, 0.0),)}, "sinusoids[0].amplitude_m"),
])
def test_bad_models_name_the_field(changes, field):
    model = W.WaveModel(patch_size_m=(20.0, 20.0), resolution=(16, 16)).replace(**changes)
    with pytest.raises(SceneError) as info:
        W.generate(model)
    assert info.value.field == field, str(info.value)
    # The same check in a scene, where the error names the water and surface.<field>.
    d = waves_scene({k: list(v) if isinstance(v, tuple) and k != "sinusoids" else v
                     for k, v in changes.items() if k != "sinusoids"})
    if "sinusoids" in changes:
        d["water"][0]["surface"]["sinusoids"] = [
            {"amplitude_m": a, "wavelength_m": wl, "direction_deg": dd, "phase_rad": p}
            for a, wl, dd, p in changes["sinusoids"]]
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    assert info.value.obj == "water 'sea'"
    assert info.value.field == f"surface.{field}", str(info.value)


def waves_scene(surface=None, **settings):
    surf = {"kind": "waves", "spectrum": "pierson_moskowitz", "wind_speed": 6.0,
            "patch_size_m": [20.0, 20.0], "resolution": [16, 16], "seed": 1}
    surf.update(surface or {})
    return {"photic_scene": 1, "name": "waves",
            "materials": {"sand": {"type": "lambertian", "reflectance": [0.3]}},
            "water": [{"name": "sea", "type": "ocean", "surface": surf,
                       "bottom": {"depth": 8.0, "material": "sand"},
                       "iops": {"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}}],
            "sun": {"zenith_deg": 30.0, "azimuth_deg": 30.0, "irradiance": [1.0]},
            "sky": {"type": "uniform", "irradiance": [0.2]},
            "radiometers": [{"name": "Ed", "quantity": "Ed", "position": [3.0, 2.0, -2.0]},
                            {"name": "Lu", "quantity": "radiance", "position": [3.0, 2.0, -1.0]}],
            "settings": {"integrator": "hybrid", "seed": 2, **settings}}


def test_waves_surface_loads_round_trips_and_renders(tmp_path):
    from photic.compile import compile_scene
    from photic.scene import load_scene, save_scene

    d = waves_scene({"spectrum": "jonswap", "fetch_m": 2e4, "choppiness": 0.5, "z": 0.2})
    path = tmp_path / "waves.json"
    import json
    path.write_text(json.dumps(d))
    scene = load_scene(path)
    surface = scene.water[0].surface
    assert surface.kind == "waves" and surface.waves.fetch_m == 2e4 and surface.z == 0.2
    mesh, period, normals = surface.patch()
    assert period == (20.0, 20.0) and mesh.vertices.shape == (17 * 17, 3) and normals.shape == (17 * 17, 3)
    save_scene(scene, tmp_path / "again.json")
    assert load_scene(tmp_path / "again.json") == scene
    core = compile_scene(scene, hybrid=True)
    core.build_beams(tuple(scene.sun.direction), 1)
    assert core.beam_count > 0
    result = render(scene, radiometer_samples=4096)
    ed = result.radiometer("Ed")
    print(f"\nEd at 2 m under the waves: {ed.mean[0, 0]:.4f} +- {ed.stderr[0, 0]:.4f}")
    assert 0.2 < ed.mean[0, 0] < 1.2 and ed.stderr[0, 0] < 0.1 * ed.mean[0, 0]
    assert result.radiometer("Lu").mean[0, 0] > 0


def test_waves_scene_errors():
    d = waves_scene({"vertices": [[0, 0, 0]], "triangles": [[0, 0, 0]]})
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    assert info.value.field in ("surface.vertices", "surface.triangles")
    d = waves_scene()
    d["water"][0]["surface"] = {"kind": "flat", "wind_speed": 3.0}
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    assert info.value.field == "surface.wind_speed" and "waves" in info.value.message
    d = waves_scene({"wind_speed": 20.0, "choppiness": 30.0})
    with pytest.raises(SceneError) as info:
        Scene.from_dict(d)
    assert info.value.field == "surface.choppiness" and "folds" in info.value.message


def test_exact_normals_reach_the_beams():
    """The beams refract with the model's normals: a patch given without normals (the
    core's seam-averaged mesh normals) builds slightly different beams than the same mesh
    with the exact normals, and a flat wave model gives the flat ocean's flux."""
    from photic.compile import compile_scene

    scene = Scene.from_dict(waves_scene({"wind_speed": 10.0, "resolution": [8, 8]}))
    mesh, period, normals = scene.water[0].surface.patch()
    as_patch = Scene.from_dict(waves_scene())
    as_patch.water[0].surface = OceanSurface("patch", mesh=TriangleMesh(mesh.vertices.copy(), mesh.triangles.copy()),
                                             period=period)
    a = compile_scene(scene, hybrid=True)
    b = compile_scene(as_patch, hybrid=True)
    sun = tuple(scene.sun.direction)
    a.build_beams(sun, 1)
    b.build_beams(sun, 1)
    da, db = a.prism_arrays()[1], b.prism_arrays()[1]
    assert da.shape == db.shape and not np.allclose(da, db, atol=1e-6)
    flat = Scene.from_dict(waves_scene({"spectrum": "flat"}))
    c = compile_scene(flat, hybrid=True)
    c.build_beams(sun, 1)
    transmitted = c.beam_total_flux()
    # One period's area x E cos(theta) x Fresnel transmittance.
    T = 1 - water_fresnel(math.cos(math.radians(30.0)))
    assert transmitted == pytest.approx(400.0 * math.cos(math.radians(30.0)) * T, rel=1e-3)


def water_fresnel(cos_i, n=1.34):
    from photic import _core
    return _core.fresnel(cos_i, 1.0, n)


def test_scene_format_documents_every_wave_field():
    """docs/scene-format.md lists every field of a "waves" surface, and the scene keys are
    exactly the WaveModel fields (plus kind and z)."""
    import dataclasses
    import json
    from pathlib import Path

    from photic.scene import _WAVE_KEYS

    assert set(_WAVE_KEYS) == {f.name for f in dataclasses.fields(W.WaveModel)}
    schema = json.loads((Path(W.__file__).parent / "schema" / "scene.schema.json").read_text())
    props = schema["$defs"]["surface"]["properties"]
    assert set(_WAVE_KEYS) <= set(props)
    doc = (Path(__file__).parents[1] / "docs" / "scene-format.md").read_text()
    missing = [key for key in _WAVE_KEYS if f"| `{key}` |" not in doc]
    assert not missing, missing


@pytest.mark.parametrize("choppiness", [0.0, 0.8])
def test_mesh_refinement_samples_the_same_waves_finer(choppiness):
    """mesh_refinement r: (r Nx + 1) x (r Ny + 1) vertices on the same band-limited surface,
    which at the grid's own points are the grid's heights and normals (choppy: to the Newton
    resampling's accuracy); between them the surface is the waves' Fourier series (checked at
    points of the finer grid against the direct sum, photic.waves.evaluate), where the coarse
    facets are off by about the shortest waves' curvature."""
    model = W.WaveModel(spectrum="jonswap", wind_speed=6.0, fetch_m=5e4, patch_size_m=(20.0, 20.0),
                        resolution=(32, 24), choppiness=choppiness)
    v1, t1, n1 = W.surface_patch(model)
    v4, t4, n4 = W.surface_patch(model.replace(mesh_refinement=4))
    assert v4.shape == (129 * 97, 3) and len(t4) == 16 * len(t1)
    tol = 1e-12 if choppiness == 0 else 1e-3 * float(np.abs(v1[:, 2]).max())
    on_grid = v4.reshape(129, 97, 3)[::4, ::4].reshape(-1, 3)
    assert np.abs(on_grid - v1).max() <= tol
    assert np.abs(n4.reshape(129, 97, 3)[::4, ::4].reshape(-1, 3) - n1).max() <= (1e-12 if choppiness == 0 else 1e-2)
    if choppiness == 0:
        # a quarter of a cell along x, on the grid's lines along y
        fine = v4.reshape(129, 97, 3)[1::4, ::4][:32, :24]
        h, _, _ = W.evaluate(model, fine[..., 0], fine[..., 1])
        assert np.abs(fine[..., 2] - h).max() <= 1e-9
        # the coarse facets there (their linear interpolation) miss the waves by much more
        c = v1.reshape(33, 25, 3)[..., 2]
        lin = 0.75 * c[:-1, :-1] + 0.25 * c[1:, :-1]
        assert np.sqrt(np.mean((lin - h) ** 2)) > 1e6 * np.sqrt(np.mean((fine[..., 2] - h) ** 2))
        assert np.sqrt(np.mean((lin - h) ** 2)) > 1e-3 * np.sqrt(np.mean(h ** 2))
