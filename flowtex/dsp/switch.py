"""Crossfading two-way switch: y = (1 - w) a + w b, with w ramping to 1 when ``index`` names ``b``.

Used to change the active surface at run time (flowtex/nodes/switch.py). The
mix is a convex combination of the two inputs, so at every tick and for every
element ``min(a, b) <= y <= max(a, b)``: a switch can never produce a value
larger than either source (no burst). ``w`` moves towards its target by
``step`` (= 1 / fade ticks) per tick; NaN in ``index`` keeps the current target.

State ``s``: [w, target]. Params ``p``: [b_index, step]. Allocation-free.
"""

from __future__ import annotations

import numpy as np
from numba import njit

S_W = 0
S_TARGET = 1
STATE_SIZE = 2


def switch_params(b_index: int, fade_ticks: float) -> np.ndarray:
    """Params for :func:`crossfade_block`: ``b`` is chosen when round(index) == b_index; fade over ``fade_ticks`` ticks (0: instant)."""
    step = 1.0 if fade_ticks <= 1.0 else 1.0 / fade_ticks
    return np.array([float(b_index), step])


@njit(cache=True)
def crossfade_block(p: np.ndarray, s: np.ndarray, index: np.ndarray, a: np.ndarray, b: np.ndarray, y: np.ndarray) -> None:
    """One block: rows of ``index`` (n, 1), ``a`` and ``b`` (n, width) -> ``y`` (n, width)."""
    b_index = p[0]
    step = p[1]
    w = s[S_W]
    target = s[S_TARGET]
    for t in range(index.shape[0]):
        k = index[t, 0]
        if k == k:
            target = 1.0 if np.floor(k + 0.5) == b_index else 0.0
        if w < target:
            w = min(target, w + step)
        elif w > target:
            w = max(target, w - step)
        u = 1.0 - w
        for c in range(a.shape[1]):
            y[t, c] = u * a[t, c] + w * b[t, c]
    s[S_W] = w
    s[S_TARGET] = target
