"""flowtex: a dataflow framework for haptic signal processing.

``import flowtex`` is cheap and has no side effects: :class:`Graph`,
:func:`load_graph` and :func:`check_graph` are imported on first use (numba,
the kernels and the numba cache configuration come with them, not before).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .version import __version__

__all__ = ["Graph", "check_graph", "load_graph", "__version__"]

_LAZY = {"Graph": "flowtex.graph.compiled", "check_graph": "flowtex.graph.compiled", "load_graph": "flowtex.graph.compiled"}
"""Public name -> module that defines it, imported when the name is first used."""

if TYPE_CHECKING:  # pragma: no cover
    from .graph.compiled import Graph, check_graph, load_graph


def __getattr__(name: str) -> Any:
    if name == "SOURCE_FINGERPRINT":  # the older spelling of flowtex.cache.source_fingerprint()
        from .cache import source_fingerprint

        return source_fingerprint()
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'flowtex' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
