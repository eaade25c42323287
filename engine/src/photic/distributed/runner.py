"""Runs a job's units on Dask (a local cluster by default, a remote scheduler when given) or
in this process, writing each unit's result as it completes and each item's outputs when
all its units are in.

The runner owns no scheduling: Dask places the units, retries the ones whose worker was
lost (and, with ``retries``, the ones that raised). The runner only records results: one
file per unit id (``store.UnitStore``), so a unit that ran twice is still merged once, and a
restarted job skips every unit whose file is already there and valid (resume). Merges read
the files in the plan's fixed order (``units.merge_order``), so the outputs do not depend on
which worker ran what, or when.
"""
from __future__ import annotations

import collections
import json
import logging
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__
from ..output import write_outputs
from .job import Item, Job, item_target, rounds_needed
from .store import UnitStore
from .units import (ItemMerger, Unit, clear_core_cache, compute_unit, merge_order, plan_round,
                    unit_spec, worst_rel_stderr)


class BatchStopped(Exception):
    """The batch was stopped (``should_stop``); finished units are kept for a resume."""


@dataclass
class BatchReport:
    out: Path
    executor: str = ""
    computed: list = field(default_factory=list)   # "item/unit id" computed by this run
    skipped: list = field(default_factory=list)    # valid files found (resume)
    failed: dict = field(default_factory=dict)     # "item/unit id" -> error text
    items: dict = field(default_factory=dict)      # item name -> summary
    wall_s: float = 0.0
    interrupted: bool = False

    @property
    def ok(self) -> bool:
        return not self.failed and not self.interrupted and all(
            s["status"] == "done" for s in self.items.values())


# --- executors -----------------------------------------------------------------------------

class SerialExecutor:
    """Units one after another in this process, in submission order (``--workers 0``)."""

    name = "this process"

    def __init__(self, should_stop=None):
        self.queue: collections.deque = collections.deque()
        self.should_stop = should_stop

    def submit(self, unit: Unit, spec: dict, item: Item) -> None:
        self.queue.append((unit, spec, item.scene))

    def pending(self) -> int:
        return len(self.queue)

    def next_done(self):
        if self.should_stop is not None and self.should_stop():
            raise BatchStopped()
        unit, spec, scene = self.queue.popleft()
        try:
            return unit, compute_unit(spec, scene), None
        except Exception as exc:  # reported per unit; the other items go on
            return unit, None, exc

    def release(self, item: Item) -> None:
        clear_core_cache()  # the item's compiled scenes are not needed any more here

    def cancel(self) -> None:
        self.queue.clear()
        clear_core_cache()


def _scene_payload(scene):
    """A task holding an item's scene: its units depend on it, so each worker receives the
    scene once, and the scheduler can recompute it if the worker holding it is lost."""
    return scene


class DaskExecutor:
    """Units as Dask tasks on a ``distributed.Client``."""

    POLL_S = 0.05

    def __init__(self, client, retries: int, should_stop=None):
        from distributed import as_completed
        self.client = client
        self.retries = retries
        self.should_stop = should_stop
        self.done = as_completed()
        self.units: dict = {}      # future key -> (unit, future)
        self.payloads: dict = {}   # item name -> scene future
        self.name = f"Dask scheduler {client.scheduler.address}"

    def submit(self, unit: Unit, spec: dict, item: Item) -> None:
        payload = self.payloads.get(item.name)
        if payload is None:
            payload = self.client.submit(_scene_payload, item.scene, pure=False,
                                         key=f"photic-scene-{item.name}-{item.fingerprint[:16]}")
            self.payloads[item.name] = payload
        key = f"photic-unit-{item.name}-{item.fingerprint[:16]}-{unit.id}"
        fut = self.client.submit(compute_unit, spec, payload, key=key, pure=False, retries=self.retries)
        self.units[fut.key] = (unit, fut)
        self.done.add(fut)

    def pending(self) -> int:
        return len(self.units)

    def next_done(self):
        while not self.done.has_ready():  # poll, so that a stop request is seen
            if self.should_stop is not None and self.should_stop():
                raise BatchStopped()
            time.sleep(self.POLL_S)
        fut = next(self.done)
        unit, _ = self.units.pop(fut.key)
        try:
            return unit, fut.result(), None
        except Exception as exc:  # the unit raised after its retries, or killed workers
            return unit, None, exc
        finally:
            fut.release()

    def release(self, item: Item) -> None:
        payload = self.payloads.pop(item.name, None)
        if payload is not None:
            payload.release()

    def cancel(self) -> None:
        futures = [f for _, f in self.units.values()] + list(self.payloads.values())
        if futures:
            self.client.cancel(futures)
        self.units.clear()
        self.payloads.clear()


class SchedulerError(ValueError):
    """A scheduler address that is no Dask scheduler, or one without workers."""


_SCHEMES = ("tcp", "tls", "ucx", "inproc")


def check_scheduler_address(address: str) -> tuple[str, str, int]:
    """(scheme, host, port) of a Dask scheduler address such as ``tcp://10.0.0.5:8786`` (or
    ``10.0.0.5:8786``); SchedulerError saying what is wrong (an http:// address is the
    dashboard, a web page, not the scheduler)."""
    text = str(address).strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    scheme = scheme.lower()
    if scheme in ("http", "https"):
        raise SchedulerError(f"{address!r} is a web address (the Dask dashboard?): the scheduler "
                             f"listens on tcp://HOST:8786 by default")
    if scheme not in _SCHEMES:
        raise SchedulerError(f"{address!r}: unknown scheme {scheme!r}; expected tcp://HOST:PORT "
                             f"(or {', '.join(s + '://' for s in _SCHEMES[1:])})")
    host, colon, port = rest.rpartition(":")
    if not colon or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise SchedulerError(f"{address!r}: expected tcp://HOST:PORT, e.g. tcp://10.0.0.5:8786")
    return scheme, host.strip("[]"), int(port)


def connect_scheduler(address: str, timeout_s: float):
    """A ``distributed.Client`` of the Dask scheduler at ``address``, or SchedulerError saying
    why not, within about ``timeout_s``: a refused or silent port, or a peer that does not
    speak Dask's protocol (a web server's 'HTTP/1.1 400' read as Dask's frame lengths asked
    for exabytes; a silent one hung the connection beyond Dask's own timeout)."""
    import socket
    import threading
    from distributed import Client
    scheme, host, port = check_scheduler_address(address)
    if scheme == "tcp":
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
        except (socket.timeout, TimeoutError):
            raise SchedulerError(f"{address}: no answer within {timeout_s:g} s") from None
        except OSError as exc:
            raise SchedulerError(f"{address}: cannot connect ({exc.strerror or exc})") from None
    box: dict = {}

    def connect():
        try:
            box["client"] = Client(address, timeout=timeout_s)
        except BaseException as exc:  # noqa: BLE001  (MemoryError included: reported below)
            box["error"] = exc

    t = threading.Thread(target=connect, name="photic-dask-connect", daemon=True)
    t.start()
    t.join(timeout_s + 5.0)
    if t.is_alive():
        raise SchedulerError(f"{address} accepted the connection but did not complete Dask's "
                             f"handshake within {timeout_s + 5:g} s: is it a Dask scheduler?")
    if "error" in box:
        exc = box["error"]
        if isinstance(exc, (MemoryError, OverflowError, ValueError, TypeError)):
            raise SchedulerError(f"{address} does not speak Dask's protocol (is it another server, "
                                 f"e.g. a web server or the dashboard?)") from None
        if isinstance(exc, (OSError, TimeoutError)):
            raise SchedulerError(f"{address}: {type(exc).__name__}: {exc}") from None
        raise exc
    return box["client"]


def wait_for_workers(client, address: str, timeout_s: float, say=None) -> None:
    """A scheduler without workers would take the units and never run them: wait up to
    ``timeout_s`` for one, saying so, then SchedulerError."""
    if client.scheduler_info().get("workers"):
        return
    if say is not None:
        say(f"the Dask scheduler {address} has no workers: waiting up to {timeout_s:g} s for one "
            f"(start them with: dask worker {address} --nthreads 1)")
    try:
        client.wait_for_workers(1, timeout=timeout_s)
    except (TimeoutError, OSError) as exc:
        raise SchedulerError(f"the Dask scheduler {address} has no workers (waited {timeout_s:g} s): "
                             f"start them with: dask worker {address} --nthreads 1") from exc


def _local_cluster(workers: int):
    """A local cluster whose worker processes ignore SIGINT: a Ctrl-C in the terminal reaches
    the whole process group, and each worker printed a KeyboardInterrupt traceback while this
    process (which alone handles it) cancels the units and closes the cluster."""
    import signal
    import threading

    from distributed import Client, LocalCluster
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:  # (an ignored signal stays ignored in the processes started meanwhile)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.CRITICAL)
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)
    client = Client(cluster)
    client.register_plugin(_quiet_worker_logs())
    return client, cluster


def _quiet_worker_logs():
    """A worker plugin that leaves only critical messages in a local worker's log. A Ctrl-C
    that lands while this process reads a unit's result closes the connection under the
    worker, which then logged 'failed during get data' with a traceback to the terminal; the
    batch itself reports every unit that fails, with its exception, so the workers' own log is
    noise here. (A plugin, not a one-off call, so that a restarted worker is quiet too.)"""
    from distributed import WorkerPlugin

    class QuietWorkerLogs(WorkerPlugin):
        name = "photic-quiet-worker-logs"

        def setup(self, worker):
            names = [n for n in logging.root.manager.loggerDict if n.split(".")[0] == "distributed"]
            for n in ["distributed", *names]:
                logging.getLogger(n).setLevel(logging.CRITICAL)

    return QuietWorkerLogs()


# --- the batch -----------------------------------------------------------------------------

class _ItemState:
    def __init__(self, item: Item):
        self.item = item
        self.units: list[Unit] = []        # every planned unit (all rounds so far)
        self.rounds = 0
        self.outstanding = 0               # submitted, not yet returned
        self.failed: dict = {}
        self.status = "pending"
        self.files: list[str] = []
        self.worst = None
        self.merged = None


def _write_json(path: Path, doc: dict) -> None:
    from ..safe_io import atomic_file, json_safe
    text = json.dumps(json_safe(doc), indent=1, default=str, allow_nan=False)
    with atomic_file(path, "w", encoding="utf-8") as f:
        f.write(text)


def run_job(job: Job, out=None, *, scheduler: str | None = None, workers: int | None = None,
            client=None, threads: int | None = None, progress: bool = True, fresh: bool = False,
            on_unit_done=None, on_item_done=None, should_stop=None, write_results: bool = True,
            connect_timeout_s: float = 30.0) -> BatchReport:
    """Run ``job``; returns a report (also written as ``OUT/summary.json``).

    Where units run: ``client`` (a ``distributed.Client``), else ``scheduler`` (an address),
    else a local cluster of ``workers`` processes (default: one per core); ``workers=0`` runs
    them in this process without Dask. ``threads``: core threads per unit (default: the job's,
    else cores / workers on a local cluster, all cores elsewhere; never changes a result).
    ``fresh`` deletes stored units first; otherwise valid stored units are not run again.
    ``on_unit_done(unit, result)`` and ``on_item_done(item, render_result)`` are called as
    they complete; ``should_stop()`` returning True stops the batch (BatchStopped), keeping
    the finished units. Ctrl-C does the same (KeyboardInterrupt). ``write_results=False``
    writes no EXR or tables (the caller takes the merged results from ``on_item_done``).
    """
    t0 = time.perf_counter()
    out = Path(out if out is not None else job.out if job.out is not None else Path("out") / job.name)
    out.mkdir(parents=True, exist_ok=True)
    store = UnitStore(out)
    if fresh and store.root.exists():
        shutil.rmtree(store.root)
    threads = threads if threads is not None else job.threads or None
    owned = []  # client / cluster this call started, closed at the end
    if workers is not None and workers < 0:
        raise SchedulerError(f"workers must be 0 (no Dask) or more, got {workers}")
    if client is None and scheduler is not None:
        client = connect_scheduler(scheduler, connect_timeout_s)
        owned.append(client)
        try:
            wait_for_workers(client, scheduler, max(connect_timeout_s, 30.0),
                             say=lambda m: print(f"photic batch: {m}", file=sys.stderr))
        except SchedulerError:
            client.close()
            raise
    if client is None and workers != 0:
        n = workers or os.cpu_count() or 1
        client, cluster = _local_cluster(n)
        owned += [client, cluster]
        threads = threads or max(1, (os.cpu_count() or 1) // n)
    if client is None:
        executor = SerialExecutor(should_stop)
    else:
        executor = DaskExecutor(client, job.retries, should_stop)
    threads = threads or 0
    report = BatchReport(out, executor.name)
    states = {item.name: _ItemState(item) for item in job.items}

    from tqdm import tqdm
    bar = tqdm(total=0, desc=f"batch {job.name}", unit="unit", file=sys.stderr, disable=not progress,
               dynamic_ncols=True)

    def summary() -> dict:
        return {"photic_version": __version__, "job": job.name,
                "job_file": str(job.path) if job.path else None, "executor": executor.name,
                "out": str(out), "wall_s": time.perf_counter() - t0,
                "units": {"computed": len(report.computed), "skipped": len(report.skipped),
                          "failed": len(report.failed)},
                "items": [item_summary(s) for s in states.values()]}

    def item_summary(st: _ItemState) -> dict:
        it = st.item
        doc = {"name": it.name, "source": it.source, "frame": it.frame, "params": it.params,
               "status": st.status, "fingerprint": it.fingerprint, "samples": it.samples,
               "radiometer_samples_per_round": it.radiometer_samples, "rounds": st.rounds,
               "seed": it.seed, "integrator": it.integrator, "units": len(st.units),
               "files": st.files, "failed_units": st.failed}
        if st.worst is not None:
            doc["worst_rel_stderr"] = st.worst
            target = item_target(job, it)
            if target is not None:
                doc["target_rel_stderr"] = target
                doc["target_met"] = st.worst <= target
        if st.merged is not None:
            doc["counters"] = {k: st.merged.stats[k] for k in ("segments", "shadow_rays", "paths")}
            doc["unit_time_s"] = st.merged.stats["time_s"]
            doc["radiometers"] = {r.name: {"value": r.mean[0].tolist(), "stderr": r.stderr[0].tolist()}
                                  for r in st.merged.radiometers if r.mean.shape[0] == 1}
        report.items[it.name] = doc
        return doc

    def submit(st: _ItemState, units: list[Unit]) -> None:
        st.units += units
        bar.total += len(units)
        for u in units:
            if store.valid(u, st.item.fingerprint):
                report.skipped.append(f"{u.item}/{u.id}")
                bar.update(1)
            else:
                executor.submit(u, unit_spec(st.item, job, u, threads), st.item)
                st.outstanding += 1
        bar.refresh()

    def advance(st: _ItemState) -> None:
        """All submitted units of the item are in: merge; more rounds or the outputs."""
        while st.outstanding == 0 and st.status == "pending":
            if st.failed:
                st.status = "failed"
                break
            merger = ItemMerger(st.item)
            missing = []
            for u in merge_order(st.units):
                res = store.read(u, st.item.fingerprint)
                if res is None:
                    missing.append(u)
                else:
                    merger.add(u, res, job)
            if missing:  # a file went bad after it was written: compute those again
                st.units = [u for u in st.units if u not in missing]
                submit(st, missing)
                continue
            result = merger.result()
            st.merged = result
            st.worst = worst_rel_stderr(result) if result.radiometers else None
            add = 0
            target = item_target(job, st.item)
            if target is not None and st.worst is not None:
                add = rounds_needed(st.rounds, st.worst, target, job.max_rounds)
            if add:
                new = []
                for r in range(st.rounds, st.rounds + add):
                    new += plan_round(st.item, job, r)
                st.rounds += add
                submit(st, new)
                continue
            if write_results:
                written = write_outputs(out / "results" / st.item.name, result)
                st.files = [str(p) for p in written["images"] + written["tables"]]
                if written["failed"]:  # the units stay in the store: a resume writes them
                    raise OSError("; ".join(str(f) for f in written["failed"]))
            st.status = "done"
            executor.release(st.item)
            _write_json(out / "summary.json", summary())
            if on_item_done is not None:
                on_item_done(st.item, result)

    try:
        for st in states.values():
            st.rounds = 1
            submit(st, plan_round(st.item, job, 0))
            advance(st)
        while executor.pending():
            unit, result, error = executor.next_done()
            st = states[unit.item]
            st.outstanding -= 1
            key = f"{unit.item}/{unit.id}"
            if error is not None:
                st.failed[unit.id] = f"{type(error).__name__}: {error}"
                report.failed[key] = st.failed[unit.id]
                bar.write(f"photic batch: unit {key} failed: {st.failed[unit.id]}")
            else:
                store.write(unit, result)
                report.computed.append(key)
            bar.update(1)
            if on_unit_done is not None:
                on_unit_done(unit, result)
            advance(st)
    except BaseException:
        report.interrupted = True
        executor.cancel()
        raise
    finally:
        bar.close()
        report.wall_s = time.perf_counter() - t0
        _write_json(out / "summary.json", summary())
        for obj in owned:
            try:
                obj.close()
            except Exception:  # closing a cluster that lost workers may complain; the results are saved
                pass
    return report
