"""Export time of Geometry Nodes instances: an ico sphere of 320 triangles instanced on the
points of a grid (Instance on Points), 10^3, 10^4 and 10^5 copies, exported from the evaluated
depsgraph as F12 does (``export.export_scene``).

``new``: the add-on as it is (one mesh and N transforms per instanced mesh). ``old``: every
copy flattened into the world, as the add-on did before instancing (its ``export.py`` and
``export_geometry.py`` read from git at ``--old-rev``, default the last revision before
instancing).

    .venv/bin/python scripts/instancing_export_time.py [--counts 1000 10000 100000] [--repeat 2]
"""
from __future__ import annotations

import argparse
import importlib.util
import math
import subprocess
import sys
import time
from pathlib import Path

import bpy

from photic.cli import load_addon

ROOT = Path(__file__).resolve().parents[1]
# The last revision of blender_addon/export.py and export_geometry.py that flattened every copy.
FLATTENING_REV = "0e60fa3"
addon = load_addon()
from photic_blender import export  # noqa: E402
from photic_blender.batch import ensure_registered  # noqa: E402
from photic_blender.engine_loader import load_engine  # noqa: E402

photic = load_engine()


def old_export(rev: str):
    """The add-on's export of git revision ``rev`` (flattening every copy), as modules of the
    add-on package so their relative imports resolve."""
    def load(name, source):
        spec = importlib.util.spec_from_loader(f"photic_blender.{name}", loader=None)
        module = importlib.util.module_from_spec(spec)
        module.__package__ = "photic_blender"
        sys.modules[spec.name] = module
        exec(compile(source, f"{rev}:{name}.py", "exec"), module.__dict__)
        return module

    def show(path):
        return subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout

    load("_old_export_geometry", show("blender_addon/export_geometry.py"))
    src = show("blender_addon/export.py").replace("from .export_geometry import",
                                                  "from ._old_export_geometry import")
    return load("_old_export", src)


def build(count: int) -> None:
    """A plane whose Geometry Nodes modifier instances an ico sphere (3 subdivisions: 320
    triangles) on the points of a grid of about ``count`` points (the carrier not kept)."""
    ensure_registered()
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "PHOTIC"
    scene.render.resolution_x, scene.render.resolution_y = 32, 32
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, 0, 50)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    mesh = bpy.data.meshes.new("Seabed")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    carrier = bpy.data.objects.new("Seabed", mesh)
    scene.collection.objects.link(carrier)
    side = max(2, math.ceil(math.sqrt(count)))
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n = tree.nodes
    go = n.new("NodeGroupOutput")
    grid = n.new("GeometryNodeMeshGrid")
    grid.inputs["Vertices X"].default_value = grid.inputs["Vertices Y"].default_value = side
    grid.inputs["Size X"].default_value = grid.inputs["Size Y"].default_value = 0.5 * side
    ico = n.new("GeometryNodeMeshIcoSphere")
    ico.inputs["Radius"].default_value = 0.2
    ico.inputs["Subdivisions"].default_value = 3
    iop = n.new("GeometryNodeInstanceOnPoints")
    tree.links.new(grid.outputs["Mesh"], iop.inputs["Points"])
    tree.links.new(ico.outputs["Mesh"], iop.inputs["Instance"])
    tree.links.new(iop.outputs["Instances"], go.inputs[0])
    carrier.modifiers.new("Scatter", "NODES").node_group = tree


def timed(module, repeat: int):
    best, info, scene = math.inf, None, None
    for _ in range(repeat):
        depsgraph = bpy.context.evaluated_depsgraph_get()
        t0 = time.perf_counter()
        scene, info = module.export_scene(depsgraph, photic)
        best = min(best, time.perf_counter() - t0)
    return best, info, scene


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--counts", type=int, nargs="+", default=[1000, 10_000, 100_000])
    p.add_argument("--repeat", type=int, default=2, help="exports of each (the best is printed)")
    p.add_argument("--old-rev", default=FLATTENING_REV, help="git revision of the flattening export")
    p.add_argument("--no-old", action="store_true", help="time the current export only")
    args = p.parse_args(argv)
    old = None if args.no_old else old_export(args.old_rev)
    print(f"{'copies':>8} {'triangles':>11} {'new s':>8} {'old s':>8} {'old/new':>8}  new scene")
    for count in args.counts:
        build(count)
        t_new, info, scene = timed(export, args.repeat)
        copies = sum(m.copies for m in scene.meshes)
        line = f"{copies:8d} {info.triangles:11d} {t_new:8.3f}"
        if old is not None:
            t_old, old_info, _ = timed(old, args.repeat)
            assert old_info.triangles == info.triangles
            line += f" {t_old:8.3f} {t_old / t_new:8.1f}"
        else:
            line += f" {'':>8} {'':>8}"
        shapes = ", ".join(f"{m.name}: {len(m.mesh.triangles)} tris x {m.copies}" for m in scene.meshes)
        print(f"{line}  {shapes}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
