"""What benchmarks that keep a baseline in the same process share: the old code swapped in where the product calls the
new (:func:`swapped`), and the CPU time of one call (:func:`cpu_per_call`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any


@contextmanager
def swapped(replacements: Mapping[tuple[Any, str], Callable]) -> Iterator[None]:
    """``(module, name) -> function``: each set on its module for the block, the module's own put back after it."""
    kept = {key: getattr(*key) for key in replacements}
    try:
        for (module, name), fn in replacements.items():
            setattr(module, name, fn)
        yield
    finally:
        for (module, name), fn in kept.items():
            setattr(module, name, fn)


def cpu_per_call(fn: Callable, args: tuple, rounds: int, min_s: float) -> float:
    """Best over ``rounds`` of the CPU seconds per call of ``fn(*args)`` (each round repeats it for at least ``min_s``
    seconds of CPU)."""
    best = float("inf")
    for _ in range(rounds):
        t, k = time.process_time(), 0
        while time.process_time() - t < min_s or k == 0:
            fn(*args)
            k += 1
        best = min(best, (time.process_time() - t) / k)
    return best
