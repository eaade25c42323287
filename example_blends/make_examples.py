"""Builds the example .blend files (and the scene file equivalent to the canonical one).

Run it with the oldest supported Blender, so that every supported Blender opens the files
(a .blend saved by 5.0 does not open in 3.4; one saved by 3.4 opens in 5.0):

    PHOTIC_SITE_PACKAGES=$PWD/.venv/lib/python3.11/site-packages \\
        blender --background --factory-startup --python example_blends/make_examples.py

It also runs in the ``bpy`` module (``.venv/bin/python example_blends/make_examples.py
[--out DIR] [--only NAME ...]``), which is what the tests do to check that the script still
works (``tests/test_addon_natural_waters.py`` builds and renders the plume example).

Scenes:

- ``stepped_pool.blend``: the talk's example, a tiled pool stepping down 0.6/1.2/1.8 m under a
  static wave mesh, the sun at 35 degrees; cameras above the pool (active) and under water.
- ``canonical_problem2.blend``: open water with a vertical radiometer array at optical depths
  1, 5 and 10, canonical problem 2 of Mobley et al. (1993) with omega0 = 0.9 (Petzold phase
  function, sun at 60 degrees, black sky). ``canonical_problem2.json`` is the same scene as a
  scene file, written from the problem's definition (not exported from Blender): exporting the
  .blend must give exactly this scene.
- ``underwater_objects.blend``: the README's main job and showcase, 960 x 540 at 16 samples per
  pixel, denoised: a diver's view of a rock, a crate, a pillar and a ring on a sandy floor 6 m
  deep under a wavy sea (a tiling wave patch), towards the sun and a little up, so that the
  caustic network on the floor and the objects, sun shafts and Snell's window are in one frame;
  and a radiometer profile (Ed, Eu, Eo at 1, 3 and 5 m) beside the diver.
- ``sediment_plume.blend`` and ``sediment_plume.npz`` beside it: a river's sediment plume
  entering clear water near a shore, seen from the air; the sea's IOPs are a clear-water model
  plus two 3-D density fields on one grid (the .npz): the sediment (mineral particles) and
  the river water, whose CDOM spreads wider and mixes deeper than the sediment; radiometers 1 m above the plume and above clear water for Rrs (``plume_rrs``,
  ``scripts/plume_rrs_plot.py``; docs/blender.md, "The sediment plume").
- ``seagrass_meadow.blend``: a seagrass meadow of Geometry Nodes instances (about 10,000 copies
  of one blade) and a rock three times (linked duplicates) under the showcase's waves, 4 m
  deep, with Ed under and over the canopy: instanced geometry as artists build it.
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


def _blender():
    """(bpy, the add-on's importer, photic's Scene) with the add-on registered."""
    photic = _import_engine()
    import bpy
    addon = photic.cli.load_addon()
    if not hasattr(bpy.types.Scene, "photic"):
        addon.register()
    from importlib import import_module
    from photic.scene import Scene
    return bpy, import_module("photic_blender.importer"), Scene


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


UNDERWATER_RESOLUTION = (960, 540)


def underwater_scene_dict(resolution=UNDERWATER_RESOLUTION, samples: int = 16) -> dict:
    """The README's showcase: a diver 1.5 m above a sandy floor 6 m deep, looking towards the
    sun and a little up, so that one frame holds the caustic network on the floor and on the
    objects' tops, the sun shafts in the water, and Snell's window (the sky squeezed into a
    97 degree cone, the sea floor mirrored outside it) across the top."""
    import trimesh
    objects = [
        ("rock", trimesh.creation.icosphere(subdivisions=3, radius=1.0), (1.3, 3.6, -5.5), "rock"),
        ("crate", trimesh.creation.box(extents=(1.6, 1.6, 1.2)), (-2.1, 4.6, -5.4), "wood"),
        ("pillar", trimesh.creation.cylinder(radius=0.35, height=5.0, sections=48), (3.2, 6.8, -3.5), "concrete"),
        ("ring", trimesh.creation.torus(major_radius=0.8, minor_radius=0.2, major_sections=32,
                                        minor_sections=12), (-0.3, 2.2, -5.8), "rock"),
    ]
    meshes = []
    for name, tm, pos, mat in objects:
        tm.apply_translation(pos)
        meshes.append({"name": name, "material": mat, "vertices": tm.vertices.tolist(),
                       "triangles": tm.faces.tolist()})
    # A swell and short wind waves (1.5-1.6 m, whole numbers per 8 m period) whose curvature
    # focuses the refracted sun about 6-7 m down: a sharp caustic network on the floor.
    v, t = wave_patch(8.0, 96, [(0.03, 1, 0, 0.0), (0.02, 1, 2, 1.1), (0.035, 4, 3, 0.4),
                                (0.03, -5, 2, 2.3), (0.012, 2, -6, 0.7)])
    return {
        "photic_scene": 1, "name": "underwater_objects",
        "bands": [{"name": "620", "center_nm": 620.0, "width_nm": 80.0},
                  {"name": "550", "center_nm": 550.0, "width_nm": 60.0},
                  {"name": "460", "center_nm": 460.0, "width_nm": 80.0}],
        "materials": {"sand": {"type": "lambertian", "reflectance": [0.42, 0.38, 0.30]},
                      "rock": {"type": "lambertian", "reflectance": [0.30, 0.27, 0.22]},
                      "wood": {"type": "lambertian", "reflectance": [0.30, 0.20, 0.12]},
                      "concrete": {"type": "lambertian", "reflectance": [0.35, 0.35, 0.33]}},
        "meshes": meshes,
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34,
                   "surface": {"kind": "patch", "vertices": v.tolist(), "triangles": t.tolist(),
                               "period": [8.0, 8.0]},
                   "bottom": {"depth": 6.0, "material": "sand"},
                   "iops": {"absorption": [0.28, 0.05, 0.025], "b": [0.12, 0.12, 0.12],
                            "phase": {"type": "petzold"}}}],
        "sun": {"zenith_deg": 35.0, "azimuth_deg": 60.0, "irradiance": [1.6, 1.8, 1.7]},
        "sky": {"type": "cardioidal", "radiance": [0.06, 0.08, 0.1]},
        "cameras": [{"name": "diver", "type": "perspective", "position": [0.0, -1.5, -4.8],
                     "look_at": [0.5, 6.0, -2.8], "up": [0, 0, 1], "fov_deg": 100.0,
                     "resolution": list(resolution)}],
        # A profiling radiometer array beside the diver: Ed, Eu, Eo at 1, 3 and 5 m.
        "radiometer_arrays": [{"name": "profile", "quantities": ["Ed", "Eu", "Eo"],
                               "positions": [[-1.0, -1.0, -z] for z in (1.0, 3.0, 5.0)]}],
        "settings": {"integrator": "hybrid", "samples": samples, "seed": 11, "forward_cone_deg": "auto",
                     "radiometer_samples": 8192, "beam_max_level": 3},
    }


# --------------------------------------------------------------------------------------------
# seagrass_meadow.blend: a meadow of Geometry Nodes instances under waves
# --------------------------------------------------------------------------------------------

MEADOW_DENSITY = 160.0  # blades per m^2 on the 8 x 8 m bed: about 10,000 copies


def seagrass_blade(segments: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """A seagrass blade in its own frame: a ribbon 1 cm wide and 0.6 m long rising from the
    origin along z, bending over along +x and twisting a little (2 x segments triangles)."""
    s = np.linspace(0.0, 1.0, segments + 1)
    spine = np.stack([0.18 * s ** 2, np.zeros_like(s), 0.58 * s - 0.05 * s ** 2], axis=1)
    twist = 0.6 * s
    half = 0.005 * (1.0 - 0.5 * s ** 4)  # narrowing to a rounded tip
    side = np.stack([np.zeros_like(s), np.cos(twist), np.sin(twist)], axis=1) * half[:, None]
    v = np.concatenate([spine - side, spine + side])
    i = np.arange(segments)
    n = segments + 1
    t = np.concatenate([np.stack([i, i + 1, n + i], 1), np.stack([i + 1, n + i + 1, n + i], 1)])
    return v, t


def meadow_scene_dict(resolution=UNDERWATER_RESOLUTION, samples: int = 16) -> dict:
    """seagrass_meadow.blend's scene before its Geometry Nodes: the underwater example's sea
    and waves over a sandy bottom 4 m deep, the blade (hidden: the meadow's instances show it),
    a rock placed three times (linked duplicates), a diver's camera looking across the meadow
    towards the sun, and Ed radiometers under the canopy and above it."""
    import trimesh
    v, t = wave_patch(8.0, 96, [(0.03, 1, 0, 0.0), (0.02, 1, 2, 1.1), (0.035, 4, 3, 0.4),
                                (0.03, -5, 2, 2.3), (0.012, 2, -6, 0.7)])
    bv, bt = seagrass_blade()
    rock = trimesh.creation.icosphere(subdivisions=3, radius=0.45)
    rock.vertices[:, 2] *= 0.6
    d = underwater_scene_dict(resolution, samples)
    d.update({
        "name": "seagrass_meadow",
        "materials": {"sand": {"type": "lambertian", "reflectance": [0.42, 0.38, 0.30]},
                      "seagrass": {"type": "lambertian", "reflectance": [0.10, 0.22, 0.06]},
                      "rock": {"type": "lambertian", "reflectance": [0.30, 0.27, 0.22]}},
        "meshes": [{"name": "seagrass blade", "material": "seagrass", "vertices": bv.tolist(),
                    "triangles": t_list(bt)},
                   {"name": "rock", "material": "rock", "vertices": (rock.vertices + (1.2, 4.5, -3.85)).tolist(),
                    "triangles": rock.faces.tolist()}],
        "water": [{"name": "sea", "type": "ocean", "ior": 1.34,
                   "surface": {"kind": "patch", "vertices": v.tolist(), "triangles": t.tolist(),
                               "period": [8.0, 8.0]},
                   "bottom": {"depth": 4.0, "material": "sand"},
                   "iops": {"absorption": [0.28, 0.05, 0.025], "b": [0.12, 0.12, 0.12],
                            "phase": {"type": "petzold"}}}],
        "cameras": [{"name": "diver", "type": "perspective", "position": [0.0, -0.5, -2.6],
                     "look_at": [0.6, 5.0, -3.6], "up": [0, 0, 1], "fov_deg": 80.0,
                     "resolution": list(resolution)}],
        # Ed on a 3 x 3 m square of the bed under the canopy and 1 m above the bed, over it:
        # the canopy's transmission of the downwelling light, averaged over its shadows.
        "radiometer_arrays": [{"name": name, "quantities": ["Ed"],
                               "positions": [[x, y, z] for x in (-1.5, -0.5, 0.5, 1.5)
                                             for y in (3.0, 4.0, 5.0, 6.0)]}
                              for name, z in (("under_canopy", -3.97), ("above_canopy", -3.0))],
    })
    return d


def t_list(t) -> list:
    return np.asarray(t, dtype=np.int64).tolist()


def _gn_socket(tree, name: str, in_out: str, socket_type: str) -> None:
    """A group socket, in Blender 4+ (tree.interface) and 3.4 (tree.inputs / outputs)."""
    if hasattr(tree, "interface"):
        tree.interface.new_socket(name=name, in_out=in_out, socket_type=socket_type)
    else:
        (tree.inputs if in_out == "INPUT" else tree.outputs).new(socket_type, name)


def _socket(sockets, name: str, kind: str | None = None):
    """A node's socket by name (and type: Random Value has one per data type)."""
    return next(x for x in sockets if x.name == name and (kind is None or x.type == kind))


def meadow_nodes(blade, density: float = MEADOW_DENSITY, seed: int = 3):
    """Geometry Nodes: points distributed on the carrier's faces, each an instance of the blade
    turned about z, leaning up to 0.3 rad and scaled 0.6-1.3; the carrier itself not drawn."""
    import bpy
    tree = bpy.data.node_groups.new("Seagrass meadow", "GeometryNodeTree")
    _gn_socket(tree, "Geometry", "INPUT", "NodeSocketGeometry")
    _gn_socket(tree, "Geometry", "OUTPUT", "NodeSocketGeometry")
    n, link = tree.nodes, tree.links.new
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    dist = n.new("GeometryNodeDistributePointsOnFaces")
    dist.distribute_method = "RANDOM"
    dist.inputs["Density"].default_value = density
    dist.inputs["Seed"].default_value = seed
    info = n.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = blade
    info.inputs["As Instance"].default_value = True
    inst = n.new("GeometryNodeInstanceOnPoints")
    rot = n.new("FunctionNodeRandomValue")
    rot.data_type = "FLOAT_VECTOR"
    _socket(rot.inputs, "Min", "VECTOR").default_value = (-0.3, -0.3, 0.0)
    _socket(rot.inputs, "Max", "VECTOR").default_value = (0.3, 0.3, 2.0 * math.pi)
    _socket(rot.inputs, "Seed").default_value = seed + 1
    size = n.new("FunctionNodeRandomValue")
    size.data_type = "FLOAT"
    _socket(size.inputs, "Min", "VALUE").default_value = 0.6
    _socket(size.inputs, "Max", "VALUE").default_value = 1.3
    _socket(size.inputs, "Seed").default_value = seed + 2
    link(_socket(gin.outputs, "Geometry"), dist.inputs["Mesh"])
    link(dist.outputs["Points"], inst.inputs["Points"])
    link(info.outputs["Geometry"], inst.inputs["Instance"])
    link(_socket(rot.outputs, "Value", "VECTOR"), inst.inputs["Rotation"])
    link(_socket(size.outputs, "Value", "VALUE"), inst.inputs["Scale"])
    link(inst.outputs["Instances"], _socket(gout.inputs, "Geometry"))
    return tree


def build_seagrass_meadow(out_dir: Path) -> Path:
    """seagrass_meadow.blend: about 10,000 Geometry Nodes instances of a seagrass blade on an
    8 x 8 m bed, a rock three times (linked duplicates), under the showcase's waves: the
    meadow exports as one mesh and its transforms (docs/blender.md), and the caustics play on
    the blades and the sand between them."""
    bpy, importer, Scene = _blender()

    out_dir.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.read_homefile(use_empty=True)
    bscene = bpy.context.scene
    created = importer.import_scene(Scene.from_dict(meadow_scene_dict()), bscene)
    blade = created["seagrass blade"]
    # The blade lives in a collection excluded from the view layer, as artists keep the
    # sources of their instances: drawn only through the meadow's copies.
    parts = bpy.data.collections.new("meadow parts")
    bscene.collection.children.link(parts)
    for c in list(blade.users_collection):
        c.objects.unlink(blade)
    parts.objects.link(blade)
    bpy.context.view_layer.layer_collection.children[parts.name].exclude = True
    rock = created["rock"]
    for k, offset in enumerate([(-2.3, 1.4, 0.02), (2.1, 2.9, -0.05)]):
        copy = rock.copy()  # a linked duplicate: the same mesh data
        copy.name = f"rock.{k + 1:03d}"
        copy.location = offset
        copy.rotation_euler = (0.0, 0.0, 1.3 * (k + 1))
        copy.scale = (1.2 - 0.3 * k, 0.9, 1.0)
        bscene.collection.objects.link(copy)
    bed = bpy.data.meshes.new("meadow bed")
    bed.from_pydata([(-4.0, 0.5, -3.99), (4.0, 0.5, -3.99), (4.0, 8.5, -3.99), (-4.0, 8.5, -3.99)],
                    [], [(0, 1, 2, 3)])
    carrier = bpy.data.objects.new("seagrass meadow", bed)
    bscene.collection.objects.link(carrier)
    mod = carrier.modifiers.new("Seagrass meadow", "NODES")
    mod.node_group = meadow_nodes(blade)
    bscene.photic.denoise = True
    path = out_dir / "seagrass_meadow.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    print(f"wrote {path}")
    return path


# --------------------------------------------------------------------------------------------
# sediment_plume.blend: a river's sediment plume entering clear water near a shore
# --------------------------------------------------------------------------------------------
# The shore runs along y = 0 with land at +y; the river comes down a channel at x = 0 and its
# plume leaves the mouth heading offshore (-y), bent towards +x by a longshore current.

PLUME_BANDS = [(415.0 + 30.0 * i, 30.0) for i in range(10)]  # 400-700 nm in 30 nm bands
PLUME_GRID_SHAPE = (128, 128, 32)                            # voxels (x, y, z): 1.7 x 1.7 x 0.27 m
PLUME_BOX_ORIGIN = (-60.0, -180.0, -8.0)                     # m; the box reaches 0.5 m above
PLUME_BOX_SIZE = (220.0, 220.0, 8.5)                         # the sea to hold the river channel
PLUME_IOR = 1.34
# Fresnel reflectance of a flat sea at normal incidence: the share of the zenith sky that a
# nadir-looking radiometer sees reflected (removed from Lu to give the water-leaving radiance).
PLUME_RHO = ((PLUME_IOR - 1.0) / (PLUME_IOR + 1.0)) ** 2
PLUME_RADIOMETERS = {"plume": (15.0, -50.0), "clear": (-300.0, -600.0)}  # (x, y) m, 1 m up
PLUME_RADIOMETER_HEIGHT = 1.0


def clear_water_model() -> dict:
    """Clear coastal ocean: pure water (Pope & Fry), a little CDOM and fine particles."""
    return {"model": "mixture", "components": [
        {"model": "cdom", "a_ref": 0.01},
        {"model": "particles", "b_ref": 0.08, "backscatter_fraction": 0.012, "a_ref": 0.004}]}


def sediment_unit_model() -> dict:
    """What one unit of sediment density adds: mineral particles that scatter strongly
    (b_p(550) = 8 m^-1, flat spectrum, b_bp/b_p = 0.02) and absorb in the blue (brown non-algal
    particles, a_NAP(443) = 0.35 m^-1). No pure water: it is in the base IOPs."""
    return {"model": "particles", "b_ref": 8.0, "exponent": 0.5, "backscatter_fraction": 0.02,
            "a_ref": 0.35, "water": "none"}


def river_cdom_model() -> dict:
    """What one unit of river water adds: its CDOM (a_g(440) = 0.5 m^-1), no pure water."""
    return {"model": "cdom", "a_ref": 0.5, "water": "none"}


def plume_unit_model() -> dict:
    """Sediment and river CDOM per unit density in one field, as if the CDOM followed the
    sediment (the example's single-field form, which scripts/grid_cost.py measures)."""
    parts = [river_cdom_model(), sediment_unit_model()]
    for part in parts:
        del part["water"]
    return {"model": "mixture", "water": "none", "components": parts}


# The river water (and its CDOM) spreads wider and mixes deeper than the sediment, which
# settles out of the fresh surface layer: the example's second density field.
CDOM_SPREAD, CDOM_LENS = 1.6, 1.5


def _smooth_noise(shape, sigmas, rng) -> np.ndarray:
    """A random field with standard deviation 1: white noise low-passed (Gaussian filters of
    the given widths in cells, weights decreasing), periodic (by FFT)."""
    freqs = np.meshgrid(*[np.fft.fftfreq(n) for n in shape], indexing="ij")
    k2 = sum(f ** 2 for f in freqs)
    out = np.zeros(shape)
    for weight, sigma in zip((1.0, 0.55, 0.3), sigmas):
        white = np.fft.fftn(rng.standard_normal(shape))
        field = np.fft.ifftn(white * np.exp(-2.0 * np.pi ** 2 * sigma ** 2 * k2)).real
        out += weight * field / field.std()
    return out / out.std()


def plume_density(shape=PLUME_GRID_SHAPE, seed: int = 7, spread: float = 1.0,
                  lens: float = 1.0) -> np.ndarray:
    """The plume's sediment density on the grid (float32, 1 in the river, decaying offshore).

    In the jet's own coordinates, s along its bending centreline from the mouth and n across
    it: a Gaussian across of width 5 + 0.28 s m, diluting as 1 / (1 + s / 70 m), its edges
    meandered and its body broken into eddies by smooth noise; the buoyant fresh water keeps
    the sediment in a surface layer exp(-(depth / h)^2) thickening from h = 1 m at the mouth.
    ``spread`` and ``lens`` widen the Gaussian and thicken the layer by those factors (the
    river water itself: CDOM_SPREAD, CDOM_LENS), with the same meanders and eddies.
    """
    rng = np.random.default_rng(seed)
    nx, ny, nz = shape
    origin, size = np.asarray(PLUME_BOX_ORIGIN), np.asarray(PLUME_BOX_SIZE)
    x, y, z = (origin[i] + (np.arange(n) + 0.5) * size[i] / n for i, n in enumerate(shape))
    xx, yy = np.meshgrid(x, y, indexing="ij")
    # The centreline leaves the mouth heading -y and turns 65 degrees towards +x.
    step = 0.5
    s_line = np.arange(0.0, 450.0, step)
    heading = np.radians(-90.0 + 65.0 * (1.0 - np.exp(-s_line / 90.0)))
    x_line = np.concatenate([[0.0], np.cumsum(np.cos(heading[:-1]) * step)])
    y_line = np.concatenate([[0.0], np.cumsum(np.sin(heading[:-1]) * step)])
    nearest = np.empty((nx, ny), int)
    for i in range(nx):  # row by row: the distance table of all columns would be large
        d2 = (xx[i, :, None] - x_line) ** 2 + (yy[i, :, None] - y_line) ** 2
        nearest[i] = np.argmin(d2, axis=1)
    s = s_line[nearest]
    h = heading[nearest]
    n = -(xx - x_line[nearest]) * np.sin(h) + (yy - y_line[nearest]) * np.cos(h)
    width = (5.0 + 0.28 * s) * spread
    cells = 128.0 / nx  # noise widths scale with the resolution so the field looks the same
    meander = _smooth_noise((nx, ny), (6.0 / cells, 3.0 / cells, 1.5 / cells), rng)
    eddies = _smooth_noise((nx, ny), (4.0 / cells, 2.0 / cells, 1.0 / cells), rng)
    across = (n + 0.45 * width * meander) / width
    column = np.exp(-0.5 * across ** 2) / (1.0 + s / 70.0) * np.clip(1.0 + 0.35 * eddies, 0.0, None)
    column = np.where(yy > 0.0, (np.abs(xx) < 9.0).astype(float), column)  # the river itself
    fade = np.clip(np.minimum(xx - origin[0], origin[0] + size[0] - xx) / 20.0, 0.0, 1.0)
    fade *= np.clip((yy - origin[1]) / 20.0, 0.0, 1.0)  # no hard edges at the box's sides
    thickness = (1.0 + 0.015 * s) * lens
    depth = np.clip(-z, 0.0, None)
    rho = (column * fade)[:, :, None] * np.exp(-(depth / thickness[:, :, None]) ** 2)
    return np.clip(rho, 0.0, None).astype(np.float32)


def shore_height(x, y):
    """Ground height (m) of the shore: a sea floor sloping from the waterline at y = 0 to
    150 m deep at y = -600, a beach and low land rising inland, and a river channel 2.5 m deep
    along x = 0 that flares at the mouth (the sea fills it)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    sea_floor = -(0.05 * np.abs(y) + 0.00035 * y ** 2)
    land = 0.04 * y - 0.00002 * y ** 2 + 0.3 * np.sin(x / 23.0) * np.clip(y / 60.0, 0.0, 1.0)
    land = np.minimum(land, 3.0 + 0.004 * y)
    ground = np.where(y < 0.0, sea_floor, land)
    half_width = 7.0 + 10.0 * np.exp(-np.clip(y, 0.0, None) / 12.0)
    channel = np.clip(1.0 - (x / half_width) ** 2, 0.0, None)
    return ground - np.where(y > -20.0, 2.5 * channel * np.clip((y + 20.0) / 20.0, 0.0, 1.0), 0.0)


def shore_meshes() -> dict:
    """The ground as two height-field meshes, fine near the river mouth and coarse far away:
    'beach' (sand, the sea floor and the beach) and 'land' (grass, from 45 m inland)."""
    xs = np.concatenate([np.linspace(-700, -150, 12)[:-1], np.linspace(-150, 250, 161)[:-1],
                         np.linspace(250, 900, 14)])
    ys = np.concatenate([np.linspace(-700, -250, 10)[:-1], np.linspace(-250, 120, 149)[:-1],
                         np.linspace(120, 900, 14)])
    xx, yy = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([xx.ravel(), yy.ravel(), shore_height(xx, yy).ravel()], 1)
    ny = len(ys)
    i, j = np.meshgrid(np.arange(len(xs) - 1), np.arange(ny - 1), indexing="ij")
    a = (i * ny + j).ravel()
    t = np.concatenate([np.stack([a, a + ny, a + ny + 1], 1), np.stack([a, a + ny + 1, a + 1], 1)])
    inland = v[t].mean(axis=1)[:, 1] > 45.0
    return {"beach": (v, t[~inland]), "land": (v, t[inland])}


def _per_colour(blue: float, green: float, red: float) -> list[float]:
    """Per-band values that Blender's colours hold exactly: each band takes its nearest
    primary (below 490 nm blue, to 580 nm green, above red; blender_addon/bands.py)."""
    return [blue if c < 490 else green if c <= 580 else red for c, _ in PLUME_BANDS]


def plume_scene_dict(resolution=(480, 270), samples: int = 96) -> dict:
    """Everything but the water's natural-waters settings, which build_sediment_plume sets on
    the Blender object (the importer holds homogeneous IOPs only)."""
    meshes = shore_meshes()
    radiometers = []
    for name, (x, y) in PLUME_RADIOMETERS.items():
        at = [x, y, PLUME_RADIOMETER_HEIGHT]
        radiometers += [{"name": f"Lu_{name}", "quantity": "radiance", "position": at,
                         "direction": [0.0, 0.0, -1.0], "half_angle_deg": 10.0},
                        {"name": f"Ed_{name}", "quantity": "Ed", "position": at}]
    x, y = PLUME_RADIOMETERS["plume"]
    radiometers.append({"name": "Lsky", "quantity": "radiance", "direction": [0.0, 0.0, 1.0],
                        "position": [x, y, PLUME_RADIOMETER_HEIGHT], "half_angle_deg": 10.0})
    sand = [0.10, 0.12, 0.14, 0.16, 0.18, 0.20, 0.22, 0.23, 0.24, 0.25]
    grass = [0.03, 0.035, 0.04, 0.06, 0.09, 0.08, 0.06, 0.05, 0.05, 0.06]
    return {
        "photic_scene": 1, "name": "sediment_plume",
        "bands": [{"name": f"{c:g}", "center_nm": c, "width_nm": w} for c, w in PLUME_BANDS],
        "materials": {"sand": {"type": "lambertian", "reflectance": sand},
                      "grass": {"type": "lambertian", "reflectance": grass}},
        "meshes": [{"name": name, "material": "sand" if name == "beach" else "grass",
                    "vertices": v.tolist(), "triangles": t.tolist()}
                   for name, (v, t) in meshes.items()],
        "water": [{"name": "sea", "type": "ocean", "ior": PLUME_IOR,
                   "surface": {"kind": "flat", "z": 0.0},
                   "iops": {"absorption": [0.05] * len(PLUME_BANDS)}}],
        # A white sun 40 degrees from the zenith behind the camera (no glint in view) and a
        # blue cardioidal sky (about a third of the blue irradiance is diffuse).
        "sun": {"zenith_deg": 40.0, "azimuth_deg": 235.0, "irradiance": [1.0] * len(PLUME_BANDS)},
        "sky": {"type": "cardioidal", "radiance": _per_colour(0.045, 0.029, 0.02)},
        "cameras": [{"name": "Camera", "type": "perspective", "position": [-70.0, -215.0, 75.0],
                     "look_at": [35.0, -60.0, -5.0], "up": [0.0, 0.0, 1.0], "fov_deg": 55.0,
                     "resolution": list(resolution)}],
        "radiometers": radiometers,
        "settings": {"integrator": "hybrid", "samples": samples, "seed": 5,
                     "radiometer_samples": 1_000_000, "beam_max_level": 2},
    }


def build_sediment_plume(out_dir: Path, grid_shape=PLUME_GRID_SHAPE) -> Path:
    """sediment_plume.blend and, beside it, sediment_plume.npz (the density)."""
    bpy, importer, Scene = _blender()

    out_dir.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out_dir / "sediment_plume.npz", density=plume_density(grid_shape),
                        cdom=plume_density(grid_shape, spread=CDOM_SPREAD, lens=CDOM_LENS))
    bpy.ops.wm.read_homefile(use_empty=True)
    bscene = bpy.context.scene
    created = importer.import_scene(Scene.from_dict(plume_scene_dict()), bscene)
    box = bpy.data.objects.new("plume box", None)  # the grid's box, drawn as a cube
    box.empty_display_type, box.empty_display_size = "CUBE", 1.0
    box.location = tuple(np.add(PLUME_BOX_ORIGIN, np.multiply(PLUME_BOX_SIZE, 0.5)))
    box.scale = tuple(np.multiply(PLUME_BOX_SIZE, 0.5))
    bscene.collection.objects.link(box)
    p = created["sea"].photic
    p.iop_source, p.iop_model = "MODEL", json.dumps(clear_water_model())
    p.iop_variation, p.grid_source, p.grid_box = "GRID", "NPZ", box
    p.grid_file = "//sediment_plume.npz"  # beside the .blend
    p.unit_source, p.unit_model = "MODEL", json.dumps(sediment_unit_model())
    cdom = p.grid_fields.add()  # the river water's CDOM: a second field, array 'cdom'
    cdom.name, cdom.unit_source, cdom.unit_model = "cdom", "MODEL", json.dumps(river_cdom_model())
    path = out_dir / "sediment_plume.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
    print(f"wrote {path}")
    return path


def plume_rrs(table) -> dict:
    """Rrs above the plume and above clear water from a render's radiometer table (path or
    ``photic.derived.RadiometerTable``): Lw = Lu - rho Lsky with rho the flat sea's Fresnel
    reflectance at nadir, Rrs = Lw / Ed (photic.derived; sr^-1, with standard errors)."""
    from photic.derived import load_table, remote_sensing_reflectance
    table = load_table(table)
    return {name: remote_sensing_reflectance(f"Lu_{name}", f"Ed_{name}", sky="Lsky",
                                             rho=PLUME_RHO, table=table)
            for name in PLUME_RADIOMETERS}


EXAMPLES = ("stepped_pool", "canonical_problem2", "underwater_objects", "sediment_plume",
            "seagrass_meadow")


def build(out_dir: Path, only=None) -> list[Path]:
    """Write the examples (``only``: a list of their names) into ``out_dir``."""
    only = set(only or EXAMPLES)
    bpy, importer, Scene = _blender()
    from photic.scenes import stepped_pool

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    problem = problem2_scene_dict()
    if "canonical_problem2" in only:
        (out_dir / "canonical_problem2.json").write_text(json.dumps(problem, indent=1) + "\n")
        written.append(out_dir / "canonical_problem2.json")
    scenes = [("stepped_pool", stepped_pool(resolution=(192, 128), waves=True, samples=16)),
              ("canonical_problem2", Scene.from_dict(problem)),
              ("underwater_objects", Scene.from_dict(underwater_scene_dict()))]
    for name, scene in scenes:
        if name not in only:
            continue
        bpy.ops.wm.read_homefile(use_empty=True)
        bscene = bpy.context.scene
        importer.import_scene(scene, bscene)
        if name == "underwater_objects":
            bscene.photic.denoise = True  # the showcase: 16 spp, denoised (docs/benchmarks.md)
        path = out_dir / f"{name}.blend"
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True)
        written.append(path)
        print(f"wrote {path}")
    if "sediment_plume" in only:
        written += [build_sediment_plume(out_dir), out_dir / "sediment_plume.npz"]
    if "seagrass_meadow" in only:
        written.append(build_seagrass_meadow(out_dir))
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
    parser.add_argument("--only", nargs="+", choices=EXAMPLES, default=None,
                        help="build only these examples (default: all)")
    args = parser.parse_args(argv)
    build(args.out, args.only)


if __name__ == "__main__":
    main()
