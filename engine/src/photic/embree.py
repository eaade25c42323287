"""Where the Embree the core traces with comes from: the Embree 4 library of the embreex wheel.

``photic._core`` calls :func:`library_path` when it is imported and loads the library itself
(dlopen), with its start-up checks (``engine/src/core/embree.cpp``); ``photic._core.EMBREE``
then names the version and file. The wheels put the library beside the package:

- Linux (auditwheel): ``site-packages/embreex.libs/libembree4-<hash>.so.4``, its TBB beside it;
- macOS (delocate): ``site-packages/embreex/.dylibs/libembree4.4.dylib``;
- Windows (delvewheel): ``site-packages/embreex.libs/embree4.dll`` with ``tbb12.dll``.

embreex is found, not imported: its own modules link the same library by name, and in a
process that already holds the system's Embree 3 (Debian's Blender) they would bind to that one.
``PHOTIC_EMBREE_LIBRARY`` names another library file instead (any Embree 4.3+ built with
Embree's default instance settings).
"""
from __future__ import annotations

import importlib.machinery
import os
import sys
from pathlib import Path

ENV = "PHOTIC_EMBREE_LIBRARY"


def _patterns() -> list[tuple[str, str]]:
    """(folder relative to the embreex package, file pattern) for this platform."""
    if sys.platform == "darwin":
        return [(".dylibs", "libembree4*.dylib")]
    if sys.platform == "win32":
        return [(os.pardir + "/embreex.libs", "embree4*.dll"), (".", "embree4*.dll")]
    return [(os.pardir + "/embreex.libs", "libembree4*.so*")]


def library_path() -> str:
    """The Embree 4 shared library to load: ``$PHOTIC_EMBREE_LIBRARY``, else the one shipped with
    the installed embreex. Raises ImportError naming what is missing."""
    override = os.environ.get(ENV)
    if override:
        return override
    # PathFinder, not importlib.util.find_spec: it searches sys.path even where embreex has been
    # blocked in sys.modules (the add-on does so inside a Blender holding Embree 3).
    spec = importlib.machinery.PathFinder.find_spec("embreex")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("photic needs the embreex package, whose wheel carries the Embree 4 "
                          "library the engine traces rays with: pip install embreex")
    package = Path(spec.submodule_search_locations[0])
    for folder, pattern in _patterns():
        found = sorted((package / folder).glob(pattern))
        if found:
            return str(found[0].resolve())
    raise ImportError(f"no Embree 4 library beside embreex at {package} (looked for "
                      f"{', '.join(f'{f}/{p}' for f, p in _patterns())}); an embreex built from "
                      f"source links another Embree: name its file in {ENV}")
