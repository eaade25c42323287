"""Writing files safely, with nothing of Photic's imported (a leaf module: the scene, the
outputs, the derived tables and the batch store all use it): atomic files, CSV cells that
no spreadsheet runs, JSON without NaN, and the machine's memory for size checks."""
from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path

import numpy as np


@contextlib.contextmanager
def atomic_path(path):
    """A temporary path beside ``path`` (the same suffix, for writers that choose a format by
    it) for a writer that takes a file name, not a file (OpenEXR's, Blender's image saver):
    renamed to ``path`` when the block ends without an error (os.replace: atomic on one file
    system), else removed, an existing file of that name left as it was: a reader never sees a
    truncated file under the final name."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "a folder of that name is in the way", str(path))
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        yield tmp
        if not tmp.is_file():
            raise OSError(errno.EIO, "the writer wrote nothing", str(path))
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()


@contextlib.contextmanager
def atomic_file(path, mode: str = "w", **kw):
    """Open ``path`` for writing under a temporary name beside it (atomic_path), flushed to
    the disk and renamed to ``path`` when the block ends without an error (a full disk, a name
    that cannot be encoded: the temporary file removed, an older file left whole)."""
    with atomic_path(path) as tmp:
        with open(tmp, mode, **kw) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())


_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_text(x):
    """A CSV cell: '' for a value that is missing (None); text that a spreadsheet would take
    for a formula (beginning with = + - @, a tab or a carriage return: a radiometer named
    '=HYPERLINK(...)') with an apostrophe in front, as spreadsheets write it. Numbers as
    they are."""
    if x is None:
        return ""
    if isinstance(x, str) and x.startswith(_FORMULA_START):
        return "'" + x
    return x



def json_safe(x):
    """``x`` with every float that is not finite (NaN, inf) as None (null): JSON has no NaN,
    and a reader that takes Python's 'NaN' would take it for a number."""
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist())
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def machine_memory() -> int | None:
    """Bytes of physical memory (None where unknown)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return None


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
