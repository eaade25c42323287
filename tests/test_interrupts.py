"""Ctrl-C never crashes (issue 49, kind 1): ``photic blend`` interrupted while it loads, while
it exports or while it renders stops with exit status 130 and the right message, its worker
threads joined (no SIGABRT 'terminate called without an active exception', no traceback); a
second Ctrl-C stops it at once, still without one; ``photic batch`` on a local cluster prints
no worker tracebacks and keeps its finished units. Ctrl-C is sent as a terminal sends it: to
the whole process group."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BLEND = ROOT / "example_blends" / "underwater_objects.blend"
JOB = ROOT / "examples" / "jobs" / "problem2_sweep.json"

pytest.importorskip("bpy")


def _start(args, cwd) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "photic", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _ctrl_c(p: subprocess.Popen) -> None:
    os.killpg(p.pid, signal.SIGINT)


def _wait_for(p: subprocess.Popen, ready, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while not ready():
        assert p.poll() is None, (p.returncode, p.communicate())
        assert time.monotonic() - t0 < timeout, "never got ready"
        time.sleep(0.05)


def _clean_end(p: subprocess.Popen, within_s: float) -> tuple[str, str]:
    try:
        out, err = p.communicate(timeout=within_s)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        pytest.fail(f"did not stop within {within_s} s: {err[-2000:]}")
    assert p.returncode == 130, (p.returncode, out[-1000:], err[-3000:])
    for bad in ("Traceback", "terminate called", "KeyboardInterrupt", "did not run"):
        assert bad not in err and bad not in out, (bad, err[-3000:])
    return out, err


@pytest.mark.parametrize("when", ["loading", "rendering"])
def test_ctrl_c_stops_photic_blend_cleanly_with_the_right_message(tmp_path, when):
    out_dir = tmp_path / "out"
    p = _start(["blend", str(BLEND), "--out", str(out_dir), "--threads", "1"], tmp_path)
    if when == "loading":
        time.sleep(0.5)  # photic and bpy being imported
    else:
        _wait_for(p, lambda: (out_dir / ".").exists() or False)  # out created: the file is open
        time.sleep(3.0)  # the render running (its first pass takes longer than this)
    t0 = time.monotonic()
    _ctrl_c(p)
    out, err = _clean_end(p, within_s=30)
    if when == "loading":
        assert "interrupted before the render started; nothing was written" in err or \
            "cancelled before the first sample; nothing was written" in err, err
    else:
        assert "stopping; keeping what is finished" in err, err
        assert time.monotonic() - t0 < 15
    if "nothing was written" in err:
        assert not out_dir.exists() or not any(out_dir.iterdir())


def test_a_second_ctrl_c_stops_photic_blend_at_once_without_a_traceback(tmp_path):
    out_dir = tmp_path / "out"
    p = _start(["blend", str(BLEND), "--out", str(out_dir), "--threads", "1"], tmp_path)
    _wait_for(p, lambda: out_dir.exists())
    time.sleep(2.0)
    _ctrl_c(p)
    time.sleep(0.05)
    _ctrl_c(p)
    _, err = _clean_end(p, within_s=15)
    assert "stopping" in err


def test_ctrl_c_on_a_local_cluster_batch_prints_no_worker_tracebacks(tmp_path):
    out_dir = tmp_path / "batch"
    p = _start(["batch", str(JOB), "--out", str(out_dir), "--workers", "2", "--quiet"], tmp_path)
    units = out_dir / "units"
    _wait_for(p, lambda: units.exists() and any(units.rglob("*.npz")), timeout=240)
    _ctrl_c(p)
    _, err = _clean_end(p, within_s=60)
    assert "interrupted; the finished units are kept" in err, err
    assert any(units.rglob("*.npz"))


@pytest.mark.parametrize("launcher", ["console script", "python -m photic"])
@pytest.mark.parametrize("after_s", [0.15, 0.3, 0.6])
def test_ctrl_c_while_photic_render_loads_or_starts_prints_no_traceback(tmp_path, launcher, after_s):
    """While numpy and the engine load, while the scene is read, or once the render runs, a
    Ctrl-C ends ``photic render`` with status 130 and a line, never a KeyboardInterrupt
    traceback (the entry point, photic._launch, handles it from Python's first ~0.05 s on)."""
    script = Path(sys.executable).with_name("photic")
    cmd = [str(script)] if launcher == "console script" else [sys.executable, "-m", "photic"]
    if launcher == "console script" and not script.exists():
        pytest.skip("the photic console script is not installed beside this Python")
    p = subprocess.Popen([*cmd, "render", str(ROOT / "examples" / "stepped_pool.json"), "--out",
                          str(tmp_path / "out"), "--threads", "1"], cwd=tmp_path, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    time.sleep(after_s)
    _ctrl_c(p)
    out, err = _clean_end(p, within_s=30)
    assert "photic: interrupted" in err or "stopping; writing the partial result" in err, err
