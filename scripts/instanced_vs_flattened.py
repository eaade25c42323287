"""Where the instanced meadow's camera time goes (issue 43; docs/benchmarks.md, "Instanced
geometry"): the meadow of ``photic bench --large --instanced`` at 10^7 rendered triangles,
instanced against the same copies flattened into world triangles; and at 10^8, the blades'
copies against the rock's tessellation (each swapped for the 10^4-triangle meadow's).

    .venv/bin/python scripts/instanced_vs_flattened.py      # about 2 minutes on 2 cores

Camera CPU time per sample (128 x 96, 16 spp, medians of 3 renders, 2 threads), per path
segment, and per random ray (``trace_rays``)."""
from __future__ import annotations

import time

from photic.bench_large import _render_timings, meadow_geometry, meadow_scene
from photic.compile import compile_scene


def measure(tag: str, scene) -> None:
    t0 = time.perf_counter()
    core = compile_scene(scene)
    compile_s = time.perf_counter() - t0
    r = _render_timings(core, scene, 16, 4096, 2, 3, 200_000)
    c = r["camera"]
    rendered = sum(len(m.mesh.triangles) * m.copies for m in scene.meshes)
    print(f"{tag:<34} {rendered:>12,} {compile_s:>8.2f} {c['cpu_s_per_sample'] * 1e6:>10.2f} "
          f"{c['cpu_s_per_segment'] * 1e9:>8.0f} {r['rays']['cpu_s_per_ray'] * 1e9:>7.0f}")


def main() -> None:
    print(f"{'case':<34} {'triangles':>12} {'compile':>8} {'camera':>10} {'segment':>8} {'ray':>7}")
    print(f"{'':<34} {'':>12} {'(s)':>8} {'(us/spp)':>10} {'(ns)':>8} {'(ns)':>7}")
    ten_m = meadow_scene(meadow_geometry(10_000_000))
    measure("10^7, instanced", ten_m)
    ten_m.meshes = [m.flattened() for m in ten_m.meshes]
    measure("10^7, the same copies flattened", ten_m)
    del ten_m
    small, big = meadow_geometry(10_000), meadow_geometry(100_000_000)
    measure("10^4, instanced", meadow_scene(small))
    measure("10^8, instanced", meadow_scene(big))
    measure("10^8 rocks, 10^4 meadow's blades", meadow_scene(dict(big, blade=small["blade"])))
    measure("10^8 blades, 10^4 meadow's rock", meadow_scene(dict(big, rock=small["rock"])))


if __name__ == "__main__":
    main()
