"""Peak Python allocation of a call, for tests and benchmarks that bound memory (tracemalloc)."""

from __future__ import annotations

import tracemalloc
from collections.abc import Callable


def peak_bytes(fn: Callable[[], object]) -> int:
    """Peak bytes Python allocated while ``fn()`` ran (tracemalloc, which slows Python: time it in a run of its own)."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
