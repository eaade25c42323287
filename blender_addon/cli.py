"""``photic-blend`` (also ``photic blend``): render a .blend file through the add-on with Blender
as a Python module (``bpy``), as F12 does, and write the multilayer EXR and radiometer tables.
It lives in the add-on package so that the engine (``photic``) never imports Blender."""
from __future__ import annotations

import argparse
import os
import signal
import sys
from pathlib import Path

from photic.cli import relative_error_arg


def build_parser() -> argparse.ArgumentParser:
    bl = argparse.ArgumentParser(
        prog="photic-blend",
        description="Opens FILE.blend with the bpy module, renders one frame through "
                    "the Photic render engine of the add-on (as F12 does) and writes a "
                    "multilayer EXR <file>_<frame>.exr (Combined = the display bands "
                    "as RGB, and the Photic Beam Surface / Beam Volume / Path / "
                    "Variance passes) and, when the scene has radiometers, "
                    "<file>_<frame>_radiometers.csv/.json beside it.")
    bl.add_argument("file", type=Path, help=".blend file")
    bl.add_argument("--frame", type=int, default=None, help="frame to render (default: the file's current frame)")
    bl.add_argument("--out", type=Path, default=Path("out"), help="output directory (default: out)")
    bl.add_argument("--samples", type=int, default=None, help="samples per pixel (default: the file's)")
    bl.add_argument("--radiometer-samples", type=int, default=None, help="samples per radiometer (default: the file's)")
    bl.add_argument("--target-error", type=relative_error_arg, default=None, metavar="REL",
                    help="stop each radiometer at this relative standard error, e.g. 1%% "
                         "(default: the file's Target Error)")
    bl.add_argument("--noise-threshold", type=relative_error_arg, default=None, metavar="REL",
                    help="turn on the file's Noise Threshold (adaptive sampling) at REL, e.g. 2%%")
    bl.add_argument("--radiometers-only", action="store_true",
                    help="render the file's radiometers alone (no image), as Render > Render "
                         "Radiometers does; a file without a camera does so anyway")
    bl.add_argument("--png", action="store_true",
                    help="also write <file>_<frame>.png beside the EXR, as Blender displays the "
                         "image (view transform, exposure)")
    bl.add_argument("--seed", type=int, default=None, help="random seed (default: the file's)")
    bl.add_argument("--threads", type=int, default=None, help="threads, 0 = all cores (default: the file's)")
    bl.add_argument("--quiet", action="store_true", help="no progress bar")
    return bl


_STOP = {"requested": False}


def _on_sigint(signum, frame) -> None:
    """Ctrl-C: the render stops as Esc stops it (the worker cancelled and joined, what is
    finished written); a second Ctrl-C ends the process at once, without a traceback (every
    output is written atomically: nothing half-written is left)."""
    if _STOP["requested"]:
        print("\nphotic-blend: interrupted again: stopped at once", file=sys.stderr, flush=True)
        os._exit(130)
    _STOP["requested"] = True
    module = sys.modules.get(f"{__package__}.final_render")
    if module is not None:
        module.CANCEL.set()
    print("\nphotic-blend: stopping; keeping what is finished (Ctrl-C again to stop at once)",
          file=sys.stderr, flush=True)


def _interrupted_early() -> int:
    print("photic-blend: interrupted before the render started; nothing was written",
          file=sys.stderr)
    return 130


def run(args) -> int:
    """Render one frame of a .blend file (the parsed arguments of main)."""
    # Installed before bpy is imported (a KeyboardInterrupt inside its import crashed the
    # process) and kept for the whole render (one inside the render left its worker running).
    from photic import cli as engine_cli
    _STOP["requested"] = bool(engine_cli.EARLY_INTERRUPT["requested"])  # while photic loaded
    previous = signal.signal(signal.SIGINT, _on_sigint)
    try:
        return _run(args)
    finally:
        signal.signal(signal.SIGINT, previous)


def _run(args) -> int:
    if _STOP["requested"]:  # (while photic loaded: bpy is not worth loading now)
        return _interrupted_early()
    try:
        import bpy  # noqa: F401  (Blender as a Python module)
    except ImportError as exc:
        print(f"photic-blend: the bpy module is needed ({exc}); install it with "
              f"'pip install bpy==5.0.*' (Python 3.11)", file=sys.stderr)
        return 2
    try:
        from . import batch, final_render
        final_render.CANCEL.clear()
        if _STOP["requested"]:
            return _interrupted_early()
        bar, progress = None, None
        if not args.quiet:
            from tqdm import tqdm
            bar = tqdm(total=1000, desc=f"rendering {Path(args.file).name}", unit="‰",
                       file=sys.stderr, bar_format="{desc}: {percentage:3.0f}%|{bar}| "
                                                   "{elapsed}<{remaining} {postfix}")

            def progress(fraction, text):
                bar.n = min(1000, int(round(1000 * fraction)))
                bar.set_postfix_str(text, refresh=False)
                bar.refresh()
        try:
            summary = batch.render_blend(args.file, frame=args.frame, out_dir=args.out,
                                         samples=args.samples,
                                         radiometer_samples=args.radiometer_samples,
                                         seed=args.seed, threads=args.threads, progress=progress,
                                         target_error=args.target_error,
                                         noise_threshold=args.noise_threshold,
                                         radiometers_only=args.radiometers_only,
                                         png=args.png)
        finally:
            if bar is not None:
                bar.close()
    except (FileNotFoundError, RuntimeError) as exc:
        if _STOP["requested"]:  # (the message of a render stopped before it began)
            return _interrupted_early()
        print(f"photic-blend: {exc}", file=sys.stderr)
        return 2
    if summary.get("nothing_done"):
        print("photic-blend: cancelled before the first sample; nothing was written",
              file=sys.stderr)
        return 130
    if summary.get("image"):
        print(f"image: {summary['image']}")
    if summary.get("png"):
        print(f"picture: {summary['png']}")
    for t in summary.get("tables", []):
        print(f"radiometer table: {t}")
    st = summary.get("stats") or {}
    if st.get("target_error") is not None:
        print(f"target error {100 * st['target_error']:.3g} %: reached by {st['target_reached']} "
              f"radiometers in {st['rounds']} rounds (at most {st['radiometer_samples']} samples)")
    if summary.get("cancelled"):
        print("cancelled: the image and tables hold the samples finished so far", file=sys.stderr)
        return 130
    return 0


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
