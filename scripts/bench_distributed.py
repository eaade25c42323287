"""Speed-up of `photic batch` on a local Dask cluster: the same job on 1 and on N worker
processes (one core thread per unit), checked bit for bit, with wall times.

    .venv/bin/python scripts/bench_distributed.py [JOB] [--workers 1 2] [--out DIR]

JOB defaults to examples/jobs/problem2_sweep.json (canonical problem 2, omega0 0.9: 8 bands x
4 sun zenith angles, 9 radiometers, 131,072 samples each: 144 units). The times exclude
the cluster's start (reported apart) and include writing the unit files and outputs.
"""
from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def unit_digests(out: Path) -> dict:
    import json

    import numpy as np
    digests = {}
    for f in sorted((out / "units").rglob("*.npz")):
        with np.load(f) as z:
            digests[str(f.relative_to(out))] = json.loads(str(z["__meta__"]))["sha256"]
    return digests


def main(argv=None) -> int:
    from distributed import Client, LocalCluster

    from photic.distributed import load_job, run_job

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("job", nargs="?", default=str(ROOT / "examples" / "jobs" / "problem2_sweep.json"))
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--out", default=None, help="folder for the runs' outputs (default: a temporary one)")
    args = p.parse_args(argv)
    job = load_job(args.job)
    base = Path(args.out or tempfile.mkdtemp(prefix="photic_bench_batch_"))
    print(f"job {job.name}: {len(job.items)} items; machine: {os.cpu_count()} cores; outputs in {base}")
    rows = []
    for n in args.workers:
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR)
        client = Client(cluster)
        start_s = time.perf_counter() - t0
        out = base / f"workers{n}"
        cpu = []  # CPU seconds of each unit's process: what the machine gave the workers
        try:
            report = run_job(job, out, client=client, threads=1, fresh=True, progress=True,
                             on_unit_done=lambda u, r: cpu.append(r["meta"]["cpu_s"]))
        finally:
            client.close()
            cluster.close()
        assert report.ok, report.failed
        unit_s = sum(s.get("unit_time_s", 0.0) for s in report.items.values())
        rows.append((n, report.wall_s, start_s, sum(cpu), unit_s, unit_digests(out)))
        print(f"{n} worker process(es): {report.wall_s:.1f} s for {len(report.computed)} units "
              f"(cluster start {start_s:.1f} s; units' wall time {unit_s:.1f} s, CPU time "
              f"{sum(cpu):.1f} s)", flush=True)
    ref = rows[0]
    # cores busy = CPU seconds / wall seconds: below the worker count when the machine is shared.
    print(f"\n{'workers':>7} {'wall s':>8} {'speed-up':>9} {'efficiency':>10} {'cores busy':>10}  "
          f"identical to {ref[0]} worker(s)")
    for n, wall, _, cpu_s, _, digests in rows:
        same = digests == ref[5]
        print(f"{n:>7} {wall:>8.1f} {ref[1] / wall:>9.2f} {ref[1] / wall / (n / ref[0]):>10.0%} "
              f"{cpu_s / wall:>10.2f}  {'yes, bit for bit' if same else 'NO'}")
    return 0 if all(r[5] == ref[5] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
