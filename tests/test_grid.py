"""3-D IOP grids (an 'iop_grid': base IOPs plus a per-voxel density times unit IOPs over a
box): a constant grid is homogeneous water, a horizontal slab is a two-layer profile, a
stratified column given as a grid equals the same 'iop_profile'; the scene format and its
errors. Fixed seeds; z-scores recorded."""
import json
import math

import numpy as np
import pytest

from photic.render import render
from photic.scene import IOPGrid, Scene, SceneError

pytestmark = pytest.mark.gate  # the physics gate (tests/test_gate.py)

N_W = 1.34
Z_MAX = 3.0

HG = {"type": "henyey_greenstein", "g": 0.85}
WATER = {"type": "pure_water"}
BOX = ([-500.0, -500.0, -40.0], [1000.0, 1000.0, 42.0])  # origin, size: z from -40 to +2 m
SUN = {"zenith_deg": 30.0, "azimuth_deg": 60.0, "irradiance": [1.0]}
SKY = {"type": "uniform", "radiance": [0.3]}


def mixture(a, b_particles, b_water):
    return {"absorption": [a], "scattering": [{"b": [b_particles], "phase": HG},
                                              {"b": [b_water], "phase": WATER}]}


def add(x, y, s=1.0):
    """The IOPs x + s y (same components)."""
    return mixture(x["absorption"][0] + s * y["absorption"][0],
                   *[c["b"][0] + s * d["b"][0] for c, d in zip(x["scattering"], y["scattering"])])


def sea(radiometers, *, iops=None, profile=None, grid=None, integrator="hybrid", seed=1):
    water = {"name": "sea", "type": "ocean", "ior": N_W, "surface": {"kind": "flat", "z": 0.0}}
    if iops is not None:
        water["iops"] = iops
    elif profile is not None:
        water["iop_profile"] = {"z_top": list(profile[0]),
                                "layers": [{"iops": x} for x in profile[1]]}
    else:
        water["iop_grid"] = grid
    d = {"photic_scene": 1, "name": "grid", "water": [water], "sky": SKY,
         "radiometers": list(radiometers),
         "settings": {"integrator": integrator, "seed": seed, "forward_cone_deg": 0.0}}
    if integrator == "hybrid":
        d["sun"] = SUN
    return Scene.from_dict(d)


def grid(base, unit, density, box=BOX):
    return {"base": {"iops": base}, "unit": {"iops": unit}, "origin": box[0], "size": box[1],
            "density": np.asarray(density, dtype=float).tolist()}


def rad(q, z):
    return {"name": f"{q}_{z:g}", "quantity": q, "position": [0.3, -0.2, -z]}


RADS = [rad(q, z) for z in (1.0, 3.0, 6.0) for q in ("Ed", "Eu", "Eo")]
N = {"hybrid": 20_000, "path": 40_000}


def compare(zscore, label, a, b):
    for r in a.radiometers:
        o = b.radiometer(r.name)
        se = float(np.hypot(r.stderr[0, 0], o.stderr[0, 0]))
        assert abs(zscore(f"{label} {r.name}", o.mean[0, 0], r.mean[0, 0], se)) < Z_MAX


@pytest.mark.parametrize("integrator", ["hybrid", "path"])
def test_constant_grid_is_homogeneous_water(zscore, integrator):
    """Density 1 in every voxel of a box holding the lit column (to 40 m): base + unit
    everywhere, against homogeneous water with those IOPs (other seed, within errors)."""
    base, unit = mixture(0.05, 0.1, 0.02), mixture(0.1, 0.2, 0.03)
    homog = render(sea(RADS, iops=add(base, unit), integrator=integrator, seed=51),
                   radiometer_samples=N[integrator])
    g = render(sea(RADS, grid=grid(base, unit, np.ones((3, 2, 5))), integrator=integrator,
                   seed=52), radiometer_samples=N[integrator])
    compare(zscore, f"{integrator} constant grid", homog, g)


def test_grid_renders_are_bit_identical_on_any_thread_count():
    """The grid and the beams' shadow map are built in slabs of bricks on the render's threads:
    a sparse scattering plume (several bricks, partial ones at the far faces) rendered on 1, 2
    and 3 threads gives the same numbers, bit for bit (hybrid: the map is used)."""
    rho = _sparse_field()
    box = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])  # (the top above the surface)
    sc = sea(RADS, grid=grid(mixture(0.05, 0.1, 0.02), mixture(0.3, 1.5, 0.0), rho, box), seed=5)
    runs = [render(sc, radiometer_samples=3000, threads=t) for t in (1, 2, 3)]
    assert runs[0].radiometers[0].mean.any()
    for other in runs[1:]:
        for r1, r2 in zip(runs[0].radiometers, other.radiometers):
            assert np.array_equal(r1.mean, r2.mean) and np.array_equal(r1.stderr, r2.stderr)


@pytest.mark.parametrize("integrator", ["hybrid", "path"])
def test_horizontal_slab_is_a_two_layer_profile(zscore, integrator):
    """Density 1 in the voxels below z = -2 m (cells 2 m high) and 0 above: the two-layer
    profile (base above, base + unit below), within errors."""
    base, unit = mixture(0.08, 0.15, 0.03), mixture(0.2, 0.8, 0.0)
    rho = np.zeros((2, 2, 21))
    rho[:, :, :19] = 1.0
    prof = render(sea(RADS, profile=([0.0, -2.0], [base, add(base, unit)]), integrator=integrator,
                      seed=61), radiometer_samples=N[integrator])
    g = render(sea(RADS, grid=grid(base, unit, rho), integrator=integrator, seed=62),
               radiometer_samples=N[integrator])
    compare(zscore, f"{integrator} slab grid", prof, g)


@pytest.mark.parametrize("integrator", ["hybrid", "path"])
def test_grid_over_a_depth_profile(zscore, integrator):
    """A grid on top of a two-layer base (tops 0 and -3.5 m): a slab of density 1 from 2 to
    5 m deep, across the base's boundary, equals the four-layer profile base | base + unit |
    lower base + unit | lower base, within errors (Ed, Eu, Eo at 1, 3, 6 m)."""
    top, low, unit = mixture(0.06, 0.1, 0.03), mixture(0.15, 0.5, 0.03), mixture(0.2, 0.8, 0.0)
    z = -40.0 + (np.arange(42) + 0.5)   # cell centres of the 1 m cells from -40 to +2 m
    rho = np.broadcast_to(np.where((z < -2.0) & (z > -5.0), 1.0, 0.0), (2, 2, 42))
    g = grid(top, unit, rho)
    g["base"] = {"iop_profile": {"z_top": [0.0, -3.5], "layers": [{"iops": top}, {"iops": low}]}}
    prof = render(sea(RADS, profile=([0.0, -2.0, -3.5, -5.0], [top, add(top, unit), add(low, unit), low]),
                      integrator=integrator, seed=81), radiometer_samples=N[integrator])
    gr = render(sea(RADS, grid=g, integrator=integrator, seed=82), radiometer_samples=N[integrator])
    compare(zscore, f"{integrator} grid over profile", prof, gr)


def test_stratified_column_as_grid_and_profile(zscore):
    """A clear top, a turbid layer (1.5-4 m) and moderately turbid water below, as an
    iop_profile and as a grid (0.5 m cells, densities 0, 1, 0.3; the box reaching 40 m):
    Ed, Eu, Eo at 1, 3 and 6 m agree within errors (hybrid, sun and sky)."""
    base, unit = mixture(0.06, 0.1, 0.03), mixture(0.25, 1.0, 0.0)
    box = ([-20.0, -20.0, -40.0], [40.0, 40.0, 40.0])
    z = -40.0 + 0.5 * (np.arange(80) + 0.5)   # cell centres
    rho = np.where(z > -1.5, 0.0, np.where(z > -4.0, 1.0, 0.3))
    rho = np.broadcast_to(rho, (4, 4, 80))
    layers = [base, add(base, unit), add(base, unit, 0.3)]
    prof = render(sea(RADS, profile=([0.0, -1.5, -4.0], layers), seed=71), radiometer_samples=30_000)
    g = render(sea(RADS, grid=grid(base, unit, rho, box), seed=72), radiometer_samples=30_000)
    compare(zscore, "column grid vs profile", prof, g)


def test_case1_chlorophyll_maximum_as_profile_and_grid_and_gershun(zscore):
    """A Case-1 column with a Gaussian chlorophyll maximum (0.2 mg m^-3 background, +2 at 4 m,
    width 1 m), at 440 nm where the classic model needs no a*_c table (a*_c(440) / a*_c(440) = 1):
    pure sea water plus particles and co-varying CDOM, a_p = 0.072 C^0.65 and b_p = 0.375 C^0.65
    (the classic b_p = 0.30 C^0.62 (550/440), with C's exponent taken as absorption's: one
    density field scales a and b together), as 0.25-m layers of an iop_profile and as the
    same 0.25-m voxels of a grid. Hybrid, sun and sky:
    - Ed, Eu, Eo at 1, 3 and 6 m from the profile and from the grid agree within errors;
    - Gershun's law holds across the maximum in the grid render, with the local absorption:
      (Ed - Eu)(3 m) - (Ed - Eu)(5 m) = sum over the 8 layers of a_i int Eo dz (Eo at the
      layers' midpoints; the midpoint rule's error ~ (K h)^2 / 24 < 1e-3)."""
    from photic.iop_models import SpectralTable, case1_classic, pure_water
    from photic.profiles import gaussian_chlorophyll
    band = [(440.0, 1.0)]  # (centre, width) nm
    flat = SpectralTable("a*_c normalised at 440 nm", [430.0, 450.0], a_star=[1.0, 1.0])
    water = pure_water(band)
    a_w, b_w = float(water.absorption[0]), float(sum(c.b[0] for c in water.scattering))
    unit_model = case1_classic(band, 1.0, flat)   # C = 1: the unit of C^0.65
    a_unit, b_unit = float(unit_model.absorption[0]), float(unit_model.scattering[0].b[0])
    assert a_unit == pytest.approx(0.072, rel=1e-4) and b_unit == pytest.approx(0.375, rel=1e-4)
    chl = gaussian_chlorophyll(background=0.2, peak=2.0, z_max=-4.0, width=1.0)
    h, n = 0.25, 160                     # 0.25-m layers / voxels from 0 to 40 m
    tops = -h * np.arange(n)
    fine = (np.arange(64) + 0.5) / 64
    rho = np.array([np.mean([chl(t - h * f) ** 0.65 for f in fine]) for t in tops])
    base = mixture(a_w, 0.0, b_w)
    unit = mixture(a_unit, b_unit, 0.0)
    layers = [add(base, unit, r) for r in rho] + [base]   # below 40 m: the grid's outside
    # density[0, 0, k]: k counts up from the box's bottom at 40 m
    g = grid(base, unit, rho[::-1].reshape(1, 1, n), ([-500.0, -500.0, -40.0], [1000.0, 1000.0, 40.0]))
    mids = 3.0 + h * (np.arange(8) + 0.5)
    rads = RADS + [rad("Ed", 5.0), rad("Eu", 5.0)] + [rad("Eo", z) for z in mids]
    samples = 40_000
    prof = render(sea(rads, profile=(list(tops) + [-40.0], layers), seed=91), radiometer_samples=samples)
    grd = render(sea(rads, grid=g, seed=92), radiometer_samples=samples)
    for r in RADS:
        a, b = prof.radiometer(r["name"]), grd.radiometer(r["name"])
        se = float(np.hypot(a.stderr[0, 0], b.stderr[0, 0]))
        assert abs(zscore(f"case-1 column grid vs profile {r['name']}", b.mean[0, 0], a.mean[0, 0], se)) < Z_MAX
    val = lambda name: (grd.radiometer(name).mean[0, 0], grd.radiometer(name).stderr[0, 0])
    (ed3, s1), (eu3, s2), (ed5, s3), (eu5, s4) = (val(x) for x in ("Ed_3", "Eu_3", "Ed_5", "Eu_5"))
    lhs = (ed3 - eu3) - (ed5 - eu5)
    a_local = a_w + a_unit * rho[12:20]                    # the layers from 3 to 5 m
    eo = np.array([val(f"Eo_{z:g}") for z in mids])
    rhs = float(np.sum(a_local * h * eo[:, 0]))
    se = math.sqrt(s1 ** 2 + s2 ** 2 + s3 ** 2 + s4 ** 2 + float(np.sum((a_local * h * eo[:, 1]) ** 2)))
    assert abs(zscore("case-1 column Gershun 3-5 m (grid)", lhs, rhs, se)) < Z_MAX
    assert se / rhs < 0.1
    # The background's absorption alone misses: the test sees the maximum.
    assert abs(lhs - (a_w + a_unit * 0.2 ** 0.65) * h * eo[:, 0].sum()) > 3 * se


# --------------------------------------------------------------------------------------
# The scene format
# --------------------------------------------------------------------------------------

def test_grid_from_npz_round_trips(tmp_path):
    """Densities read from a .npz next to the scene file; the saved scene refers to the file
    and reads back equal; density_at looks up voxels (0 outside the box)."""
    base, unit = mixture(0.05, 0.1, 0.02), mixture(0.1, 0.2, 0.03)
    rho = np.random.default_rng(1).random((5, 4, 3)).astype(np.float32)
    np.savez(tmp_path / "plume.npz", density=rho)
    g = grid(base, unit, rho)
    del g["density"]
    g["file"] = "plume.npz"
    d = sea([rad("Ed", 1.0)], iops=base).to_dict()
    del d["water"][0]["iops"]
    d["water"][0]["iop_grid"] = g
    sc = Scene.from_dict(d, base_dir=tmp_path)
    w = sc.water[0].iops
    assert isinstance(w, IOPGrid) and w.density.shape == (5, 4, 3)
    np.testing.assert_array_equal(w.density, rho)
    assert w.density_at([-499.0, -499.0, -39.0]) == pytest.approx(float(rho[0, 0, 0]))
    assert w.density_at([0.0, 0.0, 5.0]) == 0.0
    saved = sc.to_dict()
    assert "density" not in saved["water"][0]["iop_grid"]
    assert Scene.from_dict(json.loads(json.dumps(saved))) == sc
    assert render(sc, radiometer_samples=2_000).radiometer("Ed_1").mean[0, 0] > 0


# --------------------------------------------------------------------------------------
# b = 0: Beer-Lambert along a slanted ray through a 3-D field (the DDA)
# --------------------------------------------------------------------------------------

def _sparse_field():
    """37 x 29 x 45 voxels (several bricks of 8^3, partial ones at the far faces): random
    densities in two blobs, zero elsewhere, so that rays cross empty bricks, non-empty ones
    and the clear water around the non-empty voxels' box."""
    rng = np.random.default_rng(11)
    rho = rng.random((37, 29, 45)) * 2.0
    i, j, k = np.meshgrid(*(np.arange(n) for n in rho.shape), indexing="ij")
    blob1 = (i - 10) ** 2 + (j - 8) ** 2 + ((k - 30) / 1.5) ** 2 < 60
    blob2 = (abs(i - 27) < 6) & (abs(j - 20) < 5) & (abs(k - 12) < 10)
    rho[~(blob1 | blob2)] = 0.0
    return rho


def _thin_field():
    """12 x 10 x 96 random densities (a tenth of them zero) in voxels 16-26 times thinner along
    z than across: most rays cross runs of z voxels between x and y faces, which the walk sums
    in one go."""
    rng = np.random.default_rng(12)
    rho = rng.random((12, 10, 96)) * 2.0
    rho[rng.random(rho.shape) < 0.1] = 0.0
    return rho


def absorbing_grid(rho, box, base_profile=None) -> dict:
    """A sunlit sea with b = 0 whose absorption is 0.05 + 0.3 rho per metre over the box
    (as a scene dict, one radiometer to replace); ``base_profile`` = (z_top, a per layer):
    the base a depth profile instead of 0.05."""
    d = sea([rad("Ed", 1.0)], iops=mixture(0.05, 0.0, 0.0)).to_dict()
    del d["water"][0]["iops"]
    d["water"][0]["iop_grid"] = grid(mixture(0.05, 0.0, 0.0), mixture(0.3, 0.0, 0.0), rho, box)
    if base_profile is not None:
        d["water"][0]["iop_grid"]["base"] = {"iop_profile": {
            "z_top": list(base_profile[0]),
            "layers": [{"iops": mixture(a, 0.0, 0.0)} for a in base_profile[1]]}}
    return d


def _layered_depth(z, z_top, a):
    """int a dz from height z (< 0) up to the surface through layers with tops z_top."""
    tops = list(z_top) + [-np.inf]
    return sum(ai * max(0.0, min(tops[i], 0.0) - max(tops[i + 1], z)) for i, ai in enumerate(a))


def _exact_integral(rho, lo, size, p0, p1):
    """int rho dl from p0 to p1 in numpy: the segment cut at every voxel face it crosses (the
    densities as the core stores them, float32)."""
    rho = np.asarray(rho, dtype=np.float32).astype(np.float64)
    lo, size, p0, p1 = (np.asarray(x, dtype=float) for x in (lo, size, p0, p1))
    n = np.asarray(rho.shape)
    cell = size / n
    length = float(np.linalg.norm(p1 - p0))
    d = (p1 - p0) / length
    cuts = [0.0, length]
    for a in range(3):
        if d[a] != 0.0:
            t = (lo[a] + np.arange(n[a] + 1) * cell[a] - p0[a]) / d[a]
            cuts.extend(t[(t > 0.0) & (t < length)])
    t = np.unique(cuts)
    mid = p0 + np.outer(0.5 * (t[:-1] + t[1:]), d)
    q = np.floor((mid - lo) / cell).astype(int)
    ok = np.all((q >= 0) & (q < n), axis=1)
    dens = np.zeros(len(mid))
    dens[ok] = rho[tuple(q[ok].T)]
    return float(np.sum(dens * np.diff(t)))


def _large_field():
    """128 x 128 x 64 random densities (a tenth zero): 4 MB of bricks, which the core keeps in
    2 MB pages (where the system gives them) rather than 4 kB ones."""
    rng = np.random.default_rng(13)
    rho = rng.random((128, 128, 64), dtype=np.float32) * 2.0
    rho[rng.random(rho.shape) < 0.1] = 0.0
    return rho


@pytest.mark.parametrize("field", ["sparse 37x29x45", "one voxel", "full 9x8x17", "thin 12x10x96",
                                   "large 128x128x64"])
def test_grid_walk_equals_exact_integral(field):
    """The voxel walk (one DDA with empty bricks crossed in a jump and runs along z summed in
    one go) against numpy: 600 random segments starting and ending inside, outside and across
    the box, some along axes and voxel faces, through partial bricks at the far faces;
    relative error < 1e-9."""
    from photic.compile import compile_scene
    rng = np.random.default_rng(3)
    rho = {"sparse 37x29x45": _sparse_field, "one voxel": lambda: np.ones((1, 1, 1)),
           "full 9x8x17": lambda: rng.random((9, 8, 17)) + 0.1, "thin 12x10x96": _thin_field,
           "large 128x128x64": _large_field}[field]()
    box = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])
    d = absorbing_grid(rho, box)
    core = compile_scene(Scene.from_dict(d))
    lo, size = np.array(box[0]), np.array(box[1])
    cell = size / np.array(rho.shape)
    segments = []
    for i in range(600):
        p0 = lo - 0.3 * size + rng.random(3) * 1.6 * size
        p1 = lo - 0.3 * size + rng.random(3) * 1.6 * size
        if i % 5 == 1:    # along an axis
            p1 = p0.copy()
            p1[i % 3] += (rng.random() - 0.5) * 3 * size[i % 3]
        elif i % 5 == 2:  # in a plane of voxel faces
            a = i % 3
            p0[a] = p1[a] = lo[a] + rng.integers(0, rho.shape[a] + 1) * cell[a]
        elif i % 5 == 3:  # short, inside
            p1 = p0 + (rng.random(3) - 0.5) * cell * 3
        segments.append((p0, p1))
    crossed = 0
    for p0, p1 in segments:
        ref = _exact_integral(rho, lo, size, p0, p1)
        (got,) = core.grid_integral(0, p0.tolist(), p1.tolist())
        crossed += ref > 0
        # along a plane of voxel faces either neighbour's density is right
        assert got == pytest.approx(ref, rel=1e-9, abs=1e-12) or _on_face(p0, p1, lo, cell), (p0, p1, got, ref)
    assert crossed > 80


@pytest.mark.parametrize("field", ["sparse 37x29x45", "one voxel"])
def test_grid_density_lookup(field):
    """The density at a point (the beam terms' local scattering), which answers 0 without
    touching the bricks outside the non-empty voxels' box and in empty bricks: 4000 points in,
    around and outside the box, and the centres of all non-zero voxels, against numpy."""
    from photic.compile import compile_scene
    rng = np.random.default_rng(5)
    rho = {"sparse 37x29x45": _sparse_field, "one voxel": lambda: np.ones((1, 1, 1))}[field]()
    box = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])
    core = compile_scene(Scene.from_dict(absorbing_grid(rho, box)))
    lo, size = np.array(box[0]), np.array(box[1])
    n = np.array(rho.shape)
    cell = size / n
    pts = lo - 0.2 * size + rng.random((4000, 3)) * 1.4 * size
    centres = lo + (np.argwhere(rho > 0) + 0.5) * cell
    for p in np.concatenate([pts, centres]):
        q = np.floor((p - lo) / cell).astype(int)
        inside = np.all((p >= lo) & (p <= lo + size))
        ref = float(np.float32(rho[tuple(np.minimum(q, n - 1))])) if inside else 0.0
        assert core.grid_density(0, p.tolist()) == [ref], (p, ref)
    assert sum(core.grid_density(0, p.tolist())[0] > 0 for p in pts) > 100 or field == "one voxel"


@pytest.mark.parametrize("field", ["sparse 37x29x45", "thin 12x10x96"])
def test_regular_tracking_inverts_the_optical_depth_exactly(field):
    """Cursor::march (the free paths in gridded water) against numpy: along 300 random rays
    through the field, the position where the optical depth of s0 + s1 rho reaches xi
    (xi ~ Exp(1), some beyond t_stop): the depth up to it equals xi to 1e-9, the density there
    is the voxel's, and a march stopped at t_stop reports the depth left (in the thin voxels
    also where xi is reached within a run along z)."""
    from photic.compile import compile_scene
    rng = np.random.default_rng(8)
    rho = {"sparse 37x29x45": _sparse_field, "thin 12x10x96": _thin_field}[field]()
    box = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])
    d = absorbing_grid(rho, box)
    core = compile_scene(Scene.from_dict(d))
    lo, size = np.array(box[0]), np.array(box[1])
    g = Scene.from_dict(d).water[0].iops
    reached = stopped = 0
    for _ in range(300):
        o = lo + rng.random(3) * size
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        s0, s1 = (0.0, 2.0) if rng.random() < 0.3 else (0.4, 1.5)
        xi = rng.exponential()
        t_stop = 0.5 + 6.0 * rng.random()
        hit, t, (rho_at,), (integral,), left = core.grid_march(0, o.tolist(), u.tolist(), s0, [s1], xi, t_stop)
        r = _exact_integral(rho, lo, size, o, o + u * t) if t > 0 else 0.0
        assert integral == pytest.approx(r, rel=1e-9, abs=1e-12)
        depth = s0 * t + s1 * r
        if hit:
            reached += 1
            assert t <= t_stop * (1 + 1e-12) and depth == pytest.approx(xi, rel=1e-9, abs=1e-12)
            assert rho_at == pytest.approx(g.density_at(o + u * (t - 1e-9)), rel=1e-6, abs=1e-12)
        else:
            stopped += 1
            assert t == pytest.approx(t_stop, rel=1e-12)
            assert left == pytest.approx(xi - depth, rel=1e-9, abs=1e-12) and left >= 0
    assert reached > 40 and stopped > 40


def _stratified_columns():
    """24 x 20 x 160 voxels 8-15 times thinner along z than across, densities in a band of
    heights (the columns' span starts above the grid's bottom) over half the columns, some
    columns empty and some voxels zero inside: the column walk's prefix sums."""
    rng = np.random.default_rng(14)
    rho = rng.random((24, 20, 160)) * 2.0
    rho[:, :, :37] = 0.0
    rho[:, :, 141:] = 0.0
    rho[rng.random(rho.shape) < 0.15] = 0.0
    rho[rng.random((24, 20)) < 0.5] = 0.0
    return rho


@pytest.mark.parametrize("field", ["stratified columns 24x20x160", "thin 12x10x96", "sparse 37x29x45"])
def test_walks_by_columns_and_by_voxels_agree_with_numpy(field):
    """One walk, as the integrators take it, against numpy: along 400 random rays (half within
    35 degrees of vertical, which cross several voxels along z per column and are walked by
    the columns' prefix sums; a quarter within 3 degrees of the horizontal, walked voxel by
    voxel; a quarter in any direction), steps in turn of reading the
    integral at a distance and of tracking to a sampled depth (s0 + s1 rho, xi ~ Exp(1)),
    each continuing where the last stopped: every integral to 1e-9, every depth reached to
    1e-9, the density at a collision the voxel's."""
    from photic.compile import compile_scene
    rng = np.random.default_rng(21)
    rho = {"stratified columns 24x20x160": _stratified_columns, "thin 12x10x96": _thin_field,
           "sparse 37x29x45": _sparse_field}[field]()
    box = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])
    d = absorbing_grid(rho, box)
    core = compile_scene(Scene.from_dict(d))
    g = Scene.from_dict(d).water[0].iops
    lo, size = np.array(box[0]), np.array(box[1])
    modes = {True: 0, False: 0}
    hits = 0
    for r in range(400):
        o = lo - 0.2 * size + rng.random(3) * 1.4 * size
        if r % 4 == 1:
            u = rng.normal(size=3)
        elif r % 4 == 3:  # within 3 degrees of the horizontal
            u = np.array([*rng.normal(size=2), 0.0])
            u[2] = np.linalg.norm(u) * np.tan(np.radians(3.0)) * (2 * rng.random() - 1)
        else:  # steep: within 35 degrees of the vertical, up or down
            th, ph = np.radians(35.0) * np.sqrt(rng.random()), 2 * np.pi * rng.random()
            u = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th) * rng.choice([-1, 1])])
        u /= np.linalg.norm(u)
        s0, s1 = (0.0, 2.0) if rng.random() < 0.3 else (0.3, 1.5)
        steps, t = [], 0.0
        for _ in range(5):
            t += 3.0 * rng.random()
            steps.append((-1.0, t) if rng.random() < 0.4 else (rng.exponential(), t))
        by_columns, out = core.grid_walk(0, o.tolist(), u.tolist(), s0, [s1], steps)
        modes[by_columns] += 1
        pos = 0.0
        for (xi, t_stop), (hit, t, (rho_at,), (integral,), left) in zip(steps, out):
            ref = _exact_integral(rho, lo, size, o, o + u * t) if t > 0 else 0.0
            assert integral == pytest.approx(ref, rel=1e-9, abs=1e-12), (field, by_columns, o, u, t)
            if xi < 0:  # a read: the position moves on to t_stop (or stays if beyond it)
                assert t == pytest.approx(max(pos, t_stop), rel=1e-12)
            else:
                r_pos = _exact_integral(rho, lo, size, o, o + u * pos) if pos > 0 else 0.0
                depth = s0 * (t - pos) + s1 * (ref - r_pos)
                if hit:
                    hits += 1
                    assert depth == pytest.approx(xi, rel=1e-9, abs=1e-12), (field, by_columns, o, u)
                    assert rho_at == pytest.approx(g.density_at(o + u * (t - 1e-9)), rel=1e-6, abs=1e-12)
                elif t_stop > pos:
                    assert t == pytest.approx(t_stop, rel=1e-12)
                    assert left == pytest.approx(xi - depth, rel=1e-9, abs=1e-12) and left >= 0
            pos = t
    assert hits > 100
    if field != "sparse 37x29x45":  # (cube-like voxels: few rays steep enough for columns)
        assert modes[True] > 150 and modes[False] > 80, modes


def _on_face(p0, p1, lo, cell):
    """Both ends on one plane of voxel faces (the density there is either side's)."""
    for a in range(3):
        k0, k1 = (p0[a] - lo[a]) / cell[a], (p1[a] - lo[a]) / cell[a]
        if abs(k0 - round(k0)) < 1e-9 and abs(k1 - round(k1)) < 1e-9 and round(k0) == round(k1):
            return True
    return False


SMALL_SUN = 0.002


LAYERED_BASE = ([0.0, -1.7, -3.1], [0.05, 0.4, 0.15])  # a depth profile under the grid


@pytest.mark.parametrize("field", ["dense 4x5x6", "sparse 37x29x45", "dense 4x5x6 over layers",
                                   "dense 4x5x6 at optical depths of 30 and more"])
def test_sun_through_absorbing_3d_field(field):
    """A small sun (0.002 deg) at 35 deg, b = 0, random absorbing densities (in 4 x 5 x 6
    voxels, or sparse in several bricks; or over a base of three absorbing layers; or 80 times
    denser: optical depths 36 to 56, Ed 1e-18 to 1e-27): Ed at three points equals the disk
    quadrature with the optical depth integrated in numpy along the refracted ray (cut at every
    voxel face; the layers' in closed form), to 1e-3 (a deterministic estimate: no scattering,
    one refracted path per sample)."""
    import math
    from test_stratified import refracted_sun
    rho = np.random.default_rng(7).random((4, 5, 6)) * 2.0 if field.startswith("dense") else _sparse_field()
    if field.endswith("and more"):
        rho *= 80.0
    box = ([-1.5, -2.0, -4.0], [3.0, 4.0, 4.2])   # the top above the surface
    layered = field.endswith("over layers")
    d = absorbing_grid(rho, box, LAYERED_BASE if layered else None)
    points = [(0.3, -0.2, -1.0), (-0.5, 0.7, -2.5), (0.9, 0.1, -3.7)]
    if field.startswith("sparse"):  # rays through either blob, one through neither, and more
        rng = np.random.default_rng(5)  # (bricks whose sunward rays miss every blob need no walk)
        points = [(-1.0, -1.1, -1.5), (0.5, 1.2, -3.0), (-1.2, 0.0, -3.9)] + [
            tuple(p) for p in np.column_stack([rng.uniform(-1.4, 1.4, 40), rng.uniform(-1.9, 1.9, 40),
                                               rng.uniform(-3.95, -0.05, 40)])]
    d["radiometers"] = [{"name": f"Ed_{i}", "quantity": "Ed", "position": list(p)}
                        for i, p in enumerate(points)]
    # a sun of 0.002 deg: its rays to a point spread by 0.1 mm over 5 m, so that a point whose
    # ray grazes a voxel's edge sees one optical depth (the passes draw a few directions)
    d["sun"] = {"zenith_deg": 35.0, "azimuth_deg": 20.0, "irradiance": [1.0],
                "angular_diameter_deg": SMALL_SUN}
    d["sky"] = {"type": "black"}
    sc = Scene.from_dict(d)
    res = render(sc, radiometer_samples=4_000)
    g = sc.water[0].iops
    sin_w = math.sin(math.radians(35.0)) / N_W
    mu_w = math.sqrt(1 - sin_w ** 2)
    phi = math.radians(20.0)
    up = np.array([sin_w * math.cos(phi), sin_w * math.sin(phi), mu_w])  # towards the sun
    for i, p in enumerate(points):
        length = -p[2] / mu_w
        dens = _exact_integral(rho, box[0], box[1], np.asarray(p), np.asarray(p) + up * length) / length
        # the vertical-depth form of refracted_sun: tau_vertical = tau_along_ray * mu_w
        tau = (0.05 + 0.3 * dens) * length * mu_w
        if layered:
            tau = _layered_depth(p[2], *LAYERED_BASE) + 0.3 * dens * length * mu_w
        ref = refracted_sun(35.0, tau, diameter_deg=SMALL_SUN)
        if field.endswith("and more"):
            assert tau > 30.0 and ref > 0.0, (tau, ref)
        if field.startswith("sparse") and i < 2:
            assert dens > 0.2  # the ray does cross a blob
        r = res.radiometer(f"Ed_{i}")
        assert abs(r.mean[0, 0] / ref - 1) < 1e-3  # deterministic: the reference's quadrature


@pytest.mark.parametrize("azimuth,diameter", [(0.0, SMALL_SUN), (90.0, SMALL_SUN), (225.0, SMALL_SUN),
                                               (135.0, 0.53)])
def test_slanted_sun_shadow_of_a_thin_slab(azimuth, diameter):
    """A low sun (70 deg; 44.5 deg in water) over a thin absorbing slab 0.5 m thick near the
    surface, points 3 m below and up to 3 bricks away sideways: the sunward rays reach the slab
    through the sides of empty bricks (the bricks that need a walk are found per beam, and kept
    over the passes' directions in the sun's disk), Ed to 1e-3 of the numpy optical depth; the
    points in its shadow (0.1 m and more from its edges) and beside it."""
    from test_stratified import refracted_sun
    rho = np.zeros((64, 64, 32))
    rho[30:34, 30:34, 24:28] = 2.0  # x, y in [-0.5, 0.5], z in [-1.0, -0.5]
    box = ([-8.0, -8.0, -4.0], [16.0, 16.0, 4.0])
    d = absorbing_grid(rho, box)
    sin_w = math.sin(math.radians(70.0)) / N_W
    mu_w = math.sqrt(1 - sin_w ** 2)
    phi = math.radians(azimuth)
    up = np.array([sin_w * math.cos(phi), sin_w * math.sin(phi), mu_w])
    # points whose rays cross the slab's centre (and 0.4 m to either side) from 3.5 m deep
    reach = (3.5 - 0.75) / mu_w
    centre = np.array([0.0, 0.0, -0.75]) - up * reach
    side = np.array([-math.sin(phi), math.cos(phi), 0.0])
    points = [centre + side * s for s in (-0.8, -0.4, 0.0, 0.4, 0.8)]
    d["radiometers"] = [{"name": f"Ed_{i}", "quantity": "Ed", "position": list(p)}
                        for i, p in enumerate(points)]
    d["sun"] = {"zenith_deg": 70.0, "azimuth_deg": azimuth, "irradiance": [1.0],
                "angular_diameter_deg": diameter}
    d["sky"] = {"type": "black"}
    # a large sun: 64 passes (directions in the disk) for the disk's average
    res = render(Scene.from_dict(d), radiometer_samples=2_000 if diameter == SMALL_SUN else 64 * 4096)
    crossed = 0
    for i, p in enumerate(points):
        length = -p[2] / mu_w
        r = _exact_integral(rho, box[0], box[1], p, p + up * length)
        crossed += r > 0.5
        ref = refracted_sun(70.0, (0.05 * length + 0.3 * r) * mu_w, diameter_deg=diameter)
        assert res.radiometer(f"Ed_{i}").mean[0, 0] == pytest.approx(ref, rel=1e-3)
    assert crossed == 3


def test_penumbra_of_a_large_sun_is_walked():
    """A 10-degree sun at 70 deg over a thin slab (0.125 m voxels), points whose rays towards
    the disk's centre pass 5, 12 and 20 cm beside the slab: part of the disk's directions
    cross it. The beams decide once, for the whole disk, where no walk is needed; a point in
    the penumbra must be walked for every direction. Ed (256 passes over the disk) equals the
    disk quadrature of cos T_F exp(-tau), tau integrated in numpy per direction, to 1 % (the
    passes are stratified over the disk) and within 4 of its standard errors; the slab takes
    4 to 30 % of each (a map built for the disk's centre alone skips the outermost one: 4 % high)."""
    from test_stratified import _core
    rho = np.zeros((128, 128, 32))
    rho[60:68, 60:68, 24:28] = 6.0  # x, y in [-0.5, 0.5], z in [-1.0, -0.5]
    box = ([-8.0, -8.0, -4.0], [16.0, 16.0, 4.0])
    d = absorbing_grid(rho, box)
    zenith, diameter = 70.0, 10.0
    sin_w = math.sin(math.radians(zenith)) / N_W
    up = np.array([sin_w, 0.0, math.sqrt(1 - sin_w ** 2)])  # azimuth 0: the ray keeps its y
    points = [np.array([0.0, y, -0.75]) - up * (3.5 - 0.75) / up[2] for y in (0.55, 0.62, 0.7)]
    d["radiometers"] = [{"name": f"Ed_{i}", "quantity": "Ed", "position": list(p)}
                        for i, p in enumerate(points)]
    d["sun"] = {"zenith_deg": zenith, "azimuth_deg": 0.0, "irradiance": [1.0],
                "angular_diameter_deg": diameter}
    d["sky"] = {"type": "black"}
    res = render(Scene.from_dict(d), radiometer_samples=256 * 4096)
    # the disk quadrature: Gauss-Legendre in the angle from the centre, trapezoid in azimuth
    alpha, th0 = math.radians(diameter) / 2, math.radians(zenith)
    x, wx = np.polynomial.legendre.leggauss(24)
    for i, p in enumerate(points):
        total = clear = 0.0
        for r, wr in zip(alpha * (x + 1) / 2, wx * alpha / 2):
            for ph in np.linspace(0, 2 * np.pi, 96, endpoint=False):
                s = np.array([math.sin(th0) * math.cos(r) + math.cos(th0) * math.sin(r) * math.cos(ph),
                              math.sin(r) * math.sin(ph),
                              math.cos(th0) * math.cos(r) - math.sin(th0) * math.sin(r) * math.cos(ph)])
                u = np.array([s[0] / N_W, s[1] / N_W, 0.0])
                u[2] = math.sqrt(1 - u[0] ** 2 - u[1] ** 2)
                length = -p[2] / u[2]
                dens = _exact_integral(rho, box[0], box[1], p, p + u * length)
                f = s[2] * (1 - _core.fresnel(s[2], 1.0, N_W)) * math.sin(r) * wr
                total += f * math.exp(-0.05 * length - 0.3 * dens)
                clear += f * math.exp(-0.05 * length)
        norm = np.pi * math.sin(alpha) ** 2 / (2 * np.pi / 96)
        ref, ref_clear = total / norm, clear / norm
        r = res.radiometer(f"Ed_{i}")
        z = (r.mean[0, 0] - ref) / r.stderr[0, 0]
        print(f"penumbra Ed_{i} {r.mean[0, 0]:.6f} ref {ref:.6f} (without the slab {ref_clear:.6f}) "
              f"stderr {r.stderr[0, 0]:.2e} z {z:+.2f}")
        assert ref_clear / ref > 1.04  # the slab's penumbra: skipping its walks would show
        assert abs(z) < 4 and abs(r.mean[0, 0] / ref - 1) < 0.01


@pytest.mark.parametrize("wind", [0.0, 5.0])
def test_shadow_map_skips_only_clear_rays(wind):
    """The beams' shadow map decides where a walk is needed; the same absorbing patch with
    1e-12 added in every other voxel makes every ray meet density (no point is skipped). b = 0
    and one seed: both renders draw the same samples, so Ed at 24 points around and below the
    patch must agree to 1e-9 whatever the map skipped, below a smooth sea and below a rough one
    (wind 5 m/s: 16 refracted facets per pass, the map's cone widened for them; 8 passes: with
    b = 0 and a black sky each pass's Ed is its beams' at the sensor)."""
    rho = np.zeros((40, 40, 20))
    rho[16:24, 18:22, 14:17] = 1.5  # a patch 2 x 1 x 0.6 m, its top 0.6 m deep
    box = ([-5.0, -5.0, -4.0], [10.0, 10.0, 4.0])
    rng = np.random.default_rng(8)
    points = np.column_stack([rng.uniform(-2, 2, 24), rng.uniform(-2, 2, 24), rng.uniform(-3.9, -0.1, 24)])
    results = []
    for fill in (0.0, 1e-12):
        d = absorbing_grid(np.where(rho > 0, rho, fill), box)
        if wind:
            d["water"][0]["surface"] = {"kind": "flat", "z": 0.0, "roughness": {"wind_speed": wind}}
        d["radiometers"] = [{"name": f"Ed_{i}", "quantity": "Ed", "position": list(p)}
                            for i, p in enumerate(points)]
        d["sun"] = {"zenith_deg": 40.0, "azimuth_deg": 30.0, "irradiance": [1.0]}
        d["sky"] = {"type": "black"}
        res = render(Scene.from_dict(d), radiometer_samples=8 * 4096)
        results.append(np.array([res.radiometer(f"Ed_{i}").mean[0, 0] for i in range(len(points))]))
    sparse, dense = results
    assert np.all(dense > 0)
    assert np.max(np.abs(sparse / dense - 1)) < 1e-9
    shaded = sparse < 0.97 * np.median(sparse)  # some points lie in the patch's shadow
    assert 3 <= shaded.sum() <= 21


# --------------------------------------------------------------------------------------
# Conservation: a white furnace with a 3-D plume
# --------------------------------------------------------------------------------------

def test_grid_white_furnace_conserves_energy(zscore):
    """A closed non-absorbing water box in an isotropic environment L0 holding a box of random
    densities (0 to 3, some voxels empty) smaller than the water, corners inside and outside
    it: Eo = 4 pi n^2 L0 and L = n^2 L0 wherever measured (brick majorants, local components,
    density 0 outside the grid)."""
    from geometry import box
    n, l0 = 1.34, 1.0
    wv, wt = box((-2, -2, -2), (2, 2, 2))
    rng = np.random.default_rng(3)
    rho = rng.random((20, 12, 9)) * 3.0
    rho[rng.random(rho.shape) < 0.3] = 0.0
    g = grid(mixture(0.0, 0.2, 0.1), mixture(0.0, 1.0, 0.2), rho,
             ([-1.5, -1.0, -1.8], [2.5, 2.8, 3.0]))
    d = {"photic_scene": 1, "name": "furnace",
         "water": [{"name": "tank", "type": "mesh", "ior": n, "vertices": wv, "triangles": wt,
                    "iop_grid": g}],
         "sky": {"type": "uniform", "radiance": [l0], "full_sphere": True},
         "radiometers": [{"name": f"Eo_{i}", "quantity": "Eo", "position": list(p)}
                         for i, p in enumerate([(0.3, -0.4, 0.2), (-1.2, 1.5, -0.7), (1.7, 1.9, 1.6)])] +
                        [{"name": "L_mid", "quantity": "radiance", "position": [0.0, 0.5, 0.1],
                          "direction": [0.3, 0.2, -1.0]}],
         "settings": {"seed": 81, "max_depth": 100000}}
    res = render(Scene.from_dict(d), radiometer_samples=40_000)
    for r in res.radiometers:
        ref = (4 * np.pi if r.name.startswith("Eo") else 1.0) * n * n * l0
        assert r.medium == "tank"
        assert abs(zscore(f"grid furnace {r.name}", r.mean[0, 0], ref, r.stderr[0, 0])) < Z_MAX
        assert abs(r.mean[0, 0] / ref - 1) < 0.02


# --------------------------------------------------------------------------------------
# Errors
# --------------------------------------------------------------------------------------

def _grid_scene(**changes):
    base, unit = mixture(0.05, 0.1, 0.02), mixture(0.1, 0.2, 0.03)
    g = grid(base, unit, np.ones((2, 2, 2)))
    g.update(changes)
    return lambda: sea([rad("Ed", 1.0)], grid=g)


@pytest.mark.parametrize("changes, field, text", [
    ({"density": [[[1.0, -0.5]]]}, "iop_grid.density[0, 0, 1]", ">= 0"),
    ({"density": [[1.0, 2.0]]}, "iop_grid.density", "3-D array"),
    ({"size": [1.0, 0.0, 1.0]}, "iop_grid.size", "> 0"),
    ({"unit": {"iops": {"absorption": [0.1], "scattering": [{"b": [0.1], "phase": HG}]}}},
     "iop_grid.unit.iops.scattering", "same components"),
    ({"unit": {"iops": mixture(-0.1, 0.2, 0.0)}}, "iop_grid.unit.iops.absorption", ">= 0"),
    ({"file": "missing.npz"}, "iop_grid.file", "give only one of"),
    ({"base": {"iop_profile": {"z_top": [0.0, 1.0], "layers": [{"iops": mixture(0.05, 0.1, 0.02)}] * 2}}},
     "iop_grid.base.iop_profile.z_top[1]", "below"),
    ({"base": {"iop_profile": {"z_top": [0.0, -1.0], "layers": [{"iops": mixture(0.05, 0.1, 0.02)}] * 2}},
      "unit": {"iops": {"absorption": [0.1], "scattering": [{"b": [0.1], "phase": HG}]}}},
     "iop_grid.unit.iops.scattering", "iop_grid.base.iop_profile.layers[0].iops has 2"),
])
def test_bad_grids_are_scene_errors(changes, field, text):
    with pytest.raises(SceneError) as e:
        _grid_scene(**changes)()
    msg = str(e.value)
    assert "sea" in msg and field in msg and text in msg, msg


def test_grid_over_a_profile_round_trips_and_validates_against_the_schema(tmp_path):
    """A grid whose base is a depth profile is written back as such (scene file, schema-valid)
    and reads back equal; a unit from a model is aligned with every layer's components."""
    import jsonschema
    from photic.scene import IOPProfile, load_scene, save_scene, scene_schema
    g = grid(mixture(0.05, 0.1, 0.02), mixture(0.1, 0.2, 0.03), np.arange(8.0).reshape(2, 2, 2))
    g["base"] = {"iop_profile": {"z_top": [0.0, -2.0], "layers": [{"iops": mixture(0.05, 0.1, 0.02)},
                                                                  {"iops": mixture(0.2, 0.3, 0.02)}]}}
    sc = sea([rad("Ed", 1.0)], grid=g)
    assert isinstance(sc.water[0].iops.iops, IOPProfile)
    save_scene(sc, tmp_path / "s.json")
    d = json.loads((tmp_path / "s.json").read_text())
    jsonschema.validate(d, scene_schema())
    assert "iop_profile" in d["water"][0]["iop_grid"]["base"]
    assert load_scene(tmp_path / "s.json") == sc
    g["unit"] = {"iop_model": {"model": "particles", "b_ref": 1.0, "backscatter_fraction": 0.02}}
    w = sea([rad("Ed", 1.0)], grid=g).water[0].iops
    phases = [[c.phase for c in x.scattering] for x in w.iops.layers + [w.unit]]
    assert len(phases[0]) == 3 and phases[0] == phases[1] == phases[2]


@pytest.mark.parametrize("bad", [float("nan"), -1.0, float("inf")])
def test_core_refuses_bad_densities_that_skip_validation(bad):
    """The core checks the densities itself (a scene changed after validation): NaN, negative
    and infinite values in an otherwise clean row are refused, not rendered."""
    from photic.compile import compile_scene
    rho = np.zeros((3, 4, 40))
    rho[1, 2, 5] = 1.0
    sc = sea([rad("Ed", 1.0)], grid=grid(mixture(0.05, 0.1, 0.002), mixture(0.2, 0.5, 0.0), rho))
    sc.water[0].iops.density[2, 3, 37] = bad
    with pytest.raises(ValueError, match="finite and >= 0"):
        compile_scene(sc)


def test_missing_npz_is_a_scene_error(tmp_path):
    g = grid(mixture(0.05, 0.1, 0.02), mixture(0.1, 0.2, 0.03), np.ones((1, 1, 1)))
    del g["density"]
    g["file"] = "none.npz"
    d = sea([rad("Ed", 1.0)], iops=mixture(0.05, 0.1, 0.02)).to_dict()
    del d["water"][0]["iops"]
    d["water"][0]["iop_grid"] = g
    with pytest.raises(SceneError, match="iop_grid.file"):
        Scene.from_dict(d, base_dir=tmp_path)
    np.savez(tmp_path / "none.npz", rho=np.ones((1, 1, 1)))
    with pytest.raises(SceneError, match="no array 'density'"):
        Scene.from_dict(d, base_dir=tmp_path)
