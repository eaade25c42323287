"""Builds the example .blend files (and the scene file equivalent to the canonical one).

Run it with the oldest supported Blender, so that every supported Blender opens the files
(a .blend saved by 5.0 does not open in 3.4; one saved by 3.4 opens in 5.0):

    PHOTIC_SITE_PACKAGES=$PWD/.venv/lib/python3.11/site-packages \\
        blender --background --factory-startup --python example_blends/make_examples.py

It also runs in the ``bpy`` module (``.venv/bin/python example_blends/make_examples.py
[--out DIR]``), which is what the tests do to check that the script still works.

Scenes:

- ``stepped_pool.blend``: the talk's example, a tiled pool stepping down 0.6/1.2/1.8 m under a
  static wave mesh, the sun at 35 degrees; cameras above the pool (active) and under water.
- ``canonical_problem2.blend``: open water with a vertical radiometer array at optical depths
  1, 5 and 10, canonical problem 2 of Mobley et al. (1993) with omega0 = 0.9 (Petzold phase
  function, sun at 60 degrees, black sky). ``canonical_problem2.json`` is the same scene as a
  scene file, written from the problem's definition (not exported from Blender): exporting the
  .blend must give exactly this scene.
- ``underwater_objects.blend``: an underwater camera looking at a rock, a crate, a pillar and a
  ring on a sandy bottom 8 m deep under a wavy sea (a tiling wave patch), with sun shafts, and a
  radiometer profile (Ed, Eu, Eo every metre) beside the diver. The README's main job.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import site
import sys
from pathlib import Path

# A distribution Blender has no numpy of its own: the engine's site-packages bring it.
for _d in os.environ.get("PHOTIC_SITE_PACKAGES", "").split(os.pathsep):
    if _d:
        site.addsitedir(_d)

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
REPO = HERE.parent


def _import_engine():
    import photic.cli
    return photic


def problem2_scene_dict() -> dict:
    """Canonical problem 2 (omega0 0.9) with its radiometers as one vertical array; the
    radiance cap angle is written as Blender holds it (float32, 7 significant digits) and the
    camera's field of view as a 50 mm lens on a 36 mm sensor gives it."""
    from photic import problems
    d = problems.problem_scene(2, 0.9, samples=600_000, seed=1993)
    d["name"] = "canonical_problem2"
    radiometers = d.pop("radiometers")
    cap = radiometers[2]["half_angle_deg"]
    d["radiometer_arrays"] = [{
        "name": "profile", "quantities": ["Ed", "Eou", "radiance"],
        "positions": [[0.0, 0.0, -tau] for tau in problems.TAUS],
        "direction": [0.0, 0.0, -1.0],
        # Blender keeps the angle in float32 radians; the add-on reads it to 7 digits.
        "half_angle_deg": float(f"{math.degrees(float(np.float32(math.radians(cap)))):.7g}"),
    }]
    # A camera 5 m above the sea looking straight down (50 mm lens on a 36 mm sensor).
    d["cameras"] = [{"name": "Camera", "type": "perspective", "position": [0.0, 0.0, 5.0],
                     "direction": [0.0, 0.0, -1.0], "up": [0.0, 1.0, 0.0],
                     "fov_deg": math.degrees(2 * math.atan(0.5 * 36.0 / 50.0)),
                     "resolution": [64, 64]}]
    d["settings"]["samples"] = 16
    return d


def wave_patch(period: float, n: int, waves) -> tuple[np.ndarray, np.ndarray]:
    """A seamlessly tiling height field over [0, period]^2 (n x n quads): a sum of sinusoids
    with whole numbers of wavelengths per period, (amplitude m, kx, ky, phase)."""
    g = np.linspace(0.0, period, n + 1)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    z = np.zeros_like(xx)
    for amp, kx, ky, phase in waves:
        z += amp * np.sin(2 * np.pi * (kx * xx + ky * yy) / period + phase)
    v = np.stack([xx.ravel(), yy.ravel(), z.ravel()], 1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + (n + 1), a + (n + 1) + 1, a + 1
    t = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, t


def underwater_scene_dict() -> dict:
    import trimesh
    objects = [
        ("rock", trimesh.creation.icosphere(subdivisions=3, radius=1.0), (1.5, 2.0, -5.4), "rock"),
        ("crate", trimesh.creation.box(extents=(1.6, 1.6, 1.2)), (-2.0, 4.0, -5.4), "wood"),
        ("pillar", trimesh.creation.cylinder(radius=0.35, height=5.0, sections=48), (3.5, 7.0, -3.5), "concrete"),
        ("ring", trimesh.creation.torus(major_radius=0.8, minor_radius=0.2, major_sections=32,
                                        minor_sections=12), (-0.5, 1.5, -5.8), "rock"),
    ]
    meshes = []
    for name, tm, pos, mat in objects:
        tm.apply_translation(pos)
        meshes.append({"name": name, "material": mat, "vertices": tm.vertices.tolist(),
                       "triangles": tm.faces.tolist()})
    # Long, gentle waves: their foci lie below the 6 m bottom, so the bottom shows soft caustics
    # and the water soft shafts (sharp foci need the sub-pixel roughness of the sea-surface work
    # to be rendered without fireflies).
    v, t = wave_patch(8.0, 48, [(0.03, 1, 0, 0.0), (0.02, 1, 2, 1.1), (0.008, -2, 3, 2.3)])
    return {
        "photic_scene": 1, "name": "underwater_objects",
        "bands": [{"name": "620", "center_nm": 620.0, "width_nm": 80.0},
                  {"name": "550", "center_nm": 550.0, "width_nm": 60.0},
                  {"name": "460", "center_nm": 460.0, "width_nm": 80.0}],
        "materials": {"sand": {"type": "lambertian", "reflectance": [0.42, 0.38, 0.30]},
                      "rock": {"type": "lambertian", "reflectance": [0.12, 0.11, 0.10]},
                      "wood": {"type": "lambertian", "reflectance": [0.30, 0.20, 0.12]},
                      "concrete": {"type": "lambertian", "reflectance": [0.35, 0.35, 0.33]}},
        "meshes": meshes,
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34,
                   "surface": {"kind": "patch", "vertices": v.tolist(), "triangles": t.tolist(),
                               "period": [8.0, 8.0]},
                   "bottom": {"depth": 6.0, "material": "sand"},
                   "iops": {"absorption": [0.35, 0.07, 0.03], "b": [0.15, 0.15, 0.15],
                            "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": 25.0, "azimuth_deg": 0.0, "irradiance": [1.6, 1.8, 1.7]},
        "sky": {"type": "cardioidal", "radiance": [0.06, 0.08, 0.1]},
        "cameras": [{"name": "diver", "type": "perspective", "position": [0.0, -2.5, -2.5],
                     "look_at": [0.5, 4.0, -4.5], "up": [0, 0, 1], "fov_deg": 75.0,
                     "resolution": [160, 90]}],
        # A profiling radiometer array beside the diver: Ed, Eu, Eo at 1, 3 and 5 m.
        "radiometer_arrays": [{"name": "profile", "quantities": ["Ed", "Eu", "Eo"],
                               "positions": [[-1.0, -1.0, -z] for z in (1.0, 3.0, 5.0)]}],
        "settings": {"integrator": "hybrid", "samples": 32, "seed": 11, "forward_cone_deg": "auto",
                     "radiometer_samples": 8192, "beam_max_level": 2},
    }


def build(out_dir: Path) -> list[Path]:
    photic = _import_engine()
    import bpy
    addon = photic.cli.load_addon()
    if not hasattr(bpy.types.Scene, "photic"):
        addon.register()
    from importlib import import_module
    importer = import_module("photic_blender.importer")
    from photic.scene import Scene
    from photic.scenes import stepped_pool

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    problem = problem2_scene_dict()
    (out_dir / "canonical_problem2.json").write_text(json.dumps(problem, indent=1) + "\n")
    written.append(out_dir / "canonical_problem2.json")
    scenes = [("stepped_pool", stepped_pool(resolution=(192, 128), waves=True, samples=16)),
              ("canonical_problem2", Scene.from_dict(problem)),
              ("underwater_objects", Scene.from_dict(underwater_scene_dict()))]
    for name, scene in scenes:
        bpy.ops.wm.read_homefile(use_empty=True)
        bscene = bpy.context.scene
        importer.import_scene(scene, bscene)
        path = out_dir / f"{name}.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
        written.append(path)
        print(f"wrote {path}")
    return written


def main(argv=None) -> None:
    if argv is None:
        if "--" in sys.argv:
            argv = sys.argv[sys.argv.index("--") + 1:]
        elif Path(sys.argv[0]).name.startswith("blender"):  # inside Blender, no script args
            argv = []
        else:
            argv = sys.argv[1:]
    parser = argparse.ArgumentParser(description="Build the example .blend files")
    parser.add_argument("--out", type=Path, default=HERE, help="output folder (default: here)")
    args = parser.parse_args(argv)
    build(args.out)


if __name__ == "__main__":
    main()
