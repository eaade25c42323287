"""How soon the render view shows pixels, how often it updates, how fast Esc stops a render,
and what streaming costs: an example .blend at a given size, through the add-on with ``bpy``.

    .venv/bin/python scripts/streaming_bench.py                      # sediment plume, 1920x1080, 10 bands
    .venv/bin/python scripts/streaming_bench.py --blend example_blends/stepped_pool.blend --samples 16

Three runs in one process, 2 threads:
1. a final render through Blender (``bpy.ops.render.render``, the real render result, so
   ``set_rect`` is counted): time to the first streamed update, the largest gap between
   updates, the render's own time;
2. the same render with streaming off (``final_render.STREAM = False``: the image is written
   at the end only), interleaved with run 1 ``--pairs`` times: streaming's cost is the median
   of the ratios of their render times;
3. a final render through a stand-in engine whose Esc is pressed after ``--esc`` seconds: the
   time from Esc until the render returned.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


class EscEngine:
    """The RenderEngine methods FinalRender calls; Esc is 'pressed' after ``after_s``."""

    def __init__(self, after_s: float):
        self.after_s, self.t0 = after_s, time.perf_counter()

        self.pressed = None

    def test_break(self):
        now = time.perf_counter()
        if now - self.t0 > self.after_s:
            if self.pressed is None:
                self.pressed = now
            return True
        return False

    def begin_result(self, x, y, w, h):
        from photic_blender import final_render

        class Pass:
            rect = None

        class Layer:
            passes = {name: Pass() for name in ("Combined", *final_render.PASS_NAMES)}

        class Result:
            layers = [Layer()]

        return Result()

    def update_result(self, result):
        pass

    def end_result(self, result):
        pass

    def update_progress(self, f):
        pass

    def update_stats(self, stats, info):
        pass

    def report(self, kind, message):
        pass


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--blend", default=str(REPO / "example_blends" / "sediment_plume.blend"))
    p.add_argument("--size", type=int, nargs=2, default=(1920, 1080))
    p.add_argument("--samples", type=int, default=8)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--esc", type=float, default=6.0, help="seconds before Esc in run 3")
    p.add_argument("--only-esc", action="store_true", help="run 3 only")
    p.add_argument("--pairs", type=int, default=2, help="renders with and without streaming")
    args = p.parse_args(argv)

    import bpy
    from photic.cli import load_addon
    load_addon()
    from photic_blender import batch, final_render
    from photic_blender.export import export_scene
    import photic
    import photic.render  # noqa: F401  (the submodules the add-on uses)
    import photic.scene  # noqa: F401

    def open_scene():
        _, scene = batch.open_blend(args.blend)
        scene.render.resolution_x, scene.render.resolution_y = args.size
        scene.render.resolution_percentage = 100
        scene.photic.samples, scene.photic.threads = args.samples, args.threads
        scene.photic.radiometer_samples = 1024
        scene.render.filepath = str(Path(tempfile.mkdtemp(prefix="photic_stream_")) / "frame")
        return scene

    if args.only_esc:
        open_scene()
        engine = EscEngine(args.esc)
        esc = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
        back = time.perf_counter() - engine.pressed
        print(f"Esc after {args.esc:g} s: render thread stopped in {1000 * esc.get('cancel_latency_s'):.0f} ms, "
              f"render returned in {1000 * back:.0f} ms ({esc.get('samples')} samples kept)")
        return 0

    scene = open_scene()
    nb = len(export_scene(bpy.context.evaluated_depsgraph_get(), photic)[0].bands)

    def blender_render(stream: bool) -> dict:
        open_scene()
        final_render.STREAM = stream
        final_render.LAST_RENDER.clear()
        try:
            bpy.ops.render.render()
        finally:
            final_render.STREAM = True
        return dict(final_render.LAST_RENDER)

    # Streaming on and off, interleaved (the machine is shared: medians of ratios of pairs).
    runs = [(blender_render(True), blender_render(False)) for _ in range(args.pairs)]
    s = runs[0][0]
    times = s.get("update_times", [])
    gaps = [b - a for a, b in zip(times[:-1], times[1:])]
    preps = [p for on, _ in runs for p in on.get("display_prep_s", [])]
    ratios = [on["time_s"] / off["time_s"] for on, off in runs]

    open_scene()
    engine = EscEngine(args.esc)
    esc = final_render.FinalRender(engine, bpy.context.evaluated_depsgraph_get()).run()
    back = time.perf_counter() - engine.pressed

    print(f"{Path(args.blend).name} at {args.size[0]}x{args.size[1]}, {nb} bands, {args.samples} spp, "
          f"{args.threads} threads")
    print(f"  first pixels after      {times[0]:.2f} s" if times else "  no update")
    print(f"  updates                 {len(times)}; largest gap {max(gaps) if gaps else float('nan'):.2f} s, "
          f"median {statistics.median(gaps) if gaps else float('nan'):.2f} s")
    print(f"  display preparation     median {1000 * statistics.median(preps):.0f} ms per frame "
          f"(a thread of its own)" if preps else "")
    on_s = ", ".join(f"{on['time_s']:.1f}" for on, _ in runs)
    off_s = ", ".join(f"{off['time_s']:.1f}" for _, off in runs)
    print(f"  render through Blender  streaming {on_s} s; without {off_s} s: streaming costs "
          f"{100 * (statistics.median(ratios) - 1):+.1f} % (median of {len(ratios)} pairs)")
    print(f"  Esc after {args.esc:g} s          render returned in {1000 * back:.0f} ms (render thread "
          f"stopped in {1000 * (esc.get('cancel_latency_s') or float('nan')):.0f} ms; {esc.get('samples')} samples kept)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
