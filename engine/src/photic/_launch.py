"""The ``photic`` command's entry point (and ``python -m photic``'s): a Ctrl-C that no command
handles (while numpy and the engine load, or a scene is read, before a command installs its
own handler) ends the command quietly with exit status 130, where Python printed a
KeyboardInterrupt traceback. For ``photic blend`` the first one while loading is only recorded
(a KeyboardInterrupt inside bpy's import crashed the process): photic blend then says it was
interrupted before the render."""
from __future__ import annotations

import signal
import sys


def main() -> int:
    import photic

    blend = sys.argv[1:2] == ["blend"]

    def loading(signum, frame):
        if blend and not getattr(photic, "_interrupted_while_loading", False):
            photic._interrupted_while_loading = True
            return
        sys.stderr.write("photic: interrupted while loading\n")
        raise SystemExit(130)

    signal.signal(signal.SIGINT, loading)
    from .cli import main as cli_main
    if not blend:  # (photic.cli's commands install their own handlers from here on)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return cli_main()
    except BaseException as exc:  # (a compiled module's import turns one into an ImportError)
        if not _interrupt_in(exc):
            raise
        sys.stderr.write("\nphotic: interrupted\n")
        return 130


def _interrupt_in(exc: BaseException | None) -> bool:
    """Whether exc is a KeyboardInterrupt or was caused by one."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False
