"""Finding and importing the Blender add-on package (``photic_blender``) for tests, benchmarks
and the add-on's own commands. The engine itself never imports it (nor Blender)."""
from __future__ import annotations

import os
import sys
from pathlib import Path


def find_addon() -> Path:
    """The Blender add-on's folder: $PHOTIC_ADDON_DIR, else the installed add-on package
    (``pip install -e ./blender_addon``)."""
    import importlib.util
    env = os.environ.get("PHOTIC_ADDON_DIR")
    if env and (Path(env) / "__init__.py").is_file():
        return Path(env)
    spec = importlib.util.find_spec("photic_blender")
    if spec is not None and spec.origin:
        return Path(spec.origin).parent
    raise FileNotFoundError("the Photic Blender add-on package is not installed: pip install -e "
                            "./blender_addon (scripts/install.sh does it), or set PHOTIC_ADDON_DIR "
                            "to the add-on's folder")


def load_addon():
    """Import the add-on package (``photic_blender``, which imports ``bpy``): for tests,
    benchmarks and the add-on's own commands; the engine itself never calls it."""
    import importlib
    import importlib.util

    if "photic_blender" in sys.modules:
        return sys.modules["photic_blender"]
    env = os.environ.get("PHOTIC_ADDON_DIR")
    if not env and importlib.util.find_spec("photic_blender") is not None:
        return importlib.import_module("photic_blender")
    folder = find_addon()
    spec = importlib.util.spec_from_file_location("photic_blender", folder / "__init__.py",
                                                  submodule_search_locations=[str(folder)])
    module = importlib.util.module_from_spec(spec)
    sys.modules["photic_blender"] = module
    spec.loader.exec_module(module)
    return module
