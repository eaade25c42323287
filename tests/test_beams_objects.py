"""Beams near objects under waves: an object changes the light only where it stands.

A periodic wave patch's beams are built once for one period and shifted to every period a
query asks about, while objects stand in one period only. These tests put a cube, a sphere and
a thin plate under flat and wavy seas at several sun angles, with radiometers above, beside and
below them and in other periods, and check that

- above an object, beside it and in other periods the beams (and Ed) are those of the same sea
  without the object: exactly where nothing scatters, within the statistics where water does;
- below an object its shadow is there;
- the hybrid integrator agrees with path tracing under an enlarged sun where both converge.
"""
import numpy as np
import pytest
import trimesh

from geometry import box
from photic.compile import compile_scene
from photic.render import render
from photic.scene import Scene

PERIOD = 20.0  # the wave patch's period (m)


def waves(resolution=32):
    return {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0, "fetch_m": 50000.0,
            "patch_size_m": [PERIOD, PERIOD], "resolution": [resolution, resolution], "seed": 0}


def cube(centre=(0.0, 0.0, -3.0), half=1.0, material="grey"):
    c = np.asarray(centre)
    v, t = box(c - half, c + half)
    return {"name": "cube", "material": material, "vertices": v, "triangles": t}


def sphere(centre=(6.0, 3.0, -3.0), radius=1.0, material="grey"):
    m = trimesh.creation.icosphere(subdivisions=2, radius=radius)
    return {"name": "sphere", "material": material, "vertices": (m.vertices + centre).tolist(),
            "triangles": m.faces.tolist()}


def plate(centre=(-6.0, 6.0, -3.0), half=1.5, thickness=0.02, material="grey"):
    c = np.asarray(centre)
    h = np.array([half, half, thickness / 2])
    v, t = box(c - h, c + h)
    return {"name": "plate", "material": material, "vertices": v, "triangles": t}


OBJECTS = {"cube": cube, "sphere": sphere, "plate": plate}


def object_centre(name):
    m = OBJECTS[name]()
    v = np.asarray(m["vertices"])
    return (v.min(0) + v.max(0)) / 2


def sea(surface, meshes=(), zenith=30.0, azimuth=290.0, diameter=0.53, a=0.1, b=0.2,
        reflectance=0.3, integrator="hybrid", seed=1, positions=(), quantity="Ed"):
    """A sea 5 m deep with ``meshes`` (names of OBJECTS or mesh dicts); radiometers
    (``quantity``) at ``positions``."""
    rads = [{"name": f"r{i}", "quantity": quantity, "position": list(map(float, p))}
            for i, p in enumerate(positions)]
    d = {"photic_scene": 1, "name": "objects",
         "materials": {"sand": {"type": "lambertian", "reflectance": [reflectance]},
                       "grey": {"type": "lambertian", "reflectance": [reflectance]}},
         "meshes": [OBJECTS[m]() if isinstance(m, str) else m for m in meshes],
         "water": [{"name": "sea", "type": "ocean", "surface": surface,
                    "bottom": {"depth": 5.0, "material": "sand"},
                    "iops": {"absorption": [a], "b": [b], "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": zenith, "azimuth_deg": azimuth, "irradiance": [1.0],
                 "angular_diameter_deg": diameter},
         "radiometers": rads,
         "settings": {"integrator": integrator, "seed": seed, "forward_cone_deg": 0}}
    return Scene.from_dict(d)


def refracted(zenith, azimuth, ior=1.34):
    """The refracted sun's direction of travel below a flat surface."""
    th, ph = np.radians(zenith), np.radians(azimuth)
    st = np.sin(th) / ior
    return -np.array([st * np.cos(ph), st * np.sin(ph), np.sqrt(1 - st * st)])


def probe_points(name, zenith, azimuth):
    """Points above the object (1 m over its top), beside it (2.5 m from its centre towards
    the sun: lit), below it (in its shadow, 0.5 m below its bottom along the refracted sun),
    just above the floor far from it, and the same set shifted by whole periods."""
    c = object_centre(name)
    v = np.asarray(OBJECTS[name]()["vertices"])
    d = refracted(zenith, azimuth)
    sunward = -d[:2] / max(np.linalg.norm(d[:2]), 1e-9) if zenith > 0 else np.array([1.0, 0.0])
    above = np.array([c[0], c[1], v[:, 2].max() + 1.0])
    beside = np.array([*(c[:2] + 2.5 * sunward), c[2]])
    # straight below the centre when the sun is high; along the beam otherwise
    t = (v[:, 2].min() - 0.5 - c[2]) / d[2]
    below = c + d * t
    floor = np.array([c[0] + 10.0, c[1] + 10.0, -4.95])  # half a period away from all three
    lit = [above, beside, floor]
    return lit, below


SHIFTS = [(PERIOD, 0.0), (-2 * PERIOD, PERIOD), (3 * PERIOD, -3 * PERIOD)]


@pytest.mark.parametrize("surface_kind", ["flat", "waves"])
@pytest.mark.parametrize("zenith,azimuth", [(0.0, 0.0), (30.0, 290.0), (60.0, 45.0)])
def test_beams_near_objects_equal_the_object_free_sea(surface_kind, zenith, azimuth):
    """Beam by beam: at points above, beside and far from each object, in its own period and
    in others, the beams are those of the sea without objects (same directions, irradiances
    to 1e-9); below each object they are gone (its shadow)."""
    surface = {"kind": "flat", "z": 0.0} if surface_kind == "flat" else waves()
    names = list(OBJECTS)
    free = compile_scene(sea(surface, (), zenith, azimuth, positions=[(0, 0, -1)]), hybrid=True,
                         forward_cone_deg=0.0)
    with_objects = compile_scene(sea(surface, names, zenith, azimuth, positions=[(0, 0, -1)]),
                                 hybrid=True, forward_cone_deg=0.0)
    sun = tuple(sea(surface, (), zenith, azimuth, positions=[(0, 0, -1)]).sun.direction)
    free.build_beams(sun, 0)
    with_objects.build_beams(sun, 0)

    def total(core, p):
        return sum(e[0] * -d[2] for d, e in core.beams_at(tuple(map(float, p)), 0))

    checked = shadowed = 0
    for name in names:
        lit, below = probe_points(name, zenith, azimuth)
        for p in lit:
            for s in [(0.0, 0.0)] + SHIFTS:
                q = p + np.array([s[0], s[1], 0.0])
                ref = total(free, q)
                got = total(with_objects, q)
                assert got == pytest.approx(ref, rel=1e-9, abs=1e-12), (name, p, s, got, ref)
                checked += ref > 0
        # the shadow below the object, in its own period only
        assert total(with_objects, below) < 0.05 * total(free, below), (name, below)
        for s in SHIFTS:
            q = below + np.array([s[0], s[1], 0.0])
            assert total(with_objects, q) == pytest.approx(total(free, q), rel=1e-9, abs=1e-12)
        shadowed += 1
    assert checked >= 0.9 * len(names) * 3 * (1 + len(SHIFTS))  # lit points do see beams
    assert shadowed == len(names)


def test_ed_above_objects_under_waves_equals_the_object_free_sea(zscore):
    """The issue's scene: JONSWAP waves over a 20 m period, Petzold water, a 2 m cube at 4 m
    depth (and a sphere and a plate), a 5 x 5 grid of Ed radiometers at 2 m (over the cube's
    top) across more than a period. Independent seeds: Ed with the objects equals Ed without
    them within the statistics, at the original positions and shifted by two periods."""
    grid = [(x, y, -2.0) for x in range(-5, 12, 4) for y in range(-8, 9, 4)]
    shifted = [(x + 2 * PERIOD, y + 2 * PERIOD, z) for x, y, z in grid]
    free = render(sea(waves(), (), seed=11, positions=grid), radiometer_samples=4096)
    objects = [cube(centre=(0.0, 0.0, -4.0)), sphere(), plate()]  # the cube on the floor
    objs = render(sea(waves(), objects, seed=12, positions=grid + shifted),
                  radiometer_samples=4096)
    n = len(grid)
    zs = []
    for i in range(n):
        f = free.radiometers[i]
        for j in (i, i + n):
            r = objs.radiometers[j]
            se = float(np.hypot(r.stderr[0, 0], f.stderr[0, 0]))
            zs.append((r.mean[0, 0] - f.mean[0, 0]) / se)
    zs = np.array(zs)
    mean_free = np.mean([r.mean[0, 0] for r in free.radiometers])
    mean_obj = np.mean([r.mean[0, 0] for r in objs.radiometers[:n]])
    se_mean = np.sqrt(sum(r.stderr[0, 0] ** 2 for r in free.radiometers[:n]) +
                      sum(r.stderr[0, 0] ** 2 for r in objs.radiometers[:n])) / n
    zscore("grid mean Ed, objects vs none", mean_obj, mean_free, se_mean)
    assert np.max(np.abs(zs)) < 4.0, zs
    assert abs((mean_obj - mean_free) / se_mean) < 3.5


@pytest.mark.parametrize("surface_kind", ["flat", "waves"])
def test_hybrid_equals_path_tracing_near_objects(surface_kind, zscore):
    """With the sun enlarged to 10 deg both integrators converge: Ed above, beside and below
    each object (its shadow included), under a flat and a wavy sea."""
    surface = {"kind": "flat", "z": 0.0} if surface_kind == "flat" else waves(resolution=24)
    zenith, azimuth = 30.0, 290.0
    points = []
    for name in OBJECTS:
        lit, below = probe_points(name, zenith, azimuth)
        points += [lit[0], lit[1], below]
    kw = dict(zenith=zenith, azimuth=azimuth, diameter=10.0, positions=points)
    hy = render(sea(surface, list(OBJECTS), seed=3, **kw), radiometer_samples=32768)
    pt = render(sea(surface, list(OBJECTS), integrator="path", seed=4, **kw), radiometer_samples=524288)
    worst = 0.0
    for i, r in enumerate(hy.radiometers):
        p = pt.radiometers[i]
        se = float(np.hypot(r.stderr[0, 0], p.stderr[0, 0]))
        z = zscore(f"{surface_kind}: hybrid vs path at {np.round(points[i], 2).tolist()}",
                   r.mean[0, 0], p.mean[0, 0], se)
        worst = max(worst, abs(z))
    assert worst < 4.0
