"""Files written whole or not at all, and CSV cells a spreadsheet takes as text: what every
writer of outputs uses (photic.output, photic.derived, photic.scene.files, photic.distributed),
kept free of the render's imports so that each can use it without import circles."""
from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path


@contextlib.contextmanager
def atomic_file(path, mode: str = "w", **kw):
    """Open ``path`` for writing under a temporary name beside it, flushed to the disk and
    renamed to ``path`` when the block ends without an error (os.replace: atomic on one file
    system); on an error (a full disk, a name that cannot be encoded) the temporary file is
    removed and an existing file of that name is left as it was: a reader never sees a
    truncated file under the final name."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "a folder of that name is in the way", str(path))
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, mode, **kw) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()


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
