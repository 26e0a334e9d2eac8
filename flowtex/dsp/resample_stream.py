"""Causal polyphase FIR resampling by an integer factor, one tick at a time (the graph's ``resample`` node).

The kernel runs at the faster of the two rates. Up-sampling by U: a new
input sample arrives on every U-th call (call index % U == 0) and every call
writes one output sample,

    y[m] = U * sum_j h[(m % U) + j U] * x[m // U - j],

exactly ``scipy.signal.upfirdn(U * h, x, U, 1)[m]``. Down-sampling by D: every
call reads one input sample; every D-th call computes

    y[k] = sum_j h[j] * x[k D - j]  (= upfirdn(h, x, 1, D)[k])

and the other calls hold it. ``h`` comes from
:func:`flowtex.dsp.filter_design.resampling_fir`, zero-padded symmetrically
so that its group delay (len(h) - 1) / 2 is a whole number of samples at both
rates: the latency is that many samples of the faster rate.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .filter_design import resampling_fir
from .layout import Field, Layout

PARAMS = Layout("float", [
    Field("up", 1, "1 up-sampling, 0 down-sampling"),
    Field("factor", 1, "U or D"),
    Field("length", 1, "filter length"),
    Field("hist", 1, "history length per component"),
    Field("coef", "ncoef", "time-reversed coefficients: down, h; up, the U polyphase branches of hist each"),
], sizes=("ncoef",))
STATE = Layout("float", [
    Field("ring", "2 * hist * w", "per component, its last hist samples stored twice"),
    Field("held", "w", "the output held between computed samples"),
], sizes=("hist", "w"))
ISTATE = Layout("int", [Field("call", 1, "call counter modulo the factor"), Field("pos", 1, "ring slot of the newest sample")])
P_UP = PARAMS.const("up")
P_FACTOR = PARAMS.const("factor")
P_HIST = PARAMS.const("hist")
P_COEF = PARAMS.const("coef")
S_RING = STATE.const("ring")
SI_CALL = ISTATE.const("call")
SI_POS = ISTATE.const("pos")

def polyphase_filter(up: int, down: int, atten_db: float, passband: float = 0.8) -> np.ndarray:
    """The resampling FIR, symmetric zero padding so that (len - 1) / 2 is a multiple of max(up, down)."""
    h = resampling_fir(up, down, atten_db, passband)
    factor = max(up, down)
    half = (h.size - 1) // 2
    pad = (-half) % factor
    return np.concatenate([np.zeros(pad), h, np.zeros(pad)])


def latency_samples(h: np.ndarray) -> int:
    """Group delay of the filter in samples of the faster rate."""
    return (h.size - 1) // 2


def stream_params(h: np.ndarray, up: int, down: int) -> np.ndarray:
    """Kernel parameters for an integer ratio (``up == 1`` or ``down == 1``).

    Coefficients are stored time-reversed (oldest sample first) so that each
    output is one contiguous dot product: down-sampling, ``h`` itself; up-sampling,
    the U polyphase branches ``U * h[phase::U]`` (zero-padded to one length).
    """
    if up != 1 and down != 1:
        raise ValueError(f"the streaming resampler needs an integer ratio, got {up}/{down}")
    if up > 1:
        hist = -(-h.size // up)
        branches = np.zeros((up, hist))
        for phase in range(up):
            g = up * h[phase::up]
            branches[phase, :g.size] = g
        coef = branches[:, ::-1].ravel()
        return PARAMS.pack({"up": 1.0, "factor": up, "length": h.size, "hist": hist, "coef": coef}, ncoef=coef.size)
    return PARAMS.pack({"up": 0.0, "factor": down, "length": h.size, "hist": h.size, "coef": h[::-1]}, ncoef=h.size)


def stream_state_sizes(h: np.ndarray, up: int, down: int, width: int) -> tuple[int, int]:
    """(float state, int state): a doubled history ring per component plus the held output; call counter, ring slot."""
    return STATE.size(hist=history_length(h, up), w=width), ISTATE.size()


def history_length(h: np.ndarray, up: int) -> int:
    """Samples of history per component: the polyphase branch length when up-sampling, else the filter's."""
    return -(-h.size // up) if up > 1 else h.size


@njit(cache=True, nogil=True)
def resample_block(p, s, si, x, y):
    """Advance by ``x.shape[0]`` calls; x (n, w) input rows, y (n, w) output rows (see module docstring).

    Each component's history is a ring of ``hist`` samples stored twice
    (slots k and k + hist), so the last ``hist`` samples, oldest first, are
    always the contiguous run ``pos + 1 .. pos + hist``.
    """
    up = p[P_UP] > 0.5
    factor = int(p[P_FACTOR])
    hist = int(p[P_HIST])
    coef = p[P_COEF:]
    w = x.shape[1]
    span = 2 * hist
    held = S_RING + span * w
    c = si[SI_CALL]
    pos = si[SI_POS]  # ring slot of the newest input sample
    for r in range(x.shape[0]):
        fresh = (c == 0) if up else True
        if fresh:
            pos = pos + 1 if pos + 1 < hist else 0
            for q in range(w):
                s[S_RING + q * span + pos] = x[r, q]
                s[S_RING + q * span + pos + hist] = x[r, q]
        if up or c == 0:
            g = c * hist if up else 0
            for q in range(w):
                base = S_RING + q * span + pos + 1
                acc = 0.0
                for j in range(hist):
                    acc += coef[g + j] * s[base + j]
                s[held + q] = acc
        for q in range(w):
            y[r, q] = s[held + q]
        c += 1
        if c == factor:
            c = 0
    si[SI_CALL] = c
    si[SI_POS] = pos
