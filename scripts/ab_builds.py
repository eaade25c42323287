"""Paired speed comparison of two builds of the core (``_core*.so`` files), for changes whose
effect (a few per cent) is smaller than this machine's run-to-run noise between processes.

    .venv/bin/python scripts/ab_builds.py OLD.so NEW.so [--case pool|segments|wavebuild|waves] [--rounds 10]
                                          [--threads 1] [--resolution 128] [--spp 4]
                                          [--member "issue"] [--samples 1000]

Each build is loaded in its own worker process, which compiles the scene once and then, on
request, runs one unit of work: ``pool``, a pass of the stepped pool's underwater view (hybrid,
exact mode, beams built once; process CPU seconds), ``segments``, path tracing of bench's
``mesh_in_water`` radiometers (wall nanoseconds per path segment), ``rays``, the core's own
``trace_rays`` on that scene's raw triangles, 2**20 random rays to infinity as ``photic bench``'s
native column (wall nanoseconds per ray), ``wavebuild``, a beam build under a member of the
radiometers-under-waves family (photic.bench_waves; CPU seconds), or ``waves``, one pass of that
member's 64 radiometers, ``samples`` each, with the beams built once (CPU microseconds per
sample). The two workers take turns,
``rounds`` times each, in alternating order, so that drifts of the machine's load fall on both;
it prints both medians, their ratio and the median of the per-round ratios, and whether the two
builds computed the same sums (a change meant to be bit-identical must say True).

Keep one build of the current tree with ``cp .venv/lib/python3.11/site-packages/photic/_core*.so
/tmp/old.so`` before rebuilding (``pip install --no-build-isolation -e ./engine``).
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def worker(so: str, case: str, threads: int, resolution: int, spp: int, member: str, samples: int) -> None:
    import importlib.util
    import time

    import photic
    spec = importlib.util.spec_from_file_location("photic._core", so)
    core_module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(core_module)
    sys.modules["photic._core"] = core_module  # before anything imports photic.compile
    photic._core = core_module
    from photic.compile import compile_scene

    if case == "pool":
        from photic.render import sun_direction
        from photic.scenes import stepped_pool
        scene = stepped_pool(resolution=(resolution, resolution), integrator="hybrid")
        scene.cameras = [c for c in scene.cameras if c.name == "under"]
        scene.validate()
        core = compile_scene(scene, seed=7, hybrid=True, forward_cone_deg=0.0)
        core.build_beams(tuple(sun_direction(scene, 0.5, 0.5)), threads)

        def unit():
            t0 = time.process_time()
            total, _, _ = core.render_camera(0, 0, spp, threads)
            return time.process_time() - t0, float(total.sum())
    elif case in ("wavebuild", "waves"):
        import numpy as np

        from photic import bench_waves
        from photic.render import sun_direction
        m = next(m for m in bench_waves.WAVE_FAMILY if m.name == member)
        scene = bench_waves.wave_member_scene(m, "waves", samples)
        scene.validate()
        core = compile_scene(scene, seed=7, hybrid=True, forward_cone_deg=0.0)
        rng = np.random.default_rng(3)
        core.build_beams(tuple(sun_direction(scene, 0.5, 0.5)), threads)

        def unit():
            if case == "wavebuild":  # a direction drawn in the sun's disk, the same in both workers
                t0 = time.process_time()
                core.build_beams(tuple(sun_direction(scene, *rng.random(2))), threads)
                return time.process_time() - t0, float(core.beam_total_flux())
            t0, total = time.process_time(), 0.0
            for i in range(len(scene.radiometers)):
                s, _, _ = core.render_radiometer(i, 0, samples, threads)
                total += float(s.sum())
            return (time.process_time() - t0) / (samples * len(scene.radiometers)) * 1e6, total
    elif case == "rays":
        from photic import bench
        bs = bench.mesh_in_water()
        raw = bench.native_raw_scene(bench.embree_triangles(bs.scene))
        o, d = bench.random_rays(bs, 1 << 20)

        def unit():
            t0 = time.perf_counter()
            t = raw.trace_rays(o, d, threads)
            return (time.perf_counter() - t0) / len(o) * 1e9, float(t.astype(float).sum())
    else:
        from photic import bench
        scene = bench.mesh_in_water().scene
        core = compile_scene(scene)

        def unit():
            t0, segments, total = time.perf_counter(), 0, 0.0
            for i in range(len(scene.radiometers)):
                s, _, counters = core.render_radiometer(i, 0, 200_000, threads)
                segments += int(counters["segments"])
                total += float(s.sum())
            return (time.perf_counter() - t0) / segments * 1e9, total

    print("ready", flush=True)
    for line in sys.stdin:
        if line.strip() != "go":
            break
        value, checksum = unit()
        print(value, repr(checksum), flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--case", choices=("pool", "segments", "rays", "wavebuild", "waves"), default="pool")
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--member", default="issue", help="wavebuild, waves: the family member (by name)")
    ap.add_argument("--samples", type=int, default=1000, help="waves: samples per radiometer")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:
        worker(a.worker, a.case, a.threads, a.resolution, a.spp, a.member, a.samples)
        return 0
    cmd = [sys.executable, __file__, a.old, a.new, "--case", a.case, "--threads", str(a.threads),
           "--resolution", str(a.resolution), "--spp", str(a.spp), "--member", a.member,
           "--samples", str(a.samples), "--worker"]
    procs = [subprocess.Popen(cmd + [so], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT)
             for so in (a.old, a.new)]
    try:
        for p in procs:
            if p.stdout.readline().strip() != "ready":
                raise SystemExit("a worker failed to start")
        values, sums = ([], []), [None, None]
        for r in range(a.rounds):
            for k in ((0, 1) if r % 2 == 0 else (1, 0)):
                procs[k].stdin.write("go\n")
                procs[k].stdin.flush()
                value, checksum = procs[k].stdout.readline().split()
                values[k].append(float(value))
                sums[k] = checksum
    finally:
        for p in procs:
            if p.stdin:
                p.stdin.write("stop\n")
                p.stdin.close()
            p.wait()
    unit = {"pool": "CPU-s per pass", "segments": "ns per path segment", "rays": "ns per ray",
            "wavebuild": "CPU-s per build", "waves": "CPU-us per sample"}[a.case]
    mo, mn = statistics.median(values[0]), statistics.median(values[1])
    per_round = statistics.median(n / o for o, n in zip(*values))
    print(f"{a.case}, {a.threads} thread(s), {a.rounds} rounds, {unit}: old {mo:.4g}, new {mn:.4g}, "
          f"new/old {mn / mo:.3f} (median of rounds {per_round:.3f}); same sums: {sums[0] == sums[1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
