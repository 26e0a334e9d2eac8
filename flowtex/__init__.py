"""flowtex: a dataflow framework for haptic signal processing."""

__version__ = "0.1.0"

from .graph.compiled import Graph, check_graph, load_graph  # noqa: E402

__all__ = ["Graph", "check_graph", "load_graph", "__version__"]
