"""A hash of renders covering every medium kind and both integrators, for refactors of the core
that must not change a single bit (compare the printed hashes before and after).

    .venv/bin/python scripts/render_hashes.py

Renders (2 threads, fixed seeds, a few seconds in all): the examples in ``examples/`` (stepped
pool, canonical problem 2, coastal shelf) at 48 x 32, and a sunlit sea with gridded water, a
grid over a depth profile and layered water, each with the hybrid and the path integrator and
forward cones 0 and 3 deg, a camera and Ed/Eu/Eo radiometers; and wave patches: three members
of the radiometers-under-waves bench (photic.bench_waves) and a sea under waves with objects
(a camera and Ed/Eu/Eo radiometers beside and below them, hybrid and path; a rough sea). Prints one hash per render and
their combined hash (means, variances, radiometer means and standard errors).
Compare builds made with the same compiler flags: floating-point contraction differs between
flag sets (e.g. ``-march=native`` emits FMA), and so do the last bits.
"""
from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the scene builders of the grid and layer tests

import test_grid as G  # noqa: E402
import test_stratified as S  # noqa: E402
from photic.render import render  # noqa: E402
from photic.scene import Scene, load_scene  # noqa: E402

CAMERA = {"name": "diver", "type": "perspective", "position": [0.3, -1.0, -3.0],
          "look_at": [0.0, 3.0, -8.0], "fov_deg": 60, "resolution": [24, 16]}
SUN = {"zenith_deg": 30.0, "azimuth_deg": 60.0, "irradiance": [1.0]}


def update(h, result) -> None:
    for k in sorted(result.images):
        h.update(np.ascontiguousarray(result.images[k].mean).tobytes())
        h.update(np.ascontiguousarray(result.images[k].variance).tobytes())
    for r in result.radiometers:
        h.update(np.ascontiguousarray(r.mean).tobytes())
        h.update(np.ascontiguousarray(r.stderr).tobytes())


def medium_scenes() -> dict[str, dict]:
    rads = [G.rad(q, z) for q in ("Ed", "Eu", "Eo") for z in (1.0, 6.0, 20.0)]
    rho = G._sparse_field()
    box = ([-20.0, -15.0, -30.0], [40.0, 30.0, 31.0])
    base, unit = G.mixture(0.05, 0.2, 0.01), G.mixture(0.1, 0.5, 0.0)
    profile = {"iop_profile": {"z_top": [0.0, -5.0, -12.0], "layers": [
        {"iops": G.mixture(a, b, 0.01)} for a, b in ((0.05, 0.2), (0.2, 0.6), (0.1, 0.05))]}}
    layers = [S.iops(0.05, 0.3, 0.01), S.iops(0.3, 1.0, 0.01), S.iops(0.1, 0.05, 0.01)]
    out = {}
    for integrator in ("hybrid", "path"):
        out[f"grid_{integrator}"] = G.sea(rads, grid=G.grid(base, unit, rho, box), integrator=integrator).to_dict()
        d = G.sea(rads, grid=G.grid(base, unit, rho, box), integrator=integrator).to_dict()
        d["water"][0]["iop_grid"]["base"] = profile
        out[f"grid_profile_{integrator}"] = d
        out[f"layers_{integrator}"] = S.layered_sea(
            [0.0, -3.0, -8.0], layers, [S.rad(q, z) for q in ("Ed", "Eu", "Eo") for z in (1.0, 4.0, 10.0)],
            sun=SUN, sky={"type": "uniform", "radiance": [0.3]}, integrator=integrator).to_dict()
    for d in out.values():
        d["cameras"] = [CAMERA]
        d.setdefault("sun", SUN)
    return out


def wave_scenes() -> dict[str, Scene]:
    from photic import bench_waves as B
    import test_beams_objects as O  # noqa: E402

    out = {}
    for m in B.WAVE_FAMILY:
        if m.name in ("issue", "small rough fine", "large rough fine"):
            out[f"waves {m.name}"] = B.wave_member_scene(m, "waves", 256, radiometers_per_side=4)
    rads = [[x, y, z] for x, y in ((0.5, 0.2), (6.0, 3.0), (13.0, -7.0)) for z in (-1.5, -4.5)]
    for integrator in ("hybrid", "path"):
        for rough in (False, True):
            surface = O.waves(24)
            if rough:
                surface["roughness"] = {"wind_speed": 6.0}
            d = O.sea(surface, ["cube", "sphere", "plate"], integrator=integrator, positions=rads).to_dict()
            d["radiometers"] = [dict(r, quantity=q, name=f"{r['name']}_{q}") for r in d["radiometers"]
                                for q in ("Ed", "Eu", "Eo")]
            d["cameras"] = [CAMERA]
            d["settings"]["radiometer_samples"] = 512
            out[f"waves objects {integrator}" + (" rough" if rough else "")] = Scene.from_dict(d)
    return out


def main() -> None:
    total = hashlib.sha256()
    rows = []
    for name, kw in [("stepped_pool.json", dict(samples=2, radiometer_samples=2048)),
                     ("problems/mobley1993_problem2_omega0.9.json", dict(samples=1, radiometer_samples=4096)),
                     ("coastal_shelf.json", dict(samples=1, radiometer_samples=1024))]:
        scene = load_scene(ROOT / "examples" / name)
        for c in scene.cameras:
            c.resolution = (48, 32)
        result = render(scene, threads=2, **kw)
        h = hashlib.sha256()
        update(h, result)
        update(total, result)
        rows.append((name, h.hexdigest()[:12]))
    for name, d in medium_scenes().items():
        for cone in (0.0, 3.0):
            d = dict(d, settings=dict(d["settings"], forward_cone_deg=cone))
            result = render(Scene.from_dict(d), threads=2, samples=4, radiometer_samples=2048)
            h = hashlib.sha256()
            update(h, result)
            update(total, result)
            rows.append((f"{name} cone {cone:g}", h.hexdigest()[:12]))
    for name, scene in wave_scenes().items():
        result = render(scene, threads=2, samples=4)
        h = hashlib.sha256()
        update(h, result)
        update(total, result)
        rows.append((name, h.hexdigest()[:12]))
    for name, digest in rows:
        print(f"{name:50s} {digest}")
    print("all", total.hexdigest())


if __name__ == "__main__":
    main()
