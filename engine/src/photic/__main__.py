import signal
import sys

if sys.argv[1:2] == ["blend"]:
    # A Ctrl-C while numpy and photic load (before photic.cli can install its handler)
    # is recorded, not raised: photic blend then says it was interrupted before the render.
    import photic

    def _loading(signum, frame):
        if getattr(photic, "_interrupted_while_loading", False):
            raise SystemExit(130)
        photic._interrupted_while_loading = True

    signal.signal(signal.SIGINT, _loading)

from .cli import main

sys.exit(main())
