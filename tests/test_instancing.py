"""Instanced meshes (issue 43): a mesh stored once and placed by transforms is traced as an
Embree instance array over its own BVH. Its renders must be those of the same scene with every
copy's triangles in the world (``MeshObject.flattened``): pixels, radiometers near and under
the copies (shadows, caustics through waves, beams' shadow tests), rotated, stretched and
mirrored copies alike. And bad transforms are refused, naming the copy."""
import json

import numpy as np
import pytest
import trimesh

from photic.render import render
from photic.scene import MeshObject, Scene, SceneError, TriangleMesh, load_scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _transforms(n, seed=3):
    """n copies on and above a 5 m deep sea's floor: rotated about random axes, stretched
    unevenly, every fifth mirrored."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, 3, 4))
    for k in range(n):
        r = _rotation(rng.normal(size=3), rng.uniform(0, 2 * np.pi))
        s = np.diag(rng.uniform(0.4, 1.1, 3) * (-1 if k % 5 == 4 else 1, 1, 1))
        out[k, :, :3] = r @ s
        out[k, :, 3] = (rng.uniform(-4, 4), rng.uniform(-4, 4), rng.uniform(-4.6, -2.0))
    return out


def _sea(meshes, integrator="hybrid", seed=1, resolution=(48, 36)):
    """A wavy sea 5 m deep, the sun at 30 deg, an underwater camera looking down at the copies
    and radiometers beside, under and among them."""
    rads = [{"name": f"Ed{i}", "quantity": q, "position": p}
            for i, (q, p) in enumerate([("Ed", [0.0, 0.0, -4.9]), ("Ed", [2.0, -1.0, -4.5]),
                                        ("Eo", [-1.0, 1.5, -3.0]), ("Eu", [0.5, 0.5, -1.0])])]
    d = {"photic_scene": 1, "name": "instances",
         "materials": {"sand": {"type": "lambertian", "reflectance": [0.4]},
                       "rock": {"type": "lambertian", "reflectance": [0.6]}},
         "water": [{"name": "sea", "type": "ocean",
                    "surface": {"kind": "waves", "spectrum": "jonswap", "wind_speed": 6.0,
                                "fetch_m": 50000.0, "patch_size_m": [20.0, 20.0],
                                "resolution": [32, 32], "seed": 0},
                    "bottom": {"depth": 5.0, "material": "sand"},
                    "iops": {"absorption": [0.1], "b": [0.2], "phase": {"type": "petzold"}}}],
         "sun": {"zenith_deg": 30.0, "azimuth_deg": 290.0, "irradiance": [1.0]},
         "sky": {"type": "cardioidal", "irradiance": [0.3]},
         "cameras": [{"name": "diver", "type": "perspective", "position": [0.0, -6.0, -1.0],
                      "look_at": [0.0, 0.0, -4.0], "fov_deg": 70.0, "resolution": list(resolution)}],
         "radiometers": rads,
         "settings": {"integrator": integrator, "seed": seed}}
    scene = Scene.from_dict(d)
    scene.meshes = list(meshes)
    return scene


def _rock(n=12):
    m = trimesh.creation.icosphere(subdivisions=1, radius=0.6)
    v = np.asarray(m.vertices) * (1.0, 0.7, 0.5)  # not symmetric: a wrong transform shows
    return MeshObject("rocks", TriangleMesh(v, np.asarray(m.faces)), "rock", instances=_transforms(n))


def _same_but_for_rounding(a, b):
    """Two renders with the same seed of the same geometry, once instanced and once flattened:
    their paths differ only where float rounding at a copy's surface changes a decision
    (measured: pixels within 3e-5 of each other; a copy's normal left in its own frame made
    half the pixels differ by more than 1e-3)."""
    assert np.all(np.isfinite(a)) and a.mean() > 0
    rel = np.abs(a - b) / a.mean()
    assert rel.mean() < 1e-4 and np.mean(rel > 1e-3) < 0.01, (rel.mean(), np.mean(rel > 1e-3), rel.max())


def _z(a, va, b, vb):
    ok = (va + vb) > 0
    return (a - b)[ok] / np.sqrt(va + vb)[ok]


def test_instances_render_as_their_flattened_copies():
    rock = _rock()
    inst = _sea([rock])
    flat = _sea([rock.flattened()])
    assert rock.copies == 12 and len(flat.meshes[0].mesh.triangles) == 12 * 80
    # The same seed: the same paths but for float rounding where rays meet the copies.
    a = render(inst, samples=16, radiometer_samples=8192, seed=5, threads=2)
    b = render(flat, samples=16, radiometer_samples=8192, seed=5, threads=2)
    ia, ib = a.images["diver"], b.images["diver"]
    _same_but_for_rounding(ia.mean, ib.mean)
    # Independent seeds: statistically the same images and radiometers.
    c = render(flat, samples=16, radiometer_samples=8192, seed=11, threads=2)
    ic = c.images["diver"]
    z = _z(ia.mean, ia.variance, ic.mean, ic.variance)
    assert 0.75 < np.mean(z ** 2) < 1.35, np.mean(z ** 2)
    assert np.abs(z).max() < 6.0
    for ra, rc in zip(a.radiometers, c.radiometers):
        zr = (ra.mean - rc.mean) / np.sqrt(ra.stderr ** 2 + rc.stderr ** 2)
        assert np.all(np.abs(zr) < 4.5), (ra.name, ra.mean, rc.mean, zr)
    # The copies are there: the floor under them is shaded, the camera sees them.
    empty = render(_sea([]), samples=16, radiometer_samples=8192, seed=5, threads=2)
    assert np.abs(empty.images["diver"].mean - ia.mean).mean() > 0.05 * ia.mean.mean()


def test_instances_in_a_water_mesh_cast_the_beams_shadows():
    """In a closed water mesh (the stepped pool) the beams' prisms test shadow rays only where
    an opaque triangle may stand in them, found by an Embree point query that must see the
    copies in the world: a copy missed there would leave the floor under it lit."""
    from photic.scenes import stepped_pool

    def pool(rocks):
        s = stepped_pool(resolution=(48, 32))
        s.meshes.append(rocks)
        return s

    m = trimesh.creation.icosphere(subdivisions=1, radius=0.35)
    x = _transforms(8, seed=7)
    x[:, 0, 3] *= 0.6
    x[:, 1, 3] *= 0.3
    x[:, 2, 3] = np.linspace(-1.2, -0.4, 8)  # in the pool's water, between floor and surface
    rocks = MeshObject("rocks", TriangleMesh(np.asarray(m.vertices), np.asarray(m.faces)), "tile", instances=x)
    # Independent seeds (the pool's long paths under total internal reflection let rounding
    # at a copy change decisions in a few pixels with the same seed): the same images.
    a = render(pool(rocks), samples=32, seed=1, threads=2)
    b = render(pool(rocks.flattened()), samples=32, seed=2, threads=2)
    for cam in ("above", "under"):
        ia, ib = a.images[cam], b.images[cam]
        z = _z(ia.mean, ia.variance, ib.mean, ib.variance)
        assert 0.8 < np.mean(z ** 2) < 1.3 and np.abs(z).max() < 6.0, (cam, np.mean(z ** 2), np.abs(z).max())
    empty = render(stepped_pool(resolution=(48, 32)), samples=8, seed=4, threads=2)
    assert np.abs(empty.images["under"].mean - a.images["under"].mean).mean() > 0.02 * a.images["under"].mean.mean()


def test_copies_found_only_by_the_prisms_shadow_tests_cast_shadows():
    """The tank of tests/test_beams_objects.py with its thin rod and its sunshade made as two
    copies of one unit cube: no vertex ray meets either, so only the prisms' shadow tests (an
    Embree point query that must see the copies in the world) find them; in their shadows
    there is no beam, and far from both the prisms need no test."""
    from test_beams_objects import refracted, tank

    from photic.compile import compile_scene

    from geometry import box

    v, t = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    x = np.zeros((2, 3, 4))
    for k, (lo, hi) in enumerate([((0.31, 0.27, -1.5), (0.33, 0.29, -0.5)), ((0.45, -1.2, 0.5), (0.75, -0.9, 0.52))]):
        x[k, :, :3] = np.diag(np.subtract(hi, lo))
        x[k, :, 3] = lo
    cubes = MeshObject("rod and shade", TriangleMesh(np.asarray(v, float), np.asarray(t)), "grey", instances=x)
    zenith = 30.0
    scenes = {"free": tank((), zenith), "copies": tank((), zenith), "flat": tank((), zenith)}
    scenes["copies"].meshes = [cubes]
    scenes["flat"].meshes = [cubes.flattened()]
    cores = {}
    for k, sc in scenes.items():
        cores[k] = compile_scene(sc, hybrid=True, forward_cone_deg=0.0)
        cores[k].build_beams(tuple(sc.sun.direction), 0)
    checks = np.asarray(cores["copies"].prism_checks())
    assert 0.0 < checks[:, 0].mean() < 0.5 and 0.0 < checks[:, 1].mean() < 0.5, checks.mean(0)
    assert np.array_equal(checks, np.asarray(cores["flat"].prism_checks()))  # as the flattened
    d = refracted(zenith, 0.0)
    s = np.asarray(scenes["free"].sun.direction)
    z = -1.95

    def total(core, p):
        return sum(e[0] * -dd[2] for dd, e in core.beams_at(tuple(map(float, p)), 0) if np.dot(dd, d) > 0.999)

    def along_beam(p):
        return p + d * (z - p[2]) / d[2]

    rod_shadow = along_beam(np.array([0.32, 0.28, -1.0]))
    shade_shadow = along_beam(np.array([0.6, -1.05, 0.51]) - s * (0.51 / s[2]))
    for p in (rod_shadow, shade_shadow):
        assert total(cores["free"], p) > 0.5
        assert total(cores["copies"], p) == 0.0, p


def test_path_tracing_sees_instances_as_flattened_copies():
    rock = _rock(6)
    a = render(_sea([rock], integrator="path"), samples=8, radiometer_samples=4096, seed=2, threads=2)
    b = render(_sea([rock.flattened()], integrator="path"), samples=8, radiometer_samples=4096, seed=2, threads=2)
    _same_but_for_rounding(a.images["diver"].mean, b.images["diver"].mean)


def test_a_mirrored_copy_faces_outwards():
    """One copy mirrored through x: the camera sees its outside (lit), as the flattened copy
    with its winding reversed; a copy turned inside out would be dark or see through."""
    m = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    x = np.zeros((1, 3, 4))
    x[0, :, :3] = _rotation((1.0, 2.0, 0.5), 0.7) @ np.diag([-1.5, 1.0, 1.0])
    x[0, :, 3] = (0.0, 0.0, -3.0)
    box = MeshObject("box", TriangleMesh(np.asarray(m.vertices), np.asarray(m.faces)), "rock", instances=x)
    a = render(_sea([box]), samples=8, radiometer_samples=1024, seed=3, threads=2)
    b = render(_sea([box.flattened()]), samples=8, radiometer_samples=1024, seed=3, threads=2)
    _same_but_for_rounding(a.images["diver"].mean, b.images["diver"].mean)


def test_instances_round_trip_through_the_scene_file(tmp_path):
    rock = _rock(3)
    scene = _sea([rock])
    again = Scene.from_dict(json.loads(json.dumps(scene.to_dict())))
    assert np.allclose(again.meshes[0].instances, rock.instances)
    # From a .npy file, (N, 4, 4) with last rows [0, 0, 0, 1].
    x4 = np.zeros((3, 4, 4))
    x4[:, :3] = rock.instances
    x4[:, 3, 3] = 1.0
    np.save(tmp_path / "rocks.npy", x4)
    d = scene.to_dict()
    d["meshes"][0]["instances"] = "rocks.npy"
    (tmp_path / "s.json").write_text(json.dumps(d))
    read = load_scene(tmp_path / "s.json")
    assert np.array_equal(read.meshes[0].instances, rock.instances)


@pytest.mark.parametrize("change, field, words", [
    (lambda x: x.__setitem__((2, 0, 3), np.nan), "instances[2]", "finite"),
    (lambda x: x.__setitem__((1, slice(None), slice(0, 3)), 0.0), "instances[1]", "singular"),
    (lambda x: x.__setitem__((0, 2, slice(0, 3)), (1e-12, 0, 0)), "instances[0]", "degenerate"),
    (lambda x: x.__setitem__((1, 0, 3), 1e9), "instances[1]", "coordinate limit"),
])
def test_bad_transforms_are_refused_naming_the_copy(change, field, words):
    rock = _rock(3)
    change(rock.instances)
    with pytest.raises(SceneError) as e:
        _sea([rock]).validate()
    assert "rocks" in str(e.value) and field in str(e.value) and words in str(e.value), str(e.value)


def test_instances_of_a_wrong_shape_are_refused():
    rock = _rock(2)
    rock.instances = np.zeros((2, 3, 3))
    with pytest.raises(SceneError, match=r"instances.*\(N, 3, 4\)"):
        _sea([rock]).validate()
    with pytest.raises(SceneError, match="instance file not found"):
        d = _sea([_rock(1)]).to_dict()
        d["meshes"][0]["instances"] = "missing.npy"
        Scene.from_dict(d)
