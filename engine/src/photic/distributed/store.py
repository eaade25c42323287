"""Unit result files: one .npz per unit, written atomically, checked when read.

A file is written to a temporary name in its folder and renamed over the final one, so a
file under the final name is always complete; it holds the unit's id, its item's
fingerprint and a sha256 of its arrays, so resume trusts it only when all three match
(a changed job, a different item or a damaged file are computed again). A unit computed
twice (a lost worker's retry) writes the same arrays under the same name: the merge reads
one file per unit id, so nothing is counted twice.
"""
from __future__ import annotations

import hashlib
import json
import os
import uuid
import zipfile
from pathlib import Path

import numpy as np

from .units import Unit


def arrays_digest(arrays: dict) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


class UnitStore:
    """The unit files of a batch under ``root/units/<item>/<unit id>.npz``."""

    def __init__(self, root):
        self.root = Path(root) / "units"

    def path(self, unit: Unit) -> Path:
        return self.root / unit.item / f"{unit.id}.npz"

    def write(self, unit: Unit, result: dict) -> Path:
        path = self.path(unit)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = dict(result["meta"], sha256=arrays_digest(result["arrays"]))
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp")
        try:
            with open(tmp, "wb") as f:
                np.savez(f, __meta__=np.array(json.dumps(meta)), **result["arrays"])
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, path)  # atomic: readers see the old file or the whole new one
        finally:
            if tmp.exists():
                tmp.unlink()
        return path

    def read(self, unit: Unit, fingerprint: str) -> dict | None:
        """The unit's result, or None when its file is missing, damaged or of another job."""
        path = self.path(unit)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as f:
                meta = json.loads(str(f["__meta__"]))
                arrays = {k: f[k] for k in f.files if k != "__meta__"}
        except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError, EOFError):
            return None
        if (meta.get("unit") != unit.id or meta.get("fingerprint") != fingerprint
                or meta.get("sha256") != arrays_digest(arrays)):
            return None
        return {"meta": meta, "arrays": arrays}

    def valid(self, unit: Unit, fingerprint: str) -> bool:
        return self.read(unit, fingerprint) is not None
