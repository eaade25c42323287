"""The light a Lambertian floor sends up and the sea surface reflects back down: closed forms
(tests/analytic.py, FloorCase) for every radiometer quantity, and cameras against radiometers
at the same place. A bias of 1 % in these numbers must fail: the irradiances are estimated to
0.25 % or better, so such a bias is at least 4 standard errors."""
import numpy as np
import pytest

from analytic import FloorCase, cube_cameras, cube_pixel_integrals, pixel_integrals
from photic.render import render
from photic.scene import Scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

Z_MAX = 4.0
PRECISE = 0.0025  # relative standard error an irradiance must reach here
IRRADIANCES = ("Ed", "Eu", "Eo", "Eod", "Eou")
WAVES = {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0, "fetch_m": 50000.0,
         "patch_size_m": [10.0, 10.0], "resolution": [32, 32], "seed": 0}


def floor_scene(R, a, H, radiometers=(), cameras=(), zenith=None, l_sky=0.0, b=0.0, surface=None,
                meshes=(), integrator="hybrid", seed=1):
    d = {"photic_scene": 1, "name": "floor", "bands": [{"name": "b", "center_nm": 550, "width_nm": 10}],
         "materials": {"floor": {"type": "lambertian", "reflectance": [R]},
                       "black": {"type": "lambertian", "reflectance": [0.0]}},
         "meshes": list(meshes),
         "water": [{"name": "sea", "type": "ocean", "ior": 1.34,
                    "surface": surface or {"kind": "flat", "z": 0.0},
                    "iops": {"absorption": [a], "b": [b], "phase": {"type": "petzold"}},
                    "bottom": {"depth": H, "material": "floor"}}],
         "sky": {"type": "uniform", "radiance": [l_sky]} if l_sky else {"type": "black"},
         "radiometers": list(radiometers), "cameras": list(cameras),
         "settings": {"seed": seed, "integrator": integrator}}
    if zenith is not None:
        d["sun"] = {"zenith_deg": zenith, "azimuth_deg": 20.0, "irradiance": [1.0]}
    return Scene.from_dict(d)


def sensors(z, air_z=None):
    at = [0.1, 0.2, z]
    rads = [{"name": q, "quantity": q, "position": at} for q in IRRADIANCES]
    rads += [{"name": "Lup", "quantity": "radiance", "direction": [0, 0, 1], "half_angle_deg": 15.0, "position": at},
             {"name": "Ldown", "quantity": "radiance", "direction": [0, 0, -1], "half_angle_deg": 10.0,
              "position": at},
             {"name": "dist", "quantity": "radiance_distribution", "polar_bins": 9, "azimuth_bins": 2,
              "position": at}]
    if air_z is not None:
        rads.append({"name": "Lair", "quantity": "radiance", "direction": [0, 0, -1], "half_angle_deg": 5.0,
                     "position": [0.0, 0.0, air_z]})
    return rads


def check_floor_case(res, fc, zscore, with_sun, air):
    for q in IRRADIANCES:
        r = res.radiometer(q)
        ref = fc.irradiance(q)
        assert abs(zscore(q, r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
        assert r.stderr[0, 0] < PRECISE * ref, q
    checks = [("Ldown", fc.radiance_cap(False, 10.0))]
    if not with_sun or fc.l_sky > 0:  # the sun kept outside the zenith cap by the callers
        checks.append(("Lup", fc.radiance_cap(True, 15.0)))
    if air:
        checks.append(("Lair", fc.air_radiance_down(5.0)))
    for name, ref in checks:
        r = res.radiometer(name)
        assert abs(zscore(name, r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
    dist = res.radiometer("dist")
    for ip in range(9):
        c0, c1 = np.cos(np.pi * (ip + 1) / 9), np.cos(np.pi * ip / 9)
        if c0 < 0 < c1 or fc.sun_in_bin(c0, c1) or (not fc.l_sky and c0 > 0 and fc.l_floor == 0):
            continue
        ref = fc.radiance_bin(c0, c1)
        for ia in range(2):
            v, se = dist.mean[ip * 2 + ia, 0], dist.stderr[ip * 2 + ia, 0]
            assert abs(zscore(f"L bin {20 * ip}-{20 * ip + 20} deg", v, ref, se)) < Z_MAX


@pytest.mark.parametrize("R,a,H,zenith,l_sky", [
    (0.5, 0.1, 2.0, 0.0, 0.0),     # the sun overhead: no in-air cap (its glint is at the nadir)
    (0.9, 0.1, 2.0, 30.0, 0.0),
    (0.5, 0.3, 1.0, 60.0, 0.2),
    (0.2, 0.05, 4.0, 45.0, 0.0),
])
def test_floor_light_reflected_down_matches_closed_form_hybrid(zscore, R, a, H, zenith, l_sky):
    """Hybrid integrator, the real sun (and a uniform sky): every radiometer quantity 1 cm above
    the floor, and a nadir radiance in the air, against the geometric series of reflections
    between the floor and the surface."""
    h = 0.01
    air = zenith >= 20.0
    sc = floor_scene(R, a, H, sensors(-(H - h), 1.0 if air else None), zenith=zenith, l_sky=l_sky)
    res = render(sc, radiometer_samples=400_000)
    fc = FloorCase(R, a, H, h, zenith, l_sky=l_sky)
    check_floor_case(res, fc, zscore, True, air)


@pytest.mark.parametrize("integrator", ["path", "hybrid"])
def test_floor_light_under_a_uniform_sky_matches_closed_form(zscore, integrator):
    """No sun (so no beams): the sky through Snell's window and its reflections, both
    integrators."""
    R, a, H, h = 0.7, 0.15, 1.5, 0.02
    sc = floor_scene(R, a, H, sensors(-(H - h), 1.0), l_sky=1.0, integrator=integrator)
    res = render(sc, radiometer_samples=400_000)
    check_floor_case(res, FloorCase(R, a, H, h, 0.0, e_sun=0.0, l_sky=1.0), zscore, False, True)


def test_closed_form_floor_reduces_to_known_limits():
    """The closed form itself: with a black floor only the direct sun is left; the series
    E_floor = E_0 / (1 - R r) solves E_floor = E_0 + R r E_floor; Eo = Eod + Eou."""
    fc0 = FloorCase(0.0, 0.1, 2.0, 0.0, 30.0, sun_diameter_deg=0.01)
    mu_a = np.cos(np.radians(30.0))
    mu_w = np.sqrt(1 - (1 - mu_a ** 2) / 1.34 ** 2)
    from analytic import fresnel_unpolarized
    t = 1 - fresnel_unpolarized(mu_a, 1.0, 1.34)
    assert fc0.irradiance("Ed") == pytest.approx(mu_a * t * np.exp(-0.2 / mu_w), rel=1e-6)
    assert fc0.irradiance("Eu") == 0.0
    fc = FloorCase(0.6, 0.1, 2.0, 0.0, 30.0)
    assert fc.irradiance("Eu") == pytest.approx(0.6 * fc.irradiance("Ed"), rel=1e-4)  # at the floor
    assert fc.irradiance("Eo") == pytest.approx(fc.irradiance("Eod") + fc.irradiance("Eou"), rel=1e-12)


# --- cameras against radiometers ------------------------------------------------------------------

def plate(at, half, dz):
    """A black square above `at` (its own shadow keeps the direct sun off the sensors)."""
    x, y, z = at[0], at[1], at[2] + dz
    return {"name": "parasol", "material": "black",
            "vertices": [[x - half, y - half, z], [x + half, y - half, z], [x + half, y + half, z],
                         [x - half, y + half, z]], "triangles": [[0, 1, 2], [0, 2, 3]]}


def cap_camera(name, at, direction, half_angle_deg, up, resolution):
    """A narrow perspective camera whose square image holds the radiance cap."""
    return {"name": name, "type": "perspective", "position": list(at), "direction": list(direction),
            "up": list(up), "fov_deg": 2.2 * half_angle_deg, "resolution": [resolution, resolution]}


def estimate(images, weights):
    """sum of pixel value x weight over the images, and its standard error (pixels are
    independent: each has its own samples)."""
    v = sum(float(np.sum(img.mean[..., 0] * w)) for img, w in zip(images, weights))
    var = sum(float(np.sum(img.variance[..., 0] * w ** 2)) for img, w in zip(images, weights))
    return v, np.sqrt(var)


@pytest.mark.parametrize("surface,b", [("flat", 0.0), ("waves", 0.0), ("waves", 0.15)])
def test_cameras_and_radiometers_agree_on_every_quantity(zscore, surface, b):
    """At the same place, the same quantity: irradiances and a radiance distribution from a cube
    map of six cameras (each pixel weighted by the integral of the quantity's response over its
    solid angle), radiance caps from a narrow camera holding the cap, in the water near the floor
    and in the air. A black plate above the sensors keeps the refracted sun off them (a camera
    would find the sun's tiny disk by chance: too noisy to compare), so everything seen is light
    the floor sent up, the surface reflected and (b > 0) the water scattered."""
    R, a, H = 0.5, 0.1, 2.0
    at = [0.1, 0.2, -1.9]
    air_at = [0.3, -0.2, 1.0]
    caps = [("Ldown", at, [0, 0, -1], 3.0, [0, 1, 0]), ("Lslant", at, [0.8, 0.0, 0.6], 3.0, [0, 0, 1]),
            ("Lair", air_at, [0, 0, -1], 5.0, [0, 1, 0])]
    rads = [{"name": q, "quantity": q, "position": at} for q in IRRADIANCES]
    rads += [{"name": n, "quantity": "radiance", "direction": d, "half_angle_deg": ha, "position": p}
             for n, p, d, ha, _ in caps]
    rads.append({"name": "dist", "quantity": "radiance_distribution", "polar_bins": 6, "azimuth_bins": 4,
                 "position": at})
    res_px = 32
    cams = cube_cameras(at, res_px)
    cams += [cap_camera(f"cam_{n}", p, d, ha, u, 24) for n, p, d, ha, u in caps]
    sc = floor_scene(R, a, H, rads, cams, zenith=30.0, b=b, surface=WAVES if surface == "waves" else None,
                     meshes=[plate(at, 0.25, 0.3)], seed=5)
    res = render(sc, samples=96, radiometer_samples=600_000)

    def bin_of(ip, ia):
        def g(v):
            th = np.arccos(np.clip(v[..., 2], -1, 1))
            ph = np.mod(np.arctan2(v[..., 1], v[..., 0]), 2 * np.pi)
            return ((np.minimum(5, (th / np.pi * 6).astype(int)) == ip)
                    & (np.minimum(3, (ph / (2 * np.pi) * 4).astype(int)) == ia)) * 1.0
        return g

    responses = {"Ed": lambda v: np.maximum(v[..., 2], 0.0), "Eu": lambda v: np.maximum(-v[..., 2], 0.0),
                 "Eo": lambda v: np.ones(v.shape[:-1]), "Eod": lambda v: (v[..., 2] > 0) * 1.0,
                 "Eou": lambda v: (v[..., 2] < 0) * 1.0}
    bins = [(ip, ia) for ip in range(6) for ia in range(4)]
    weights = cube_pixel_integrals(res_px, list(responses.values()) + [bin_of(*x) for x in bins])
    cube = [res.images[f"cube{i}"] for i in range(6)]
    for q, w in zip(responses, weights):
        r = res.radiometer(q)
        v, se = estimate(cube, w)
        assert abs(zscore(f"{q} camera - radiometer", v - r.mean[0, 0], 0.0, np.hypot(se, r.stderr[0, 0]))) < Z_MAX
        assert np.hypot(se, r.stderr[0, 0]) < 2 * PRECISE * v, q
    dist = res.radiometer("dist")
    compared = 0
    for (ip, ia), w in zip(bins, weights[5:]):
        omega = w.sum()
        v, se = estimate(cube, w / omega)
        rv, rs = dist.mean[ip * 4 + ia, 0], dist.stderr[ip * 4 + ia, 0]
        if v == 0.0 and rv == 0.0:  # the plate (black) fills the bin for both
            continue
        compared += 1
        assert abs(zscore(f"L bin {ip},{ia} camera - radiometer", v - rv, 0.0, np.hypot(se, rs))) < Z_MAX
    assert compared >= 12
    for n, p, d, ha, u in caps:
        c = np.cos(np.radians(ha))
        dd = np.asarray(d, float) / np.linalg.norm(d)
        (w,) = pixel_integrals(dd, u, 2.2 * ha, 24, [lambda v: (v @ dd >= c) * 1.0])
        v, se = estimate([res.images[f"cam_{n}"]], [w / (2 * np.pi * (1 - c))])
        r = res.radiometer(n)
        assert abs(zscore(f"{n} camera - radiometer", v - r.mean[0, 0], 0.0, np.hypot(se, r.stderr[0, 0]))) < Z_MAX
