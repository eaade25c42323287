"""Command line: ``photic render``, ``photic derive``, ``photic bench`` and others (also ``python -m photic``)."""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
from pathlib import Path


import numpy as np

from .addon import find_addon, load_addon  # noqa: F401  (photic.cli.load_addon: tests, tools)


def _format_value(v: float, e: float) -> str:
    return f"{v:.6g} +- {e:.2g}"


def radiometer_table(result) -> str:
    """Closing table: one line per radiometer and band (distributions summarised). A standard
    error that cannot be trusted (photic.estimates: too few passes, heavy tails) is marked with
    '?' and the reason is given under the table."""
    lines = [f"{'radiometer':<28} {'quantity':<22} {'medium':<10} {'band':<8} {'value +- stderr':<28} {'rel.err':>9}"]
    flagged = {}
    for r in result.radiometers:
        for k, band in enumerate(result.bands):
            if r.bins:
                v, e = float(r.mean[:, k].mean()), float((r.stderr[:, k] ** 2).mean() ** 0.5 / r.mean.shape[0] ** 0.5)
                label = f"{r.quantity} (mean of {r.mean.shape[0]} bins)"
            else:
                v, e = float(r.mean[0, k]), float(r.stderr[0, k])
                label = r.quantity
            trusted = r.reliable is None or bool(np.all(r.reliable[:, k]))
            if not trusted:
                flagged[r.name] = r.notes
            rel = (f"{100 * e / abs(v):.2f}%" if v else "-") + ("" if trusted else "?")
            lines.append(f"{r.name:<28} {label:<22} {r.medium:<10} {band.name:<8} {_format_value(v, e):<28} {rel:>9}")
    if flagged:
        lines.append("? standard error not to be trusted (more samples, or a forward cone, help):")
        for name, notes in flagged.items():
            lines.append(f"    {name}: {', '.join(notes) or 'see the tables'}")
    return "\n".join(lines)


def _write_beam_mesh(scene, path, threads) -> int:
    """--beam-mesh: build the beams once for the sun's central direction and write their
    footprints. Returns an exit status (1 with a message when there is nothing to write)."""
    from .compile import compile_scene, scene_band_groups
    from .footprints import write_footprints

    group = scene_band_groups(scene)[0]
    core = compile_scene(scene, group, hybrid=True, forward_cone_deg=0)
    core.build_beams(tuple(float(c) for c in scene.sun.direction), int(threads or 0))
    if core.beam_count == 0:
        why = ("the flat ocean surface refracts the sun as one analytic beam, which has no prisms"
               if core.has_flat_beam else "no triangulated water surface is lit by the sun")
        print(f"photic: --beam-mesh: scene {scene.name} has no beams ({why}); nothing written",
              file=sys.stderr)
        return 1
    try:
        out = write_footprints(path, core)
    except (OSError, ValueError) as e:
        print(f"photic: --beam-mesh: cannot write {path}: {e}", file=sys.stderr)
        return 1
    note = ("; face properties phi = flux entering the water per prism, before attenuation, "
            "area = footprint area in m^2" if out.suffix.lower() == ".ply" else "")
    print(f"beam footprints: {out} ({core.beam_count} prisms, flux entering the water "
          f"{core.beam_total_flux():.6g} in band {scene.bands[0].name}{note})")
    return 0


def relative_error_arg(text: str) -> float:
    """--target-error: '1%' or 0.01 (a fraction), between 0 and 1 exclusive."""
    t = text.strip()
    try:
        v = float(t[:-1]) / 100.0 if t.endswith("%") else float(t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a relative error such as 1% or 0.01, got {text!r}")
    if not 0.0 < v < 1.0:
        raise argparse.ArgumentTypeError(f"must be between 0 and 100 % (0 and 1), got {text!r}")
    return v


def noise_summary(result) -> list[str]:
    """A line per camera of an adaptive render (settings.noise_threshold): how many pixels
    reached the threshold, and their samples."""
    lines = []
    for name, img in result.images.items():
        if img.noise_threshold is None or img.pixel_samples is None:
            continue
        ps = img.pixel_samples
        lines.append(f"camera {name}: noise threshold {100 * img.noise_threshold:.3g} % reached by "
                     f"{100 * float(np.mean(img.converged)):.1f} % of pixels; samples per pixel "
                     f"{int(ps.min())}-{int(ps.max())}, mean {float(ps.mean()):.1f} (at most {img.samples})")
    return lines


def target_summary(result) -> str | None:
    """One line on the target error of an adaptive render (None without one)."""
    st = result.stats
    if st.get("target_error") is None or not result.radiometers:
        return None
    rs = result.radiometers
    worst = max(r.relative_error for r in rs)
    samples = sorted(r.samples for r in rs)
    return (f"target error {100 * st['target_error']:.3g} %: reached by {st['target_reached']} of "
            f"{len(rs)} radiometers in {st['rounds']} rounds (worst {100 * worst:.3g} %; "
            f"{samples[0]}-{samples[-1]} samples, at most {st['radiometer_samples']})")


def cmd_render(args) -> int:
    from .output import check_output_dir, check_output_files, write_outputs
    from .render import Renderer
    from .scene import SceneError, load_scene

    try:
        check_output_dir(args.out)
    except OSError as e:
        print(f"photic: {e}", file=sys.stderr)
        return 2
    try:
        scene = load_scene(args.scene)
        if args.integrator:
            scene.settings.integrator = args.integrator
        if args.forward_cone is not None:
            scene.settings.forward_cone_deg = args.forward_cone if args.forward_cone == "auto" else float(args.forward_cone)
        if args.target_error is not None:
            scene.settings.target_error = args.target_error
        if args.noise_threshold is not None:
            scene.settings.noise_threshold = args.noise_threshold
        renderer = Renderer(scene, samples=args.samples, radiometer_samples=args.radiometer_samples,
                            seed=args.seed, threads=args.threads)
    except SceneError as e:
        print(f"photic: invalid scene {args.scene}: {e}", file=sys.stderr)
        return 2
    except (OSError, ValueError) as e:
        print(f"photic: cannot load {args.scene}: {e}", file=sys.stderr)
        return 2
    try:
        check_output_files(args.out, scene)
    except OSError as e:
        print(f"photic: {e}", file=sys.stderr)
        return 2
    if args.beam_mesh is not None and scene.sun is None:
        print(f"photic: --beam-mesh: scene {scene.name} has no sun, so no beams", file=sys.stderr)
        return 2

    # Ctrl-C cancels cleanly: the render stops within a piece of a pass (a few tens of ms) and
    # what is done is written; a second Ctrl-C interrupts at once (the writing too).
    def on_sigint(*_):
        renderer.cancel()
        print("\nphotic: stopping; writing the partial result (Ctrl-C again to abort)",
              file=sys.stderr, flush=True)
        signal.signal(signal.SIGINT, signal.default_int_handler)

    signal.signal(signal.SIGINT, on_sigint)
    bar = None
    if not args.quiet:
        from tqdm import tqdm
        bar = tqdm(total=1000, desc=f"rendering {scene.name}", unit="‰", file=sys.stderr,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining} {postfix}")

    def progress(frac, msg):
        if bar is not None:
            bar.n = int(1000 * frac)
            bar.set_postfix_str(msg, refresh=False)
            bar.refresh()

    try:
        result = renderer.run(progress)
    except SceneError as e:  # found when the scene is built (e.g. a sensor on a boundary)
        if bar is not None:
            bar.close()
        print(f"photic: invalid scene {args.scene}: {e}", file=sys.stderr)
        return 2
    if bar is not None:
        bar.close()
    for w in result.warnings:
        print(f"photic: warning: {w}", file=sys.stderr)
    written = write_outputs(args.out, result)
    st = result.stats
    integ = st.get("integrator", "path")
    if integ == "hybrid":
        integ += f", forward cone {st.get('forward_cone_deg', 0.0):g} deg"
    print(f"scene {scene.name}: {integ}; {st['paths']} paths, {st['segments']} segments in {st['time_s']:.2f} s "
          f"({st['segments_per_s'] / 1e6:.2f} M segments/s, {st['threads']} threads, seed {st['seed']})"
          + ("  [CANCELLED: partial result]" if result.cancelled else ""))
    if result.radiometers:
        print(radiometer_table(result))
        line = target_summary(result)
        if line:
            print(line)
    for line in noise_summary(result):
        print(line)
    for p in written["images"]:
        print(f"image: {p}")
    for p in written["tables"]:
        print(f"radiometer table: {p}")
    for f in written["failed"]:
        print(f"photic: {f}", file=sys.stderr)
    status = 130 if result.cancelled else (1 if written["failed"] else 0)
    if args.beam_mesh is not None and not result.cancelled:
        status = _write_beam_mesh(scene, args.beam_mesh, renderer.threads) or status
    return status


def cmd_bench(args) -> int:
    if args.large:
        from .bench_large import run_large_cli
        return run_large_cli(args)
    if args.error:
        from .bench import DEFAULT_ERROR_PLOT, SPEED_CASES, run_speed_bench
        say = None if args.json else (lambda msg: print(msg, file=sys.stderr, flush=True))
        plot = str(DEFAULT_ERROR_PLOT) if args.plot is None else args.plot
        cases = args.cases.split(",") if args.cases else list(SPEED_CASES)
        unknown = set(cases) - set(SPEED_CASES)
        if unknown:
            print(f"photic bench: unknown --cases {sorted(unknown)} (known: {','.join(SPEED_CASES)})",
                  file=sys.stderr)
            return 2
        out = run_speed_bench(cases, quick=args.quick, threads=max(args.threads), plot=plot or None,
                              print_table=not args.json, progress=say)
        if "examples" in cases:  # every example's image (photic.bench_examples)
            from .bench_examples import DEFAULT_EXAMPLES_PLOT, run_examples_bench
            kw = (dict(width=48, ref_spp=16, budgets=(2, 4), seeds=4, seed_spp=2) if args.quick
                  else dict(width=args.examples_width))
            out["examples"] = run_examples_bench(threads=max(args.threads), progress=say, print_table=not args.json,
                                                 plot=DEFAULT_EXAMPLES_PLOT if plot else None, **kw)
        if args.json:
            print(json.dumps(out, indent=1, default=float))
        return 0
    from .bench import run_bench
    records = run_bench(quick=args.quick, threads=args.threads, seconds=args.seconds, print_table=not args.json)
    if args.json:
        print(json.dumps(records, indent=1))
    return 0


def cmd_problems(args) -> int:
    from .problems import CONFIGS, format_records, problem_scene, reference_table, run_problem
    from .scene import Scene, load_scene

    refs = reference_table()
    records = []
    for problem, omega0 in CONFIGS:
        if args.problem and problem not in args.problem:
            continue
        # The problems' definitions (examples/problems holds the same scenes as files, tested
        # equal); --scenes: files of that name in a folder instead.
        path = None if args.scenes is None else Path(args.scenes) / f"mobley1993_problem{problem}_omega{omega0:g}.json"
        scene = load_scene(path) if path is not None else Scene.from_dict(problem_scene(problem, omega0))
        cone = None if args.forward_cone is None else (args.forward_cone if args.forward_cone == "auto" else float(args.forward_cone))
        records += run_problem(scene, problem, omega0, refs, samples=args.samples, threads=args.threads,
                               forward_cone_deg=cone, adaptive=not args.fixed)
        if not args.json:
            print(f"problem {problem}, omega0 {omega0:g}: done in {records[-1]['seconds']:.1f} s", file=sys.stderr)
    if args.json:
        print(json.dumps(records, indent=1))
    else:
        print(format_records(records))
    return 0 if all(r["passed"] for r in records) else 1


def cmd_derive(args) -> int:
    from .derived import DerivedError, derive, derived_rows, format_table, load_table, write_derived_csv

    try:
        table = load_table(args.table)
        rrs = None
        if args.rrs:
            extra = {"sky": args.sky, "rho": args.rho, "reflected": args.reflected}
            rrs = [{"lu": lu, "ed": ed, **{k: v for k, v in extra.items() if v is not None}} for lu, ed in args.rrs]
        elif args.sky or args.rho is not None or args.reflected:
            raise DerivedError("--sky, --rho and --reflected apply to the radiometers named by --rrs")
        derived = derive(table, rrs=rrs, fit=not args.no_fit)
    except OSError as e:
        print(f"photic derive: cannot read {args.table}: {e}", file=sys.stderr)
        return 2
    except DerivedError as e:
        print(f"photic derive: {e}", file=sys.stderr)
        return 2
    out_dir = args.out if args.out is not None else args.table.parent
    csv_path = write_derived_csv(out_dir / f"{args.table.stem}_derived.csv", derived, table.bands,
                                 header=f"scene {table.scene}; from {args.table.name}")
    if args.json:
        rows = [{k: (None if isinstance(v, float) and v != v else v) for k, v in row.items()}  # NaN -> null
                for row in derived_rows(derived, table.bands)]
        print(json.dumps(rows, indent=1))
    else:
        if table.cancelled:
            print("note: the render was cancelled; the values hold the passes finished", file=sys.stderr)
        print(format_table(derived, table.bands) if derived else
              "no derived quantities: no profiles, no radiometers sharing a position, no Lu/Ed above water")
        print(f"derived table: {csv_path}")
    return 0


def cmd_blend(args) -> int:
    """``photic blend ...``: the add-on package's command (``photic-blend``), which renders
    through Blender; the engine only hands the arguments over when the package is installed."""
    import importlib.util
    if importlib.util.find_spec("bpy") is None:
        print("photic blend: the bpy module is needed; install it with 'pip install bpy==5.0.*' "
              "(Python 3.11)", file=sys.stderr)
        return 2
    if importlib.util.find_spec("photic_blender") is None:
        print("photic blend: the Blender add-on package is not installed (pip install -e "
              "./blender_addon; scripts/install.sh does it)", file=sys.stderr)
        return 2
    from photic_blender.cli import main as blend_main
    return blend_main(args.args)


def cmd_batch(args) -> int:
    from .distributed import JobError, SchedulerError, load_job, run_job

    try:
        job = load_job(args.job)
    except JobError as exc:
        print(f"photic batch: {exc}", file=sys.stderr)
        return 2
    except (FileNotFoundError, RuntimeError) as exc:  # .blend inputs: bpy or the add-on missing
        print(f"photic batch: {exc}", file=sys.stderr)
        return 2
    try:
        report = run_job(job, args.out, scheduler=args.scheduler, workers=args.workers,
                         threads=args.threads, progress=not args.quiet, fresh=args.fresh)
    except KeyboardInterrupt:
        print("photic batch: interrupted; the finished units are kept: run the same command "
              "again to resume", file=sys.stderr)
        return 130
    except SchedulerError as exc:  # not a Dask scheduler, no workers, a bad --workers
        print(f"photic batch: {exc}", file=sys.stderr)
        return 2
    except (OSError, TimeoutError) as exc:  # the scheduler did not answer, or a file failed
        what = f"cannot reach the Dask scheduler {args.scheduler} or" if args.scheduler else "cannot"
        print(f"photic batch: {what} write the results: {exc}", file=sys.stderr)
        return 2
    for name, s in report.items.items():
        err = s.get("worst_rel_stderr")
        extra = f", worst radiometer rel. error {100 * err:.3g}%" if err is not None else ""
        if s.get("rounds", 1) > 1:
            extra += f", {s['rounds']} rounds"
        print(f"{name}: {s['status']}{extra}")
        for f in s["files"]:
            print(f"  {f}")
    failed = f", {len(report.failed)} failed (run again to retry them)" if report.failed else ""
    print(f"{len(report.computed)} units computed, {len(report.skipped)} reused from "
          f"{report.out / 'units'}{failed}")
    print(f"{report.executor}; {report.wall_s:.1f} s; summary: {report.out / 'summary.json'}")
    return 0 if report.ok else 1


def cmd_plugins(args) -> int:
    from . import plugins
    for kind, group in plugins.GROUPS.items():
        found = plugins.available(kind)
        print(f"{group}: " + (", ".join(f"{n} ({ep.value})" for n, ep in sorted(found.items())) or "none"))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="photic",
        description="Photic: physically based light in natural waters. Renders scene files "
                    "(JSON, see docs/scene-format.md) to multilayer EXR images in radiance units "
                    "and radiometer tables with Monte Carlo standard errors.")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a scene file",
                       description="Render SCENE: writes <scene>_<camera>.exr for every camera "
                                   "(radiance.<band>, variance.<band>, samples) and "
                                   "<scene>_radiometers.csv/.json for the radiometers, then "
                                   "prints a table of radiometer values with standard errors. "
                                   "With the hybrid integrator the EXR also holds the component "
                                   "passes beam_surface.<band>, beam_volume.<band>, path.<band> "
                                   "and the tables value_<component>/stderr_<component> columns "
                                   "(they sum to the total). "
                                   "Ctrl-C stops after the current pass and writes what is done.")
    r.add_argument("scene", type=Path, help="scene file (.json)")
    r.add_argument("--out", type=Path, default=Path("out"), help="output directory (default: out)")
    r.add_argument("--samples", type=int, default=None, help="camera samples per pixel (default: the scene's)")
    r.add_argument("--radiometer-samples", type=int, default=None,
                   help="samples per radiometer (default: the scene's); with --target-error the "
                        "most any radiometer takes")
    r.add_argument("--target-error", type=relative_error_arg, default=None, metavar="REL",
                   help="stop each radiometer when its relative standard error (the worst of its "
                        "bins and bands) is at most REL, e.g. 1%% or 0.01, and its error can be "
                        "trusted (default: the scene's settings.target_error)")
    r.add_argument("--noise-threshold", type=relative_error_arg, default=None, metavar="REL",
                   help="adaptive sampling: stop each pixel when its relative standard error is at "
                        "most REL in every band (e.g. 2%% or 0.02; after settings."
                        "adaptive_min_samples), --samples then being the most a pixel takes "
                        "(default: the scene's settings.noise_threshold)")
    r.add_argument("--seed", type=int, default=None, help="random seed (default: the scene's)")
    r.add_argument("--integrator", choices=["auto", "hybrid", "path"], default=None,
                   help="hybrid (the refracted sun as beams), path (pure path tracing) or auto "
                        "(hybrid when there is a sun); default: the scene's")
    r.add_argument("--forward-cone", default=None,
                   help="forward-scattering cone half-angle in degrees kept in the beams, or auto; default: the scene's")
    r.add_argument("--threads", type=int, default=None, help="threads, 0 = all cores (default: the scene's)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--beam-mesh", type=Path, default=None, metavar="PATH",
                   help="after rendering, build the beams once for the sun's central direction "
                        "and write their footprints (where each beam prism ends on the bottom or "
                        "an object) as a triangle mesh: .ply (face properties phi = flux entering "
                        "the water per prism, W in band 0, before attenuation; area = m^2) or "
                        ".obj. Needs a sun and a wavy (patch) or mesh water surface")
    r.set_defaults(func=cmd_render)
    pr = sub.add_parser("problems", help="canonical problems 1 and 2 of Mobley et al. 1993",
                        description="Runs canonical problems 1 and 2 of Mobley et al. (1993) from the "
                                    "scenes (those of examples/problems) and compares Ed, Eou and Lu at "
                                    "optical depths 1, 5, 10 with the published model mean and CV: "
                                    "ours +- standard error, reference, CV, time, and pass/fail "
                                    "(|ours - ref| <= (2 CV + 0.005) ref + 3 SE). Exit status 1 if any fails.")
    pr.add_argument("--scenes", default=None,
                    help="folder with the problems' scene files mobley1993_problem<N>_omega<W>.json "
                         "(default: the problems' definitions, photic.problems.problem_scene, the "
                         "same scenes as the repository's examples/problems)")
    pr.add_argument("--problem", type=int, nargs="+", choices=[1, 2], help="only these problems")
    pr.add_argument("--samples", type=int, default=None,
                    help="samples per radiometer, the most one takes (default: the files')")
    pr.add_argument("--fixed", action="store_true",
                    help="every radiometer takes all its samples (default: each stops when its "
                         "standard error is a third of its pass band, 2 CV + 0.005)")
    pr.add_argument("--threads", type=int, default=None, help="threads, 0 = all cores")
    pr.add_argument("--forward-cone", default=None, help="forward cone half-angle in degrees, or auto")
    pr.add_argument("--json", action="store_true",
                    help="print records (problem, omega0, tau, quantity, value, stderr, reference, cv, seconds, passed)")
    pr.set_defaults(func=cmd_problems)
    bt = sub.add_parser("batch", help="run a job of many renders on Dask (a local cluster by default)",
                        description="Runs JOB (a job file, docs/distributed.md: scenes or .blend files, "
                                    "frames, swept parameters, samples or a target standard error) as "
                                    "independent work units on a Dask cluster: a local one by default, "
                                    "the scheduler at --scheduler otherwise. Each unit's sums are written "
                                    "to OUT/units as it completes; each item's EXR images and radiometer "
                                    "tables to OUT/results/<item> when all its units are in; "
                                    "OUT/summary.json lists the items. Run the same command again after an "
                                    "interruption to resume: finished units are not computed again. The "
                                    "results are the same bit for bit on any cluster.")
    bt.add_argument("job", type=Path, help="job file (.json)")
    bt.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="Dask scheduler address (e.g. tcp://10.0.0.5:8786); default: a local cluster")
    bt.add_argument("--workers", type=int, default=None,
                    help="local cluster worker processes (default: one per core); 0 runs the units "
                         "in this process without Dask")
    bt.add_argument("--threads", type=int, default=None,
                    help="core threads per unit (default: the job's, else cores / workers)")
    bt.add_argument("--out", type=Path, default=None,
                    help="output folder (default: the job's 'out', else out/<job name>)")
    bt.add_argument("--fresh", action="store_true", help="delete stored units first (no resume)")
    bt.add_argument("--quiet", action="store_true", help="no progress bar")
    bt.set_defaults(func=cmd_batch)
    pl = sub.add_parser("plugins", help="list installed IOP-model and wave-model plugins",
                        description="Lists the plugins found through the entry-point groups "
                                    "photic.iop_models and photic.wave_models (see "
                                    "engine/src/photic/plugins.py and docs/plugin_example).")
    pl.set_defaults(func=cmd_plugins)
    bl = sub.add_parser("blend", add_help=False,
                        help="render a .blend file with the Photic Blender add-on (needs bpy and the "
                             "add-on package; the same as photic-blend)")
    bl.add_argument("args", nargs=argparse.REMAINDER, help="photic-blend's arguments (photic blend --help)")
    bl.set_defaults(func=cmd_blend)
    dv = sub.add_parser("derive", help="Kd, R, Rrs and mean cosines from a radiometer table",
                        description="Reads TABLE (<scene>_radiometers.json, written by 'photic render') "
                                    "and prints derived quantities with first-order standard errors "
                                    "(radiometers taken as independent): K (Kd, Ku, Ko, ...) between "
                                    "consecutive depths of each profile (same quantity, medium and x, y; "
                                    "depth = -z, K = -d ln E / d depth) and a least-squares K over "
                                    "profiles of three or more depths; R = Eu/Ed, mu_d = Ed/Eod, "
                                    "mu_u = Eu/Eou, mu = (Ed - Eu)/Eo at a shared position; Rrs from "
                                    "radiance and Ed radiometers above the water. Writes "
                                    "<table stem>_derived.csv beside TABLE (or in --out). See "
                                    "docs/derived-quantities.md.")
    dv.add_argument("table", type=Path, help="radiometer table (.json)")
    dv.add_argument("--out", type=Path, default=None, help="output directory (default: the table's)")
    dv.add_argument("--json", action="store_true",
                    help="print the rows as JSON (name, quantity, band, value, stderr, units, sources, ...)")
    dv.add_argument("--no-fit", action="store_true", help="no least-squares K over profiles")
    dv.add_argument("--rrs", nargs=2, action="append", metavar=("LU", "ED"), default=None,
                    help="Rrs from these radiometers (radiance looking down above the water, Ed above "
                         "the water) instead of every air radiance paired with an air Ed at the same "
                         "x, y (reported as Rrs_uncorrected: sky reflection not removed); repeatable")
    dv.add_argument("--sky", default=None, metavar="NAME",
                    help="with --rrs: sky radiance radiometer; Lw = Lu - RHO * L_sky")
    dv.add_argument("--rho", type=float, default=None, help="with --sky: surface reflectance factor")
    dv.add_argument("--reflected", default=None, metavar="NAME",
                    help="with --rrs: radiometer holding the surface-reflected radiance; Lw = Lu - it")
    dv.set_defaults(func=cmd_derive)
    b = sub.add_parser("bench", help="throughput benchmark against raw Embree ray casting",
                       description="Measures the engine's path segments per second on two scenes "
                                   "(a 300k-triangle mesh in water; a flat ocean with a few objects) "
                                   "and raw Embree ray throughput (embreex, and the core's native "
                                   "call) on the same geometry, for 1 and 2 threads, and prints "
                                   "their ratios. Medians of repeated runs.")
    b.add_argument("--json", action="store_true", help="print the records as JSON (each has a 'ratio' field)")
    b.add_argument("--quick", action="store_true", help="smaller scenes and shorter runs (for tests)")
    b.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="thread counts (default: 1 2)")
    b.add_argument("--seconds", type=float, default=2.0, help="approximate seconds per measurement")
    b.add_argument("--error", action="store_true",
                   help="speed against error instead: path tracing, hybrid (forward cone 0) and hybrid "
                        "(auto) at doubling budgets on canonical problem 2 (omega0 0.9, radiometers) and "
                        "the stepped pool's underwater camera, relative error against a reference "
                        "rendered with hybrid cone 0 at a large budget; prints a table and the time to "
                        "5%% error, writes a log-log plot (threads: the largest of --threads)")
    b.add_argument("--cases", default=None,
                   help="with --error: comma-separated cases among problem2, pool (32x24), pool256 "
                        "(the 256x256 pool view: time to 5 %% and CPU-s per sample), waves (256 Ed "
                        "radiometers under a wave patch against a flat sea), cycles (Cycles' CPU-s "
                        "per sample on the pool view, when bpy is present), examples (every example "
                        "scene's image at --examples-width pixels across: time to 5 %% image RMS and "
                        "median pixel error, and its error bars against 12 seeds' spread; the .blend "
                        "examples when bpy is present); default: all")
    b.add_argument("--examples-width", type=int, default=240,
                   help="with --cases examples: the images' width in pixels (aspect kept; default 240)")
    b.add_argument("--plot", default=None,
                   help="with --error: PNG plot of error against time (default: docs/images/bench_error.png); "
                        "with --large: time and memory against triangles (default: "
                        "docs/images/large_scenes.png); '' for none")
    b.add_argument("--large", action="store_true",
                   help="large scenes instead: a seabed with rocks of 1e4 to 1e7 triangles under a tiled "
                        "wave surface, each size in a fresh process: peak memory, bytes per triangle, "
                        "build time, time per camera and radiometer sample and per ray; the closed-mesh "
                        "check of a water body; a tiled ocean's memory (threads: the largest of --threads)")
    b.add_argument("--sizes", nargs="+", default=None, metavar="N",
                   help="with --large: triangle counts (default: 1e4 1e5 1e6 1e7)")
    b.add_argument("--repeats", type=int, default=3,
                   help="with --large: processes per size and renders per process (medians; default 3)")
    b.add_argument("--no-ocean", action="store_true", help="with --large: no tiled-ocean cases")
    b.add_argument("--instanced", action="store_true",
                   help="with --large: an instanced seagrass meadow (copies of a 1,000-triangle blade and "
                        "100 copies of one rock) of 1e4 to 1e8 rendered triangles (--sizes), each in a fresh "
                        "process: peak memory and the camera's cost per sample against the flattened "
                        "10^4-triangle seabed (plot default: docs/images/large_instanced.png)")
    b.add_argument("--out-json", default=None, metavar="PATH",
                   help="with --large: JSON file of the records (default: docs/images/large_scenes.json; "
                        "'' for none)")
    b.set_defaults(func=cmd_bench)
    return p


#: A Ctrl-C while ``photic blend`` loads (bpy takes seconds, and a KeyboardInterrupt inside
#: its import crashed the process): photic_blender.cli reads it once its own handler is in.
EARLY_INTERRUPT = {"requested": False}


def _early_sigint(signum, frame) -> None:
    if EARLY_INTERRUPT["requested"]:
        os._exit(130)
    EARLY_INTERRUPT["requested"] = True


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    if argv[:1] == ["blend"]:  # everything after it is photic-blend's (--help included)
        if threading.current_thread() is not threading.main_thread():
            return cmd_blend(argparse.Namespace(args=argv[1:]))
        import photic  # (python -m photic records a Ctrl-C while it loads there)
        EARLY_INTERRUPT["requested"] = bool(getattr(photic, "_interrupted_while_loading", False))
        previous = signal.signal(signal.SIGINT, _early_sigint)
        try:
            return cmd_blend(argparse.Namespace(args=argv[1:]))
        finally:
            signal.signal(signal.SIGINT, previous)
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
