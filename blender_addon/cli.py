"""``photic-blend`` (also ``photic blend``): render a .blend file through the add-on with Blender
as a Python module (``bpy``), as F12 does, and write the multilayer EXR and radiometer tables.
It lives in the add-on package so that the engine (``photic``) never imports Blender."""
from __future__ import annotations

import argparse
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


def run(args) -> int:
    """Render one frame of a .blend file (the parsed arguments of main)."""
    try:
        import bpy  # noqa: F401  (Blender as a Python module)
    except ImportError as exc:
        print(f"photic-blend: the bpy module is needed ({exc}); install it with "
              f"'pip install bpy==5.0.*' (Python 3.11)", file=sys.stderr)
        return 2
    try:
        from . import batch
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
        print(f"photic-blend: {exc}", file=sys.stderr)
        return 2
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
        print("cancelled: the image holds the samples finished so far", file=sys.stderr)
    return 0


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
