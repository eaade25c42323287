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
    from ..output import atomic_file
    text = _dumps(scene.to_dict()) + "\n"
    with atomic_file(path, "w", encoding="utf-8") as f:  # never a truncated scene file
        f.write(text)


def check_npz(path, names=None, limit_bytes: int | None = None) -> dict[str, tuple]:
    """{name: (shape, dtype)} of the arrays of a .npz file, read from their headers only, after
    checking that each array is whole (its member holds header + shape x itemsize bytes: a
    truncated file, or a header claiming 256 GiB, made numpy fail deep inside or allocate the
    claim) and, with ``limit_bytes``, that the arrays in ``names`` (default all) fit in it.
    ValueError saying what is wrong (the callers name the object and field)."""
    import zipfile

    import numpy as np
    from numpy.lib import format as npformat
    path = Path(path)
    out: dict[str, tuple] = {}
    try:
        with zipfile.ZipFile(path) as zf:
            members = {i.filename[:-4] if i.filename.endswith(".npy") else i.filename: i
                       for i in zf.infolist()}
            total = 0
            for name, info in members.items():
                if names is not None and name not in names:
                    continue
                with zf.open(info) as f:
                    version = npformat.read_magic(f)
                    if version == (1, 0):
                        shape, fortran, dtype = npformat.read_array_header_1_0(f)
                    else:
                        shape, fortran, dtype = npformat.read_array_header_2_0(f)
                    header = f.tell()
                if dtype.hasobject:
                    raise ValueError(f"array {name!r} holds Python objects, not numbers")
                nbytes = int(np.prod(shape, dtype=object)) * dtype.itemsize
                if info.file_size < header + nbytes:
                    raise ValueError(f"array {name!r} is cut short or its header lies: it claims "
                                     f"shape {tuple(shape)} of {dtype} ({_size(nbytes)}) but the "
                                     f"file holds {_size(max(0, info.file_size - header))} of it")
                total += nbytes
                out[name] = (tuple(shape), dtype)
            if limit_bytes is not None and total > limit_bytes:
                raise ValueError(f"its arrays need {_size(total)} of memory, more than the "
                                 f"{_size(limit_bytes)} this machine can give them")
    except zipfile.BadZipFile as exc:
        raise ValueError(f"not a whole .npz (zip) file: {exc}") from None
    except (EOFError, OSError) as exc:
        raise ValueError(f"cannot read it: {exc}") from None
    return out


def _size(n: int) -> str:
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} bytes"
