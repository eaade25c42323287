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

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

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


# --- A water mesh (a tank): which prisms test visibility --------------------------------------

def tank(objects=(), zenith=30.0, azimuth=0.0):
    """A 4 x 4 x 2 m tank of water (its top in 8 x 8 x 2 triangles) on an opaque floor, with
    opaque ``objects`` (mesh dicts) in and above it."""
    water = trimesh.creation.box(extents=(4.0, 4.0, 2.001))
    water.apply_translation((0.0, 0.0, -1.0005))  # its bottom 1 mm into the floor
    water = water.subdivide().subdivide().subdivide()
    fv, ft = box((-3.0, -3.0, -2.2), (3.0, 3.0, -2.0))
    d = {"photic_scene": 1, "name": "tank",
         "materials": {"grey": {"type": "lambertian", "reflectance": [0.3]}},
         "meshes": [{"name": "floor", "material": "grey", "vertices": fv, "triangles": ft}, *objects],
         "water": [{"name": "tank", "type": "mesh", "vertices": water.vertices.tolist(),
                    "triangles": water.faces.tolist(),
                    "iops": {"absorption": [0.1], "b": [0.0], "phase": {"type": "isotropic"}}}],
         "sun": {"zenith_deg": zenith, "azimuth_deg": azimuth, "irradiance": [1.0],
                 "angular_diameter_deg": 0.53},
         "radiometers": [{"name": "r", "quantity": "Ed", "position": [0.0, 0.0, -1.0]}],
         "settings": {"integrator": "hybrid", "forward_cone_deg": 0}}
    return Scene.from_dict(d)


def opaque_box(name, lo, hi):
    v, t = box(lo, hi)
    return {"name": name, "material": "grey", "vertices": v, "triangles": t}


def test_tank_prisms_test_shadows_where_objects_may_cut_them():
    """A thin rod in the water between the vertex rays of the prisms around it, and a small
    sunshade above the water: no vertex ray meets either, so only the prisms' shadow tests
    find them. Far from both, no prism tests (they cannot be cut) and the beams equal those
    of the tank without the objects; in the shadows of the rod and of the shade there is no
    beam."""
    zenith = 30.0
    rod = opaque_box("rod", (0.31, 0.27, -1.5), (0.33, 0.29, -0.5))
    shade = opaque_box("shade", (0.45, -1.2, 0.5), (0.75, -0.9, 0.52))
    scenes = {k: tank(objs, zenith) for k, objs in [("free", ()), ("objects", (rod, shade))]}
    cores = {}
    for k, s in scenes.items():
        cores[k] = compile_scene(s, hybrid=True, forward_cone_deg=0.0)
        cores[k].build_beams(tuple(s.sun.direction), 0)
    checks = np.asarray(cores["objects"].prism_checks())
    # most prisms are far from the rod and the shade (the floor they end on does not count)
    assert checks[:, 0].mean() < 0.5 and checks[:, 1].mean() < 0.5, checks.mean(0)

    d = refracted(zenith, 0.0)
    s = np.asarray(scenes["free"].sun.direction)
    z = -1.95

    def total(core, p):  # the beams through the top (the side facing the sun sends others)
        return sum(e[0] * -dd[2] for dd, e in core.beams_at(tuple(map(float, p)), 0) if np.dot(dd, d) > 0.999)

    def along_beam(p):  # from height z on the beam through p (under water)
        return p + d * (z - p[2]) / d[2]

    rod_shadow = along_beam(np.array([0.32, 0.28, -1.0]))
    # the shade's shadow: through the surface at the shade's centre seen from the sun
    at_surface = np.array([0.6, -1.05, 0.51]) - s * (0.51 / s[2])
    shade_shadow = along_beam(at_surface)
    for p in (rod_shadow, shade_shadow):
        assert total(cores["free"], p) > 0.5
        assert total(cores["objects"], p) == 0.0, p
    rng = np.random.default_rng(3)
    far = 0
    for _ in range(300):
        p = np.array([*rng.uniform(-1.9, 1.9, 2), rng.uniform(-1.95, -0.05)])
        near_rod = np.linalg.norm((along_beam(p) - rod_shadow)[:2]) < 0.6
        near_shade = np.linalg.norm((along_beam(p) - shade_shadow)[:2]) < 0.6
        if near_rod or near_shade:
            continue
        assert cores["objects"].beams_at(tuple(p), 0) == cores["free"].beams_at(tuple(p), 0), p
        far += 1
    assert far > 100


def test_cameras_do_not_change_the_beams():
    """The reflected beams end at the bounds of what they can light (meshes, radiometers, the
    ocean), not at a camera high above: the stepped pool's beams in the air (on the deck and the
    walls above the water) and in the water are the same with its camera at 3.8 m or without it."""
    from photic.render import sun_direction
    from photic.scenes import DECK_Z, POOL_X, POOL_Y, stepped_pool
    cores = {}
    for name, keep in (("both", ("above", "under")), ("under", ("under",))):
        s = stepped_pool(resolution=(8, 8))
        s.cameras = [c for c in s.cameras if c.name in keep]
        s.validate()
        core = compile_scene(s, hybrid=True, forward_cone_deg=0.0)
        core.build_beams(tuple(sun_direction(s, 0.5, 0.5)), 0)
        cores[name] = core
    rng = np.random.default_rng(3)
    # above the water, below the deck's top (the walls' faces there, air radiometers)
    air = rng.uniform([POOL_X[0], POOL_Y[0], 0.05], [POOL_X[1], POOL_Y[1], DECK_Z - 0.01], (300, 3))
    lit = 0
    for p in air:
        a, b = cores["both"].beams_at(tuple(p), -1), cores["under"].beams_at(tuple(p), -1)
        assert a == b, p
        lit += len(a) > 0
    assert lit > 100  # the sun reflected by the waves
    # the reflected prisms end at the deck's height (plus a margin of 1e-3 of the scene), not
    # at the camera's 3.8 m
    for core in cores.values():
        v, d, length = (np.asarray(x) for x in core.prism_arrays(air=True)[:3])
        assert len(v) > 1000
        assert (v + d * length[:, :, None])[:, :, 2].max() < DECK_Z + 0.05
    water = rng.uniform([POOL_X[0], POOL_Y[0], -0.55], [POOL_X[1], POOL_Y[1], -0.05], (200, 3))
    for p in water:
        assert cores["both"].beams_at(tuple(p), 0) == cores["under"].beams_at(tuple(p), 0), p
