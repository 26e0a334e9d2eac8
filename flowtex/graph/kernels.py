"""Tiny jitted helpers the generated graph code calls (inlined by numba)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always", cache=True)
def view(f: np.ndarray, offset: int, width: int, rows: int) -> np.ndarray:
    """``rows x width`` row-major view of the float arena starting at ``offset``."""
    return f[offset:offset + rows * width].reshape((rows, width))


@njit(inline="always", cache=True)
def copy_row(f: np.ndarray, dst: int, src: int, width: int) -> None:
    """Copy ``width`` values inside the float arena (hold logic of multi-rate nodes)."""
    for q in range(width):
        f[dst + q] = f[src + q]
