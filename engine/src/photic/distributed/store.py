"""Unit result files: one .npz per unit, written atomically, checked when read.

A file is written to a temporary name in its folder and renamed over the final one, so a
file under the final name is always complete; it holds the unit's id, its item's
fingerprint, a sha256 of its arrays and a keyed digest (HMAC-SHA256 with this user's secret
key, ``unit_key``) over the fingerprint (the job's parameters for the item), the unit's
metadata and the arrays, so resume trusts it only when all match: a changed job, a
different item or a damaged file are computed again, and so is a unit someone else wrote or
forged with a recomputed checksum (one was reused: Ed 1.76 became 1761, issue 49). A unit computed
twice (a lost worker's retry) writes the same arrays under the same name: the merge reads
one file per unit id, so nothing is counted twice.
"""
from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import stat
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


def config_dir() -> Path:
    """This user's Photic folder for secrets: $PHOTIC_CONFIG_DIR, else $XDG_CONFIG_HOME/photic,
    else ~/.config/photic."""
    if os.environ.get("PHOTIC_CONFIG_DIR"):
        return Path(os.environ["PHOTIC_CONFIG_DIR"])
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "photic"


def cache_dir() -> Path:
    """This user's Photic cache: $PHOTIC_CACHE_DIR, else $XDG_CACHE_HOME/photic, else
    ~/.cache/photic."""
    if os.environ.get("PHOTIC_CACHE_DIR"):
        return Path(os.environ["PHOTIC_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "photic"


def private_dir(path) -> Path:
    """``path`` as a folder only this user can enter (created 0700): OSError when it is a
    link, or someone else's (a shared, predictable folder such as /tmp/photic_dask let any
    user plant or read units)."""
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True, mode=0o700)
    st = os.lstat(path)
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISDIR(st.st_mode):
        raise OSError(f"{path} is not a folder of its own (a link?): refusing to keep units there")
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        raise OSError(f"{path} belongs to another user: refusing to keep units there")
    if st.st_mode & 0o077:
        os.chmod(path, 0o700)
    return path


def unit_key() -> bytes:
    """This user's secret key for the units' digests (32 random bytes in config_dir()/unit-key,
    readable by this user only), created on first use."""
    folder = private_dir(config_dir())
    path = folder / "unit-key"
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        key = bytes.fromhex(path.read_text().strip())
        if len(key) < 32:
            raise OSError(f"{path}: not a Photic unit key (delete it to make a new one)")
        return key
    key = secrets.token_bytes(32)
    with os.fdopen(fd, "w") as f:
        f.write(key.hex() + "\n")
    return key


def unit_digest(key: bytes, meta: dict, arrays_sha256: str) -> str:
    """HMAC-SHA256 over the unit's metadata (its id, the item's fingerprint, passes, ...) and
    the sha256 of its arrays."""
    body = {k: v for k, v in meta.items() if k not in ("sha256", "hmac")}
    body = json.loads(json.dumps(body, default=str))  # as the file holds it
    text = json.dumps(body, sort_keys=True) + "|" + arrays_sha256
    return hmac.new(key, text.encode("utf-8"), hashlib.sha256).hexdigest()


class UnitStore:
    """The unit files of a batch under ``root/units/<item>/<unit id>.npz``."""

    def __init__(self, root):
        self.root = Path(root) / "units"
        self._key: bytes | None = None

    @property
    def key(self) -> bytes:
        if self._key is None:
            self._key = unit_key()
        return self._key

    def path(self, unit: Unit) -> Path:
        return self.root / unit.item / f"{unit.id}.npz"

    def write(self, unit: Unit, result: dict) -> Path:
        path = self.path(unit)
        path.parent.mkdir(parents=True, exist_ok=True)
        digest = arrays_digest(result["arrays"])
        meta = dict(result["meta"], sha256=digest)
        meta["hmac"] = unit_digest(self.key, meta, digest)
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
        if not isinstance(meta, dict) or meta.get("unit") != unit.id or meta.get("fingerprint") != fingerprint:
            return None
        digest = arrays_digest(arrays)
        if meta.get("sha256") != digest or not hmac.compare_digest(
                str(meta.get("hmac", "")), unit_digest(self.key, meta, digest)):
            return None
        return {"meta": meta, "arrays": arrays}

    def valid(self, unit: Unit, fingerprint: str) -> bool:
        return self.read(unit, fingerprint) is not None
