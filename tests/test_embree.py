"""The Embree the core traces with: embreex's Embree 4, loaded when ``photic._core`` is imported
(``photic/embree.py`` finds it, ``engine/src/core/embree.cpp`` loads and checks it)."""
from __future__ import annotations

import importlib.machinery
import os
import subprocess
import sys
from pathlib import Path

import pytest

import photic._core as core
from photic import embree
from photic.compile import compile_scene
from photic.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]


def test_the_core_traces_with_the_embree_of_the_embreex_wheel():
    version, _, path = core.EMBREE.removeprefix("Embree ").partition(" from ")
    assert version.startswith("4."), core.EMBREE
    assert path == embree.library_path()
    spec = importlib.machinery.PathFinder.find_spec("embreex")
    site = Path(spec.submodule_search_locations[0]).parent
    assert Path(path).is_relative_to(site), (path, site)
    # Mapped, and no Embree 3 with it (the core linked the system's); bpy, when an earlier test
    # imported it, maps an Embree 4 of its own.
    with open("/proc/self/maps") as maps:
        mapped = {ln.split()[-1] for ln in maps if "libembree" in ln}
    assert path in mapped and not any("libembree3" in m for m in mapped), mapped


def test_embree_errors_become_python_exceptions():
    with pytest.raises(core.EmbreeError, match="rtcNewGeometry: RTC_ERROR"):
        core.Scene.embree_error_probe()
    assert issubclass(core.EmbreeError, RuntimeError)
    # The error was taken with it: the next scene builds on this thread start clean.
    compile_scene(load_scene(ROOT / "examples" / "stepped_pool.json"))


def test_without_embreex_the_reason_is_given(monkeypatch):
    monkeypatch.delenv(embree.ENV, raising=False)
    monkeypatch.setattr(importlib.machinery.PathFinder, "find_spec", classmethod(lambda cls, name: None))
    with pytest.raises(ImportError, match="pip install embreex"):
        embree.library_path()


def _import_core_with(library: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, **{embree.ENV: library})
    return subprocess.run([sys.executable, "-c", "import photic._core"], env=env,
                          capture_output=True, text=True, timeout=120)


def test_a_missing_library_fails_the_import_with_its_path(tmp_path):
    proc = _import_core_with(str(tmp_path / "libembree4.so.4"))
    assert proc.returncode != 0
    assert "ImportError: cannot load Embree from" in proc.stderr, proc.stderr[-2000:]


@pytest.mark.skipif(not Path("/lib/x86_64-linux-gnu/libembree3.so.3").exists(),
                    reason="no system Embree 3 to try")
def test_embree_3_is_refused_at_start_up():
    proc = _import_core_with("/lib/x86_64-linux-gnu/libembree3.so.3")
    assert proc.returncode != 0
    assert "the core needs Embree 4" in proc.stderr, proc.stderr[-2000:]
