"""flowtex: a dataflow framework for haptic signal processing."""

__version__ = "0.1.0"

from .cache import configure_numba_cache  # noqa: E402

# Before any kernel module is imported: numba's cache folder follows the source tree.
SOURCE_FINGERPRINT = configure_numba_cache()

from .graph.compiled import Graph, check_graph, load_graph  # noqa: E402

__all__ = ["Graph", "check_graph", "load_graph", "__version__"]
