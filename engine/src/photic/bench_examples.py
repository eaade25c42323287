"""``photic bench --error --cases examples``: every example scene's image, time to 5 % error
and whether its error bars are honest.

Every scene with a camera in ``examples/*.json`` and ``example_blends/*.blend`` (the .blend
files through Blender's ``bpy`` module and the add-on's export, in a separate process; skipped
without bpy) is rendered by its first camera at ``width`` pixels across (its aspect kept), with
the file's own settings (hybrid, its forward cone, its sun-disk blur), so no scene is tuned
alone. Per scene:

- a reference at ``ref_spp`` samples per pixel (its own variance removed from every error);
- renders at doubling ``budgets`` (samples per pixel), each: wall time, the image's RMS error
  relative to the reference's mean (error^2 = raw^2 - the reference's noise^2), the median lit
  pixel's reported relative standard error, and the share of the image's variance in its
  noisiest 0.1 % of pixels (fireflies);
- the time to 5 % of each (log-log interpolation, or extrapolated as t^-1/2 beyond the largest
  budget, flagged);
- the error bars' honesty: ``seeds`` renders at ``seed_spp``, the RMS of their image errors
  over the RMS of their reported image errors (the target band is 0.7-1.5; heavy tails that the
  reported variance misses read below 0.7 only rarely, above 1.5 when it underestimates).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .scene import Scene

REPO = Path(__file__).resolve().parents[3]
ERROR_TARGET = 0.05
DEFAULT_EXAMPLES_PLOT = Path("docs") / "images" / "bench_examples.png"

# Converts .blend files to scene JSON in a separate process (bpy changes global state; the
# benchmark's own process stays without it). argv: output folder, then the .blend files.
_EXPORT_SCRIPT = r"""
import sys
from pathlib import Path
import bpy
from photic.addon import load_addon
load_addon()
import photic
from photic_blender import batch
from photic_blender.export import export_scene
from photic.scene.files import save_scene
out = Path(sys.argv[1])
for path in sys.argv[2:]:
    batch.open_blend(path)
    scene, _ = export_scene(bpy.context.evaluated_depsgraph_get(), photic)
    save_scene(scene, out / (Path(path).stem + ".json"))
    print("exported", path)
"""


@dataclass
class ExampleScene:
    name: str      # the file's name
    source: str    # the file, relative to the repository
    scene: Scene
    file_resolution: tuple[int, int]  # the camera's resolution in the file


def bpy_available() -> bool:
    import importlib.util
    return importlib.util.find_spec("bpy") is not None


def _with_camera(d: dict, width: int) -> tuple[dict, tuple[int, int]] | None:
    cams = d.get("cameras") or []
    if not cams:
        return None
    cam = dict(cams[0])
    w0, h0 = (int(v) for v in cam.get("resolution", [width, width]))
    cam["resolution"] = [int(width), max(1, int(round(width * h0 / w0)))]
    d = dict(d, cameras=[cam], radiometers=[], radiometer_arrays=[])
    return d, (w0, h0)


def example_scenes(width: int = 240, root: Path = REPO, blends: bool = True, progress=None) -> list[ExampleScene]:
    """The example scenes with a camera, their first camera at ``width`` pixels across."""
    say = progress or (lambda msg: None)
    found: list[tuple[str, str, dict]] = []
    for path in sorted((root / "examples").glob("*.json")):
        found.append((path.name, str(path.relative_to(root)), json.loads(path.read_text())))
    blend_files = sorted((root / "example_blends").glob("*.blend")) if blends else []
    if blend_files and not bpy_available():
        say("no bpy: the .blend examples are not measured")
        blend_files = []
    if blend_files:
        with tempfile.TemporaryDirectory() as tmp:
            run = subprocess.run([sys.executable, "-c", _EXPORT_SCRIPT, tmp, *map(str, blend_files)],
                                 cwd=root, capture_output=True, text=True, timeout=900)
            if run.returncode != 0:
                raise RuntimeError(f"exporting the example .blend files failed:\n{run.stderr[-2000:]}")
            for path in blend_files:
                out = Path(tmp) / (path.stem + ".json")
                found.append((path.name, str(path.relative_to(root)), json.loads(out.read_text())))
    scenes = []
    for name, source, d in found:
        picked = _with_camera(d, width)
        if picked is None:
            continue
        d, res = picked
        scenes.append(ExampleScene(name, source, Scene.from_dict(d, base_dir=root / Path(source).parent), res))
    return scenes


def _render(scene: Scene, spp: int, seed: int, threads: int):
    from .render import render

    res = render(scene, samples=spp, seed=seed, threads=threads)
    img = next(iter(res.images.values()))
    return float(res.stats["time_s"]), img.mean, img.variance


def image_errors(values, var, ref, ref_var) -> dict:
    """Errors of one render against the reference (all relative to the reference's mean).

    ``rms``: sqrt(mean((x - ref)^2) - mean(ref_var)) / mean(ref) (the reference's own noise
    removed, floored at 0); ``reported``: sqrt(mean(var)) / mean(ref), what the render says its
    RMS error is; ``median_pixel``: the median over lit pixels (above 5 % of the mean) of
    sqrt(var) / ref; ``top_0.1``: the share of the image's reported variance in its noisiest
    0.1 % of pixels."""
    from .bench import image_relative_error

    m = float(np.mean(ref))
    rms, rms_raw, ref_noise = image_relative_error(values, ref, ref_var)
    lit = ref > 0.05 * m
    rel = np.sqrt(np.maximum(var[lit], 0.0)) / ref[lit]
    v = np.sort(var.ravel())[::-1]
    total = float(v.sum())
    return {"rms": rms, "rms_raw": rms_raw, "ref_noise": ref_noise,
            "reported": math.sqrt(float(np.mean(var))) / m,
            "median_pixel": float(np.median(rel)) if rel.size else float("nan"),
            "top_0.1": float(v[:max(1, v.size // 1000)].sum() / total) if total > 0 else 0.0}


def time_to(budgets: list[dict], key: str, target: float = ERROR_TARGET) -> dict:
    """When ``key``'s error reaches ``target`` for good (as bench.time_to_error), or the time
    extrapolated as t^-1/2 from the largest budget (``extrapolated``: True)."""
    from .bench import time_to_error

    recs = [{"budget": b["spp"], "seconds": b["seconds"], "rel_error": b[key]} for b in budgets]
    tt = time_to_error(recs, target)
    if tt["seconds"] is not None:
        return {"seconds": tt["seconds"], "extrapolated": False, "bound": tt["bound"]}
    return {"seconds": tt["extrapolated"], "extrapolated": True, "bound": False}


def run_examples_bench(width: int = 240, ref_spp: int = 256, budgets=(4, 8, 16, 32, 64), seeds: int = 12,
                       seed_spp: int = 8, threads: int = 2, blends: bool = True, names=None,
                       plot: str | Path | None = DEFAULT_EXAMPLES_PLOT, print_table: bool = True,
                       progress=None) -> list[dict]:
    """One record per example scene (see the module's docstring); prints the table and writes
    the plot of error against time unless told not to."""
    say = progress or (lambda msg: None)
    if min(*budgets, seed_spp, ref_spp) < 2:
        raise ValueError("every render needs at least 2 samples per pixel (a pixel's variance is estimated "
                         "from its samples)")
    records = []
    for ci, ex in enumerate(example_scenes(width, blends=blends, progress=progress)):
        if names and ex.name not in names:
            continue
        t_ref, ref, ref_var = _render(ex.scene, ref_spp, 700_001 + ci, threads)
        say(f"{ex.name}: reference {ref_spp} spp in {t_ref:.1f} s")
        runs = []
        for bi, spp in enumerate(budgets):
            t, x, v = _render(ex.scene, spp, 710_000 + 100 * ci + bi, threads)
            runs.append(dict(spp=int(spp), seconds=t, **image_errors(x, v, ref, ref_var)))
            say(f"{ex.name}: {spp} spp in {t:.1f} s, image error {100 * runs[-1]['rms']:.1f} %")
        errs, reported = [], []
        for s in range(seeds):
            _, x, v = _render(ex.scene, seed_spp, 720_000 + 100 * ci + s, threads)
            e = image_errors(x, v, ref, ref_var)
            errs.append(e["rms"])
            reported.append(e["reported"])
        ratio = math.sqrt(np.mean(np.square(errs))) / math.sqrt(np.mean(np.square(reported)))
        say(f"{ex.name}: {seeds} seeds' error / reported {ratio:.2f}")
        h, w = ref.shape[:2]
        records.append({"scene": ex.name, "source": ex.source, "resolution": [w, h],
                        "file_resolution": list(ex.file_resolution), "ref_spp": ref_spp, "ref_seconds": t_ref,
                        "ref_noise": runs[0]["ref_noise"], "budgets": runs,
                        "time_to_5pct_rms": time_to(runs, "rms"), "time_to_5pct_median": time_to(runs, "median_pixel"),
                        "seeds": seeds, "seed_spp": seed_spp, "seed_errors": errs, "seed_reported": reported,
                        "error_bar_ratio": float(ratio)})
    if print_table:
        print(format_examples_table(records))
    if plot and records:
        plot_examples(records, plot)
        if print_table:
            print(f"plot: {plot}")
    return records


def _t(tt: dict) -> str:
    if tt["seconds"] is None:
        return "n/a"
    return ("~" if tt["extrapolated"] else "<=" if tt["bound"] else "") + f"{tt['seconds']:.3g} s"


def format_examples_table(records: list[dict]) -> str:
    lines = ["Every example's image (its first camera, hybrid, the file's settings): time to 5 % image RMS "
             "error and median pixel error, ~: extrapolated as t^-1/2 beyond the largest budget",
             f"  {'scene':<22} {'pixels':>9} {'spp':>5} {'s':>7} {'RMS err':>8} {'median px':>9} {'top 0.1%':>8}"]
    for r in records:
        for b in r["budgets"]:
            lines.append(f"  {r['scene']:<22} {r['resolution'][0]:>4}x{r['resolution'][1]:<4} {b['spp']:>5} "
                         f"{b['seconds']:>7.2f} {100 * b['rms']:>7.2f}% {100 * b['median_pixel']:>8.2f}% "
                         f"{100 * b['top_0.1']:>7.1f}%")
    lines.append("")
    lines.append(f"  {'scene':<22} {'to 5 % RMS':>11} {'to 5 % median':>13} {'error bars (spread / reported)':>31}")
    for r in records:
        lines.append(f"  {r['scene']:<22} {_t(r['time_to_5pct_rms']):>11} {_t(r['time_to_5pct_median']):>13} "
                     f"{r['error_bar_ratio']:>10.2f} ({r['seeds']} seeds at {r['seed_spp']} spp)")
    lines.append("  times are wall seconds of the render at the bench's resolution on this machine; "
                 "the reference's own noise is removed from the errors (error^2 = raw^2 - noise^2)")
    return "\n".join(lines)


def plot_examples(records: list[dict], path: str | Path) -> Path:
    from .plots import loglog_panels, save_figure

    panels = []
    for r in records:
        t = [b["seconds"] for b in r["budgets"]]  # (errors are finite: every render had 2+ spp)
        panels.append({"title": f"{r['scene']} {r['resolution'][0]}x{r['resolution'][1]}", "xlabel": "time (s)",
                       "ylabel": "relative error", "percent": True, "legend": True,
                       "series": [("image RMS error", t, [max(b["rms"], 1e-4) for b in r["budgets"]], (40, 90, 215)),
                                  ("median pixel error", t, [max(b["median_pixel"], 1e-4) for b in r["budgets"]],
                                   (30, 150, 60))],
                       "hlines": [(ERROR_TARGET, (110, 110, 110), "5%"),
                                  (max(r["ref_noise"], 1e-4), (170, 170, 170), "reference noise")]})
    return save_figure(loglog_panels(panels), path)
