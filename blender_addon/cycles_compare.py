"""Cycles on a Photic scene: the baseline of ``photic bench --error``.

The scene's objects come from the importer; Cycles gets its own nodes for them: Diffuse BSDFs
with the materials' reflectances (the bands nearest to red, green and blue), and for each water
mesh a smooth Glass BSDF at the water's index over a homogeneous volume with its absorption,
scattering and a Henyey-Greenstein phase function (Cycles has no tabulated phase function: HG
with the water's g, or 0.9 for Petzold and Fournier-Forand). Sun and sky keep their radiometric
values (a Blender sun's strength is its irradiance in W m^-2; a world's colour times strength is
the sky's radiance). Rendered on the CPU without denoising or adaptive sampling, each sample
count in a fresh render, so the time per sample is measured the way Photic's is.

Run in a separate process (``photic.bench`` starts it when ``bpy`` is importable):

    python cycles_compare.py SCENE.json --camera under --resolution 256 256 \
        --samples 16 64 --threads 2 --exr out/cycles.exr

prints one JSON object: cpu and wall seconds per sample count, the marginal CPU seconds per
sample, and the EXR (linear RGB radiance) of the largest count.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np


def _rgb_indices(bands) -> list[int]:
    """Indices of the bands nearest to 610, 550 and 465 nm (red, green, blue)."""
    centres = np.array([b.center_nm for b in bands], float)
    return [int(np.argmin(np.abs(centres - c))) for c in (610.0, 550.0, 465.0)]


def _diffuse(name, rgb):
    import bpy

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*[float(c) for c in rgb], 1.0)
    links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _water(name, ior, absorption, scattering, g):
    """Glass surface over a volume: absorption and scattering coefficients per RGB channel."""
    import bpy

    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    glass = nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = float(ior)
    glass.inputs["Roughness"].default_value = 0.0
    links.new(glass.outputs["BSDF"], out.inputs["Surface"])
    # Cycles: sigma_a = density (1 - colour) for Volume Absorption, sigma_s = density colour for
    # Volume Scatter.
    add = nodes.new("ShaderNodeAddShader")
    va = nodes.new("ShaderNodeVolumeAbsorption")
    da = max(float(np.max(absorption)), 1e-12)
    va.inputs["Density"].default_value = da
    va.inputs["Color"].default_value = (*[1.0 - float(a) / da for a in absorption], 1.0)
    vs = nodes.new("ShaderNodeVolumeScatter")
    ds = max(float(np.max(scattering)), 1e-12)
    vs.inputs["Density"].default_value = ds if np.max(scattering) > 0 else 0.0
    vs.inputs["Color"].default_value = (*[float(b) / ds for b in scattering], 1.0)
    vs.inputs["Anisotropy"].default_value = float(g)
    links.new(va.outputs["Volume"], add.inputs[0])
    links.new(vs.outputs["Volume"], add.inputs[1])
    links.new(add.outputs["Shader"], out.inputs["Volume"])
    return mat


def _phase_g(phase) -> float:
    if phase.type == "henyey_greenstein":
        return float(phase.params["g"])
    if phase.type in ("petzold", "fournier_forand"):
        return 0.9
    return 0.0


def build(scene, camera: str, resolution, threads: int, full_bounces: bool = False):
    """The Photic ``scene`` as a Cycles scene in a fresh file; returns the Blender scene."""
    import bpy

    from photic_blender.batch import ensure_registered
    from photic_blender.importer import import_scene

    bpy.ops.wm.read_factory_settings(use_empty=True)
    ensure_registered()
    bscene = bpy.context.scene
    created = import_scene(scene, bscene)
    rgb = _rgb_indices(scene.bands)
    for m in scene.meshes:
        refl = np.atleast_1d(np.asarray(scene.materials[m.material].reflectance, float))
        refl = refl if refl.size > 1 else np.repeat(refl, len(scene.bands))
        obj = created[m.name]
        obj.data.materials.clear()
        obj.data.materials.append(_diffuse(f"cycles_{m.material}", refl[rgb]))
    for w in scene.water:
        if w.type != "mesh":
            raise ValueError(f"water {w.name!r}: the Cycles comparison takes water meshes only")
        a = np.asarray(w.iops.absorption, float)
        b = np.asarray(w.iops.total_scattering, float)
        comps = w.iops.scattering
        g = _phase_g(comps[0].phase) if comps else 0.0
        obj = created[w.name]
        obj.display_type = "TEXTURED"
        obj.data.materials.clear()
        obj.data.materials.append(_water(f"cycles_{w.name}", w.ior, a[rgb], b[rgb], g))
    if scene.sun is not None:
        sun = created["Sun"].data
        e = np.asarray(scene.sun.irradiance, float)
        e = e[rgb] if e.size > 1 else np.repeat(e, 3)
        sun.color, sun.energy = tuple(e / max(e.max(), 1e-30)), float(e.max())
    world = bscene.world
    world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    if scene.sky.type == "black":
        bg.inputs["Strength"].default_value = 0.0
    else:
        if scene.sky.type != "uniform":
            raise ValueError("the Cycles comparison takes a black or uniform sky")
        radiance = np.asarray(scene.sky.radiance_scale, float)
        radiance = radiance[rgb] if radiance.size > 1 else np.repeat(radiance, 3)
        top = float(radiance.max())
        bg.inputs["Color"].default_value = (*[float(r / top) if top > 0 else 0.0 for r in radiance], 1.0)
        bg.inputs["Strength"].default_value = top
    bscene.camera = created[camera]
    r = bscene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y = int(resolution[0]), int(resolution[1])
    r.resolution_percentage = 100
    r.threads_mode = "FIXED"
    r.threads = int(threads)
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    bscene.view_settings.view_transform = "Standard"
    cy = bscene.cycles
    cy.device = "CPU"
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = 1
    if full_bounces:  # the light transport Photic computes: no bounce limit short of its own
        for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                     "volume_bounces", "transparent_max_bounces"):
            setattr(cy, attr, scene.settings.max_depth)
    return bscene


def render(scene_path: str, camera: str, resolution, samples, threads: int, exr: str | None,
           full_bounces: bool = False) -> dict:
    from photic.cli import load_addon
    from photic.scene import load_scene

    import bpy

    load_addon()
    scene = load_scene(scene_path)
    bscene = build(scene, camera, resolution, threads, full_bounces)
    runs = []
    for i, n in enumerate(sorted(samples)):
        bscene.cycles.samples = int(n)
        last = i == len(samples) - 1
        if last and exr:
            bscene.render.filepath = str(Path(exr).with_suffix(""))
        c0, w0 = time.process_time(), time.perf_counter()
        bpy.ops.render.render(write_still=bool(last and exr))
        runs.append({"samples": int(n), "cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0})
    out = {"runs": runs, "version": bpy.app.version_string, "exr": None}
    if len(runs) >= 2:
        a, b = runs[0], runs[-1]
        out["cpu_s_per_spp"] = (b["cpu_s"] - a["cpu_s"]) / (b["samples"] - a["samples"])
        out["wall_s_per_spp"] = (b["wall_s"] - a["wall_s"]) / (b["samples"] - a["samples"])
    else:
        out["cpu_s_per_spp"] = runs[0]["cpu_s"] / runs[0]["samples"]
        out["wall_s_per_spp"] = runs[0]["wall_s"] / runs[0]["samples"]
    if exr:
        written = Path(str(Path(exr).with_suffix("")) + ".exr")
        if written.exists() and written != Path(exr):
            written.replace(exr)
        out["exr"] = str(exr) if Path(exr).exists() else None
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("--camera", required=True)
    p.add_argument("--resolution", type=int, nargs=2, default=(256, 256))
    p.add_argument("--samples", type=int, nargs="+", default=[16, 64])
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--exr", default=None)
    p.add_argument("--full-bounces", action="store_true",
                   help="raise Cycles' bounce limits to the scene's max_depth (Photic's light transport)")
    args = p.parse_args(argv)
    out = render(args.scene, args.camera, args.resolution, args.samples, args.threads, args.exr,
                 args.full_bounces)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
