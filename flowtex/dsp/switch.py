"""Crossfading two-way switch: y = (1 - w) a + w b, with w ramping to 1 when ``index`` names ``b``.

Used to change the active surface at run time (flowtex/nodes/switch.py). The
mix is a convex combination of the two inputs, so at every tick and for every
element ``min(a, b) <= y <= max(a, b)``: a switch can never produce a value
larger than either source (no burst). ``w`` moves towards its target by
``step`` (= 1 / fade ticks) per tick.

Chains. N surfaces are chosen by a chain of N - 1 switches, switch i (b_index
i) mixing the chain so far (a) with surface i (b). For a change from surface j
to surface k to be a crossfade of exactly those two (no third surface leaking
in during the fade), a switch acts on the index k as follows:

* k > b_index: a later switch has the surface; this one is masked and holds
  its w (if it carries the old surface j < k, the chain keeps delivering it
  to switch k, which fades it out);
* k == b_index: fade towards b; but if the previous index was above b_index
  (masked), jump to b at once: its output was hidden, and switch j (j > k)
  fades out towards it;
* k < b_index: fade towards a; jump at once if the previous index was above
  b_index (hidden, see above).

NaN or negative ``index`` keeps everything as it is. If the index changes
again within a fade, the mix stays convex over the surfaces involved but may
step. State ``s``: [w, last index]. Params ``p``: [b_index, step].
Allocation-free.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .layout import Field, Layout

PARAMS = Layout("float", [Field("b_index", 1, "index value choosing b"), Field("step", 1, "change of w per tick")])
STATE = Layout("float", [Field("w", 1, "weight of b"),
                         Field("last", 1, "the last valid index (rounded); 0 at the start: the chain starts on surface 0")])
P_B_INDEX = PARAMS.const("b_index")
P_STEP = PARAMS.const("step")
S_W = STATE.const("w")
S_LAST = STATE.const("last")
STATE_SIZE = STATE.size()


def switch_params(b_index: int, fade_ticks: float) -> np.ndarray:
    """Params for :func:`crossfade_block`: ``b`` is chosen when round(index) == b_index; fade over ``fade_ticks`` ticks (0: instant)."""
    step = 1.0 if fade_ticks <= 1.0 else 1.0 / fade_ticks
    return PARAMS.pack({"b_index": float(b_index), "step": step})


@njit(cache=True)
def crossfade_block(p: np.ndarray, s: np.ndarray, index: np.ndarray, a: np.ndarray, b: np.ndarray, y: np.ndarray) -> None:
    """One block: rows of ``index`` (n, 1), ``a`` and ``b`` (n, width) -> ``y`` (n, width)."""
    b_index = p[P_B_INDEX]
    step = p[P_STEP]
    w = s[S_W]
    last = s[S_LAST]
    for t in range(index.shape[0]):
        k = index[t, 0]
        if k == k and k >= -0.5:
            k = np.floor(k + 0.5)
            if k == b_index:
                w = 1.0 if last > b_index else min(1.0, w + step)
            elif k < b_index:
                w = 0.0 if last > b_index else max(0.0, w - step)
            last = k
        else:  # NaN or negative: keep the current choice and any fade in progress
            if last == b_index:
                w = min(1.0, w + step)
            elif last < b_index:
                w = max(0.0, w - step)
        u = 1.0 - w
        for c in range(a.shape[1]):
            y[t, c] = u * a[t, c] + w * b[t, c]
    s[S_W] = w
    s[S_LAST] = last
