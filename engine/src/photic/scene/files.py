"""Scene files: ``load_scene`` (refusing duplicate keys and deep nesting) and ``save_scene``.
"""
from __future__ import annotations

import json
from pathlib import Path

from .checks import SceneError
from .model import Scene
from .writing import _dumps


# ----------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------

def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file; relative mesh paths are relative to its directory.

    Raises
    ------
    SceneError
        If the file cannot be read, is not valid JSON, or the scene is invalid.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError("scene", str(path), f"cannot read scene file: {exc}") from exc
    try:
        d = json.loads(text, object_pairs_hook=_no_duplicate_keys)
    except json.JSONDecodeError as exc:
        raise SceneError("scene", str(path), f"invalid JSON at line {exc.lineno} column "
                                             f"{exc.colno}: {exc.msg}") from exc
    except _DuplicateKey as exc:
        raise SceneError("scene", str(path), f"the key {exc.args[0]!r} appears twice in one "
                                             f"object (which value is meant?)") from exc
    except RecursionError as exc:
        raise SceneError("scene", str(path), "JSON nested too deeply (a scene needs a few "
                                             "levels)") from exc
    return Scene.from_dict(d, base_dir=path.resolve().parent)


class _DuplicateKey(ValueError):
    pass


def _no_duplicate_keys(pairs: list) -> dict:
    """A JSON object as a dict, refusing a key given twice (json keeps the last silently)."""
    out = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write a scene as JSON (meshes inline)."""
    from ..safe_io import atomic_file
    text = _dumps(scene.to_dict()) + "\n"
    with atomic_file(path, "w", encoding="utf-8") as f:  # never a truncated scene file
        f.write(text)

