"""Make ``photic`` importable from the source tree when it is not installed."""
import sys
from pathlib import Path

try:
    import photic  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "engine" / "src"))


# --- z-score report -----------------------------------------------------------------------
# Statistical tests record (test, quantity, value, reference, standard error, z) here; the
# table is printed at the end of the run so every z-score is visible in CI logs.
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


def pytest_terminal_summary(terminalreporter):
    if not _ZSCORES:
        return
    tr = terminalreporter
    tr.section("Monte Carlo checks: z = (value - reference) / standard error")
    tr.write_line(f"{'test':<44} {'quantity':<34} {'value':>12} {'reference':>12} {'stderr':>10} {'z':>7}")
    for test, label, v, ref, se, z in _ZSCORES:
        tr.write_line(f"{test[:44]:<44} {label[:34]:<34} {v:12.6g} {ref:12.6g} {se:10.3g} {z:7.2f}")


@pytest.fixture(autouse=True)
def _unblock_embreex():
    """The add-on's engine loader blocks embreex (sys.modules['embreex'] = None: in Blender it
    clashes with the system Embree); a test that loads the add-on must not leave it blocked
    for the tests after it in the same process (photic bench casts rays with embreex)."""
    blocked_before = "embreex" in sys.modules and sys.modules["embreex"] is None
    yield
    if not blocked_before and "embreex" in sys.modules and sys.modules["embreex"] is None:
        del sys.modules["embreex"]
