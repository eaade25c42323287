"""Import of the Photic engine, late and at most once.

The add-on registers even when the engine cannot be imported (no compiled core for this
Python, a missing wheel): the panels then show the reason instead of the settings. Heavy
imports stay out of ``register`` so Blender starts quickly (as Cycles does with its core).

Where the engine comes from, first found wins:

1. already importable (``bpy`` in the same virtual environment, or an extension's wheels);
2. ``site_packages.txt`` beside this file, written by ``scripts/install_blender_addon.py`` for a
   distribution Blender: one site-packages directory per line, added with ``site.addsitedir``
   (so editable installs' ``.pth`` hooks work);
3. the ``PHOTIC_SITE_PACKAGES`` environment variable (``os.pathsep``-separated directories).

Directories are appended, so Blender's own modules keep precedence.

Embree: the engine's core is imported normally (with ``RTLD_DEEPBIND`` its C++ runtime symbols
would bind privately and Blender 3.4 aborts at exit) and loads the Embree 4 library of the
embreex wheel itself, by path and with ``RTLD_DEEPBIND`` (``photic.embree``), so that library
binds to itself and its own TBB even in a Blender that links the system's Embree 3 and TBB under
the same symbol names. embreex's Python modules, which link that library by name, are not
needed by the add-on, but trimesh (used for the closedness check of water meshes) imports them
when installed, and their ray calls then crash in a Blender that already holds the system Embree
3 ("inputs are from different devices"). In such a process embreex is therefore blocked before
anything imports it (the core finds the library without importing embreex); trimesh falls back
to its own code.
"""
from __future__ import annotations

import importlib
import os
import site
import sys
import threading
import traceback
from pathlib import Path

_engine = None
_error: str | None = None


def _candidate_dirs() -> list[str]:
    dirs = []
    listing = Path(__file__).with_name("site_packages.txt")
    if listing.is_file():
        dirs += [line.strip() for line in listing.read_text().splitlines() if line.strip()]
    dirs += [d for d in os.environ.get("PHOTIC_SITE_PACKAGES", "").split(os.pathsep) if d]
    return dirs


def add_search_paths() -> None:
    """Append the listed site-packages directories (``site_packages.txt``, then
    ``PHOTIC_SITE_PACKAGES``) to ``sys.path``. Cheap; ``__init__`` calls it before its own
    imports when numpy is missing (a distribution Blender has none; the engine's venv has)."""
    for d in _candidate_dirs():
        if Path(d).is_dir() and d not in sys.path:
            site.addsitedir(d)
    importlib.invalidate_caches()


def _system_embree_loaded() -> bool:
    """True when the process already maps a shared Embree 3 library (a distribution Blender)."""
    try:
        with open("/proc/self/maps") as maps:
            return any("libembree3" in line for line in maps)
    except OSError:
        return False


def load_engine():
    """The ``photic`` package with its compiled core, or None (see ``engine_error``)."""
    global _engine, _error
    if _engine is not None or _error is not None:
        return _engine
    try:
        if _system_embree_loaded() and "embreex" not in sys.modules:
            sys.modules["embreex"] = None  # see the module docstring
        try:
            importlib.import_module("photic._core")
        except ImportError:
            add_search_paths()
            importlib.import_module("photic._core")
        for name in ("photic.scene", "photic.render", "photic.output", "photic.iop_models",
                     "photic.waves", "photic.surface"):
            importlib.import_module(name)
        _engine = sys.modules["photic"]
    except Exception as exc:  # any failure: keep Blender running and say why
        _error = (f"the Photic engine could not be imported ({type(exc).__name__}: {exc}). "
                  f"Install the Photic extension with its wheels, or list the site-packages "
                  f"directory holding 'photic' in {Path(__file__).with_name('site_packages.txt')} "
                  f"or in PHOTIC_SITE_PACKAGES.")
        traceback.print_exc()
    return _engine


_warming: threading.Thread | None = None


def warm_up() -> None:
    """Import the engine in a background thread (once), so that the first viewport image or
    render after a file with a Photic scene opens does not wait for it (about 0.1 s of numpy,
    the core and Embree). Blender holds Python's lock only while it runs Python, so the import
    proceeds while the interface is idle; a ``load_engine`` meanwhile simply waits for the same
    modules (Python's import locks)."""
    global _warming
    if _engine is not None or _error is not None or _warming is not None:
        return
    _warming = threading.Thread(target=load_engine, name="photic-warm-up", daemon=True)
    _warming.start()


def engine_error() -> str | None:
    """Why the engine is unavailable (None when it loaded or was not tried yet)."""
    return _error


def require_engine():
    """The engine, or a RuntimeError carrying the reason."""
    engine = load_engine()
    if engine is None:
        raise RuntimeError(_error)
    return engine
