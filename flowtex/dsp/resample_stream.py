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

_HEADER = 4  # p[0] = 1 up / 0 down; p[1] = factor; p[2] = filter length; p[3] = history length per component

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
        return np.concatenate([[1.0, up, h.size, hist], branches[:, ::-1].ravel()])
    return np.concatenate([[0.0, down, h.size, h.size], h[::-1]])


def stream_state_sizes(h: np.ndarray, up: int, down: int, width: int) -> tuple[int, int]:
    """(float state, int state): a doubled history ring per component plus the held output; call counter, ring slot."""
    hist = -(-h.size // up) if up > 1 else h.size
    return 2 * hist * width + width, 2


@njit(cache=True, nogil=True)
def resample_block(p, s, si, x, y):
    """Advance by ``x.shape[0]`` calls; x (n, w) input rows, y (n, w) output rows (see module docstring).

    Each component's history is a ring of ``hist`` samples stored twice
    (slots k and k + hist), so the last ``hist`` samples, oldest first, are
    always the contiguous run ``pos + 1 .. pos + hist``.
    """
    up = p[0] > 0.5
    factor = int(p[1])
    hist = int(p[3])
    coef = p[_HEADER:]
    w = x.shape[1]
    span = 2 * hist
    held = span * w
    c = si[0]
    pos = si[1]  # ring slot of the newest input sample
    for r in range(x.shape[0]):
        fresh = (c == 0) if up else True
        if fresh:
            pos = pos + 1 if pos + 1 < hist else 0
            for q in range(w):
                s[q * span + pos] = x[r, q]
                s[q * span + pos + hist] = x[r, q]
        if up or c == 0:
            g = c * hist if up else 0
            for q in range(w):
                base = q * span + pos + 1
                acc = 0.0
                for j in range(hist):
                    acc += coef[g + j] * s[base + j]
                s[held + q] = acc
        for q in range(w):
            y[r, q] = s[held + q]
        c += 1
        if c == factor:
            c = 0
    si[0] = c
    si[1] = pos
