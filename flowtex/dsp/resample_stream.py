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

_HEADER = 3  # p[0] = 1 for up-sampling, 0 for down-sampling; p[1] = factor; p[2] = filter length


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
    """Kernel parameters for an integer ratio (``up == 1`` or ``down == 1``)."""
    if up != 1 and down != 1:
        raise ValueError(f"the streaming resampler needs an integer ratio, got {up}/{down}")
    if up > 1:
        return np.concatenate([[1.0, up, h.size], up * h])
    return np.concatenate([[0.0, down, h.size], h])


def stream_state_sizes(h: np.ndarray, up: int, down: int, width: int) -> tuple[int, int]:
    """(float state, int state): history ring of (taps per phase) x width plus the held output; call counter, ring slot."""
    hist = -(-h.size // up) if up > 1 else h.size
    return hist * width + width, 2


@njit(cache=True, nogil=True)
def resample_block(p, s, si, x, y):
    """Advance by ``x.shape[0]`` calls; x (n, w) input rows, y (n, w) output rows (see module docstring)."""
    up = p[0] > 0.5
    factor = int(p[1])
    taps = int(p[2])
    h = p[_HEADER:_HEADER + taps]
    w = x.shape[1]
    hist = (taps + factor - 1) // factor if up else taps
    held = hist * w
    c = si[0]
    pos = si[1]  # ring slot of the newest input sample
    for r in range(x.shape[0]):
        if up:
            phase = c % factor
            if phase == 0:
                pos = pos + 1 if pos + 1 < hist else 0
                for q in range(w):
                    s[pos * w + q] = x[r, q]
            for q in range(w):
                acc = 0.0
                slot = pos
                for j in range(phase, taps, factor):
                    acc += h[j] * s[slot * w + q]
                    slot = slot - 1 if slot > 0 else hist - 1
                y[r, q] = acc
        else:
            pos = pos + 1 if pos + 1 < hist else 0
            for q in range(w):
                s[pos * w + q] = x[r, q]
            if c % factor == 0:
                for q in range(w):
                    acc = 0.0
                    slot = pos
                    for j in range(taps):
                        acc += h[j] * s[slot * w + q]
                        slot = slot - 1 if slot > 0 else hist - 1
                    s[held + q] = acc
            for q in range(w):
                y[r, q] = s[held + q]
        c += 1
        if c == factor:
            c = 0
    si[0] = c
    si[1] = pos
