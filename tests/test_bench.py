"""``photic bench`` in quick mode: one record per scene with positive finite throughputs."""
import math

from photic.bench import run_bench

NUMBERS = ("triangles", "threads", "engine_segments_per_s", "embreex_rays_per_s",
           "native_rays_per_s", "ratio", "ratio_native")


def test_quick_bench_records():
    records = run_bench(quick=True, threads=(1,), seconds=0.2, print_table=False)
    assert [r["scene"] for r in records] == ["mesh_in_water", "flat_ocean_objects"]
    for r in records:
        assert r["threads"] == 1
        for key in NUMBERS:
            assert math.isfinite(r[key]) and r[key] > 0, (r["scene"], key, r[key])
        assert math.isclose(r["ratio"], r["engine_segments_per_s"] / r["embreex_rays_per_s"])
        assert math.isclose(r["ratio_native"], r["engine_segments_per_s"] / r["native_rays_per_s"])
        assert isinstance(r["note"], str) and "WARNING" not in r["note"]
