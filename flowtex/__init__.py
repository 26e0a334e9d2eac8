"""flowtex: a dataflow framework for haptic signal processing."""

__version__ = "0.1.0"

import os as _os
import sys as _sys

try:
    from .cache import configure_numba_cache

    # Before any kernel module is imported: numba's cache folder follows the source tree.
    SOURCE_FINGERPRINT = configure_numba_cache()

    from .graph.compiled import Graph, check_graph, load_graph
except KeyboardInterrupt:
    # Ctrl-C while the command line starts (numba and the kernels load for a second or two): the command's
    # "interrupted" and exit code 130 (docs/cli.md), not a traceback. Elsewhere (a REPL) the interrupt stays one.
    if _sys.argv[:1] == ["-m"] or _os.path.basename(_sys.argv[0] if _sys.argv else "") == "flowtex":
        print("interrupted", file=_sys.stderr)
        raise SystemExit(130) from None
    raise

__all__ = ["Graph", "check_graph", "load_graph", "__version__"]
