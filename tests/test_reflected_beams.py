"""The sun reflected by the water into the air, as beams (the hybrid integrator).

Light that the smooth water surface reflects onto walls, decks and objects above it (and into
radiometers in the air) was found by path tracing only when a path, after a diffuse bounce,
reflected on the water and escaped into the sun's 0.53 deg disk: rare samples thousands of
times the pixel's value (fireflies in the stepped pool). The hybrid integrator now carries it in
reflected beams, as it carries the refracted sun below the surface:

- over a flat smooth sea the mirror image of the sun, closed form: Eu above an absorbing sea is
  F(theta) E cos(theta);
- the same irradiances as path tracing under a large sun (where path tracing converges);
- flux: refracted plus reflected prisms carry all the sun on the water mesh's lit faces;
- rough seas keep their BSDF (no reflected beams: the glint is sampled there).
"""
import numpy as np
import pytest

from geometry import box
from photic import _core
from photic.compile import compile_scene
from photic.render import render
from photic.scene import Scene

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)


def mirror_sea(integrator="hybrid", diameter=0.53, zenith=40.0, plate=True, rough=False):
    """A flat sea that absorbs everything (a = 50 per m), black sky, a grey plate 1.5 m above it,
    Eu radiometers 1 m up beside and below the plate, a camera looking up at the plate."""
    v, t = box((-1, -1, 1.5), (1, 1, 1.52))
    surface = {"kind": "flat", "z": 0.0}
    if rough:
        surface["roughness"] = {"wind_speed": 5.0}
    d = {"photic_scene": 1, "name": "mirror",
         "materials": {"grey": {"type": "lambertian", "reflectance": [0.5]}},
         "meshes": [{"name": "plate", "material": "grey", "vertices": v, "triangles": t}] if plate else [],
         "water": [{"name": "sea", "type": "ocean", "surface": surface, "iops": {"absorption": [50.0]}}],
         "sun": {"zenith_deg": zenith, "azimuth_deg": 0.0, "irradiance": [1.0],
                 "angular_diameter_deg": diameter},
         "radiometers": [{"name": "Eu", "quantity": "Eu", "position": [3.0, 0.0, 1.0]},
                         {"name": "Eu_below_plate", "quantity": "Eu", "position": [0.0, 0.0, 1.0]}],
         "cameras": [{"name": "up", "type": "perspective", "position": [0.0, 0.0, 1.2],
                      "direction": [0, 0, 1], "up": [0, 1, 0], "fov_deg": 20, "resolution": [8, 8]}],
         "settings": {"integrator": integrator, "forward_cone_deg": 0}}
    return Scene.from_dict(d)


def test_mirror_image_of_the_sun_in_closed_form(zscore):
    """Eu above an absorbing flat sea is the reflected sun alone: F(theta) E cos(theta), in
    closed form per pass (the sun's disk only moves theta by its radius); under a plate the
    same (its beam comes from water the plate does not shade), and the plate's underside has
    radiance rho F E cos(theta) / pi (plus 0.2 % of light between plate and water)."""
    theta = np.radians(40.0)
    F = _core.fresnel(np.cos(theta), 1.0, 1.34)
    expected = F * np.cos(theta)
    res = render(mirror_sea(plate=False), samples=4, radiometer_samples=4096, seed=1, threads=2)
    for r in res.radiometers:
        assert float(r.mean[0, 0]) == pytest.approx(expected, rel=1e-3), r.name
    res = render(mirror_sea(), samples=16, radiometer_samples=1 << 14, seed=1, threads=2)
    for r in res.radiometers:
        z = zscore(f"{r.name} above a mirror sea (closed form)", float(r.mean[0, 0]), expected,
                   float(r.stderr[0, 0]) + 0.003 * expected)
        assert abs(z) < 4
    img = res.images["up"]
    assert float(np.mean(img.mean)) == pytest.approx(0.5 / np.pi * expected, rel=0.01)


def test_reflected_beams_equal_path_tracing_under_a_large_sun(zscore):
    """A 20 deg sun, where path tracing finds the sun after the reflection often enough to
    converge: Eu beside and below the plate and the plate's underside seen by the camera agree
    with the hybrid's reflected beams."""
    hyb = render(mirror_sea("hybrid", 20.0), samples=16, radiometer_samples=1 << 16, seed=2, threads=2)
    pt = render(mirror_sea("path", 20.0), samples=1024, radiometer_samples=1 << 21, seed=3, threads=2)
    for a, b in zip(hyb.radiometers, pt.radiometers):
        z = zscore(f"{a.name}: hybrid vs path (20 deg sun)", float(a.mean[0, 0]), float(b.mean[0, 0]),
                   float(np.hypot(a.stderr[0, 0], b.stderr[0, 0])))
        assert abs(z) < 4, a.name
        assert a.stderr[0, 0] < 0.2 * b.stderr[0, 0]  # the beams' estimate is far less noisy
    ia, ib = hyb.images["up"], pt.images["up"]
    se = np.hypot(np.sqrt(ia.variance.sum()), np.sqrt(ib.variance.sum())) / ia.variance.size
    z = zscore("plate underside: hybrid vs path (20 deg sun)", float(ia.mean.mean()), float(ib.mean.mean()), se)
    assert abs(z) < 4


def tank_with_canopy(integrator="hybrid", diameter=0.53):
    """A tank of dark water (a = 5 per m) 2 x 2 x 1 m on a dark floor, its top wavy (3 cm
    sinusoids), under a canopy 0.8 m above it; the sun at 40 deg. Eu radiometers just under the
    canopy, shaded from the sun, see mostly what the water reflects up: caustics of the
    reflected sun."""
    import trimesh

    # a closed water body 1 m deep whose top (z = 0, split finely) carries the waves
    water = trimesh.creation.box(extents=(2.0, 2.0, 1.0))
    water.apply_translation((0, 0, -0.5))
    water = water.subdivide().subdivide().subdivide().subdivide()
    v = water.vertices.copy()
    on_top = np.isclose(v[:, 2], 0.0)
    v[on_top, 2] = 0.03 * np.sin(2 * np.pi * v[on_top, 0] / 0.7) * np.cos(2 * np.pi * v[on_top, 1] / 0.9)
    fv, ft = box((-3.0, -3.0, -1.2), (3.0, 3.0, -1.0))
    cv, ct = box((-1.0, -1.0, 0.8), (0.2, 1.0, 0.82))
    d = {"photic_scene": 1, "name": "tank_canopy",
         "materials": {"grey": {"type": "lambertian", "reflectance": [0.6]},
                       "dark": {"type": "lambertian", "reflectance": [0.02]}},
         "meshes": [{"name": "floor", "material": "dark", "vertices": fv, "triangles": ft},
                    {"name": "canopy", "material": "grey", "vertices": cv, "triangles": ct}],
         "water": [{"name": "tank", "type": "mesh", "vertices": v.tolist(), "triangles": water.faces.tolist(),
                    "iops": {"absorption": [5.0], "b": [0.0], "phase": {"type": "isotropic"}}}],
         "sun": {"zenith_deg": 40.0, "azimuth_deg": 0.0, "irradiance": [1.0], "angular_diameter_deg": diameter},
         "radiometers": [{"name": f"Eu_{k}", "quantity": "Eu", "position": [x, y, 0.75]}
                         for k, (x, y) in enumerate([(-0.6, 0.0), (-0.2, 0.4), (-0.8, -0.5)])],
         "settings": {"integrator": integrator, "forward_cone_deg": 0}}
    return Scene.from_dict(d)


@pytest.mark.slow  # about a minute
def test_caustics_reflected_under_a_canopy_equal_path_tracing(zscore):
    """Eu under the canopy (the wavy water's reflected caustics, the light it lets back out)
    from the hybrid's reflected beams equals path tracing's under a 20 deg sun, and the beams'
    part is most of it."""
    # (many passes: with a 20 deg sun the caustic at a point changes wildly between passes)
    hyb = render(tank_with_canopy("hybrid", 20.0), radiometer_samples=1 << 18, seed=4, threads=2)
    pt = render(tank_with_canopy("path", 20.0), radiometer_samples=1 << 20, seed=5, threads=2)
    for a, b in zip(hyb.radiometers, pt.radiometers):
        z = zscore(f"{a.name} under a canopy: hybrid vs path (20 deg sun)", float(a.mean[0, 0]),
                   float(b.mean[0, 0]), float(np.hypot(a.stderr[0, 0], b.stderr[0, 0])))
        assert abs(z) < 4, a.name
        direct = float(a.components["beam_direct"][0][0, 0])
        assert direct > 0.5 * float(a.mean[0, 0]), (a.name, direct, float(a.mean[0, 0]))


def test_reflected_and_refracted_prisms_carry_the_sun_on_the_water():
    """Over the tank's lit faces the refracted prisms carry (1 - F) and the reflected ones F of
    the sun's flux: together all of it (E cos A summed over the lit faces)."""
    sc = tank_with_canopy()
    sc.meshes = [m for m in sc.meshes if m.name != "canopy"]  # (its shadow would take flux)
    core = compile_scene(sc, hybrid=True, forward_cone_deg=0.0)
    s = np.asarray(sc.sun.direction)
    core.build_beams(tuple(s), 0)
    assert core.has_air_beams and core.air_beam_count > 0
    w = sc.water[0].mesh
    tri = w.vertices[w.triangles]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) / 2  # area-weighted outward normals
    cos_a = nrm @ s
    incident = 1.0 * float(np.sum(cos_a[cos_a > 0]))  # irradiance 1 normal to the sun
    total = core.beam_total_flux() + core.air_beam_total_flux()
    assert total == pytest.approx(incident, rel=2e-3)
    assert 0.01 < core.air_beam_total_flux() / total < 0.1


def test_rough_seas_keep_their_bsdf():
    """A rough sea's reflection is sampled by its microfacet BSDF (glint by next-event
    estimation): no reflected beams there."""
    core = compile_scene(mirror_sea(rough=True), hybrid=True, forward_cone_deg=0.0)
    core.build_beams(tuple(mirror_sea(rough=True).sun.direction), 0)
    assert not core.has_air_beams
    core = compile_scene(mirror_sea(), hybrid=True, forward_cone_deg=0.0)
    core.build_beams(tuple(mirror_sea().sun.direction), 0)
    assert core.has_air_beams
