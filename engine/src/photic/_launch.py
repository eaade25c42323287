"""The ``photic`` command's entry point (and ``python -m photic``'s): a Ctrl-C that no command
handles (while numpy and the engine load, or a scene is read, before a command installs its
own handler) ends the command quietly with exit status 130, where Python printed a
KeyboardInterrupt traceback. For ``photic blend`` the first one while loading is only recorded
(a KeyboardInterrupt inside bpy's import crashed the process): photic blend then says it was
interrupted before the render."""
from __future__ import annotations

import os
import signal
import sys


def main() -> int:
    import photic

    blend = sys.argv[1:2] == ["blend"]
    interrupted = []

    def loading(signum, frame):
        if blend and not getattr(photic, "_interrupted_while_loading", False):
            photic._interrupted_while_loading = True
            return
        interrupted.append(True)
        raise SystemExit(130)

    signal.signal(signal.SIGINT, loading)
    try:
        from .cli import main as cli_main
        if not blend:  # (photic.cli's commands install their own handlers from here on)
            signal.signal(signal.SIGINT, signal.default_int_handler)
        return cli_main()
    except BaseException as exc:
        # (a compiled module's import turns the interrupt into an ImportError, which numpy's
        # import turns into another)
        if not (interrupted or _interrupt_in(exc)):
            raise
        sys.stderr.write("\nphotic: interrupted\n")
        # Out at once: an interrupt met inside code that a compiled module ran marks the
        # interpreter, which would then end itself by SIGINT at exit (status -2, not 130).
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)


def _interrupt_in(exc: BaseException | None) -> bool:
    """Whether exc is a KeyboardInterrupt or was caused by one."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False
