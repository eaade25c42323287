"""Make ``photic`` importable from the source tree when it is not installed; keep the
tests' secrets and caches out of the user's own folders."""
import os
import sys
import tempfile
from pathlib import Path

# Photic's per-user unit key and Dask cache (photic.distributed.store) go to folders of this
# test session, inherited by the processes the tests start.
_PRIVATE = tempfile.mkdtemp(prefix="photic-tests-")
os.environ.setdefault("PHOTIC_CONFIG_DIR", os.path.join(_PRIVATE, "config"))
os.environ.setdefault("PHOTIC_CACHE_DIR", os.path.join(_PRIVATE, "cache"))
# Blender (the bpy module here, and the blender binary the tests start) reads and writes its
# user configuration in folders of this session, never the user's own ~/.config/blender:
# made first, as Blender ignores a BLENDER_USER_* folder that does not exist.
for _name, _sub in (("BLENDER_USER_CONFIG", "blender/config"), ("BLENDER_USER_SCRIPTS", "blender/scripts"),
                    ("BLENDER_USER_DATAFILES", "blender/datafiles")):
    os.makedirs(os.path.join(_PRIVATE, _sub), exist_ok=True)
    os.environ.setdefault(_name, os.path.join(_PRIVATE, _sub))

try:
    import photic  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engine" / "src"))


# --- z-score report -----------------------------------------------------------------------
# Statistical tests record (test, quantity, value, reference, standard error, z) here; the
# table is printed at the end of the run so every z-score is visible in CI logs.
import numpy as np  # noqa: E402
import pytest  # noqa: E402

_ZSCORES: list[tuple] = []


@pytest.fixture
def zscore(request):
    """zscore(label, value, reference, stderr) -> z, recorded for the closing table."""
    def record(label, value, reference, stderr):
        if stderr > 0:
            z = (value - reference) / stderr
        else:  # a deterministic estimate: it must equal the reference to rounding
            z = 0.0 if abs(value - reference) <= 1e-9 * abs(reference) else float("inf")
        _ZSCORES.append((request.node.name, label, value, reference, stderr, z))
        return z
    return record


_CALIBRATION: list[tuple] = []


@pytest.fixture
def calibration():
    """calibration(scene, quantity, samples, ratio, flagged): the spread of seeds' means over
    the median reported standard error, recorded for the closing table (the physics gate)."""
    def record(scene, quantity, samples, ratio, flagged):
        _CALIBRATION.append((scene, quantity, samples, ratio, flagged))
    return record


def pytest_addoption(parser):
    parser.addoption("--gate-report", default=None, metavar="FILE",
                     help="write the run's z-scores and error-bar calibration as Markdown (the physics gate)")


def _gate_markdown(session_seconds: float, outcome: str) -> str:
    lines = [f"Run: `.venv/bin/python -m pytest -m gate`, {outcome}, {session_seconds / 60:.1f} min.", ""]
    if _CALIBRATION:
        lines += ["Error bars: spread of 32 (pixels: 16) seeds' means / median reported standard error "
                  "(pixels: / the root mean square of the reported errors, per pixel then its median "
                  "over pixels, or over the whole image; flagged: seeds whose error Photic marked as "
                  "not to be trusted).", "",
                  "| scene | quantity | samples | spread / SE | flagged |", "| --- | --- | --- | --- | --- |"]
        lines += [f"| {sc} | {q} | {n:,} | {r:.2f} | {f} |" for sc, q, n, r, f in _CALIBRATION]
        lines.append("")
    if _ZSCORES:
        zs = np.array([abs(z) for *_, z in _ZSCORES if np.isfinite(z)])
        lines += [f"z-scores: {len(_ZSCORES)} comparisons with references or between integrators; "
                  f"|z| median {np.median(zs):.2f}, largest {zs.max():.2f}; "
                  f"{int(np.sum(zs > 3))} above 3.", "",
                  "| test | quantity | value | reference | stderr | z |", "| --- | --- | --- | --- | --- | --- |"]
        lines += [f"| {t} | {q} | {v:.6g} | {ref:.6g} | {se:.3g} | {z:.2f} |" for t, q, v, ref, se, z in _ZSCORES]
    return "\n".join(lines) + "\n"


def pytest_sessionstart(session):
    import time
    session.config._photic_t0 = time.perf_counter()


def pytest_terminal_summary(terminalreporter, exitstatus=0, config=None):
    tr = terminalreporter
    if _CALIBRATION:
        tr.section("Error bars: spread of seeds' means / median reported standard error (pixels: RMS)")
        tr.write_line(f"{'scene':<40} {'quantity':<18} {'samples':>9} {'ratio':>7} {'flagged':>8}")
        for sc, q, n, r, f in _CALIBRATION:
            tr.write_line(f"{sc[:40]:<40} {q[:18]:<18} {n:9d} {r:7.2f} {f:8d}")
    if _ZSCORES:
        tr.section("Monte Carlo checks: z = (value - reference) / standard error")
        tr.write_line(f"{'test':<44} {'quantity':<34} {'value':>12} {'reference':>12} {'stderr':>10} {'z':>7}")
        for test, label, v, ref, se, z in _ZSCORES:
            tr.write_line(f"{test[:44]:<44} {label[:34]:<34} {v:12.6g} {ref:12.6g} {se:10.3g} {z:7.2f}")
    config = config or tr.config
    path = config.getoption("--gate-report")
    if path:
        import time
        stats = {k: len(v) for k, v in tr.stats.items() if k in ("passed", "failed", "error", "skipped")}
        outcome = ", ".join(f"{n} {k}" for k, n in stats.items())
        seconds = time.perf_counter() - getattr(config, "_photic_t0", time.perf_counter())
        Path(path).write_text(_gate_markdown(seconds, outcome))
        tr.write_line(f"gate report: {path}")


@pytest.fixture(autouse=True)
def _unblock_embreex():
    """The add-on's engine loader blocks embreex (sys.modules['embreex'] = None: in Blender it
    clashes with the system Embree); a test that loads the add-on must not leave it blocked
    for the tests after it in the same process (photic bench casts rays with embreex)."""
    blocked_before = "embreex" in sys.modules and sys.modules["embreex"] is None
    yield
    if not blocked_before and "embreex" in sys.modules and sys.modules["embreex"] is None:
        del sys.modules["embreex"]
