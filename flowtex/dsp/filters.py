"""Linear filter kernels: cascaded biquads, first-order low-pass, backward difference.

All kernels work on blocks: ``x`` and ``y`` are ``(n, channels)`` arrays and
each channel is filtered independently with its own state, so a 3-axis
position filters as three scalar signals.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fastmath import FASTMATH
from .layout import Field, Layout

SECTION = Layout("float", [Field("b0"), Field("b1"), Field("b2"), Field("a1"), Field("a2")])
"""One biquad's coefficients (a0 normalised to 1); a cascade's are ``sections`` of these in a row."""
SECTION_MEMORY = Layout("float", [Field("x1", 1, "x[t-1]"), Field("x2", 1, "x[t-2]"), Field("y1", 1, "y[t-1]"),
                                  Field("y2", 1, "y[t-2]")])
"""One biquad's state per channel; a cascade's are ``channels * sections`` of these, channel-major."""
SECTION_PARAMS = SECTION.size()
"""Per biquad: b0, b1, b2, a1, a2 (a0 normalised to 1)."""
SECTION_STATE = SECTION_MEMORY.size()
"""Per biquad and channel: x[t-1], x[t-2], y[t-1], y[t-2]."""
B0, B1, B2, A1, A2 = (SECTION.const(n) for n in ("b0", "b1", "b2", "a1", "a2"))
X1, X2, Y1, Y2 = (SECTION_MEMORY.const(n) for n in ("x1", "x2", "y1", "y2"))


def sos_to_params(sos: np.ndarray) -> np.ndarray:
    """scipy ``sos`` (rows b0 b1 b2 a0 a1 a2) -> flat ``[b0 b1 b2 a1 a2]*`` with a0 = 1."""
    sos = np.atleast_2d(np.asarray(sos, dtype=np.float64))
    if sos.shape[1] != 6:
        raise ValueError("sos must have 6 columns (b0 b1 b2 a0 a1 a2)")
    a0 = sos[:, 3:4]
    if np.any(a0 == 0):
        raise ValueError("a0 of every section must be non-zero")
    norm = sos / a0
    return np.ascontiguousarray(norm[:, [0, 1, 2, 4, 5]].ravel())


@njit(cache=True, fastmath=FASTMATH)
def sos_block(coef: np.ndarray, state: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """Cascade of biquads (direct form I) over a block.

    ``coef`` holds ``sections * 5`` values; ``state`` holds
    ``channels * sections * 4``. Direct form I keeps the feedback recursion to
    one fused multiply-add per sample, which is what lets a chain of these
    run as fast as scipy's ``sosfilt``. (Unrolling the recursion over two
    samples is faster still, but its rounding would depend on where a run is
    split into blocks, and chunked runs must equal one pass exactly.)
    """
    n = x.shape[0]
    channels = x.shape[1]
    sections = coef.shape[0] // SECTION_PARAMS
    for c in range(channels):
        for k in range(sections):
            at = SECTION_PARAMS * k
            b0 = coef[at + B0]
            b1 = coef[at + B1]
            b2 = coef[at + B2]
            a1 = coef[at + A1]
            a2 = coef[at + A2]
            base = (c * sections + k) * SECTION_STATE
            x1 = state[base + X1]
            x2 = state[base + X2]
            y1 = state[base + Y1]
            y2 = state[base + Y2]
            src = x if k == 0 else y
            for t in range(n):
                x0 = src[t, c]
                # Evaluated left to right, so that (with contraction to fused multiply-adds)
                # the recursion through y1 and y2 costs one operation per sample: this
                # order measured fastest over blocks (benchmarks/bench_engine.py).
                y0 = (b0 * x0 + b1 * x1 + b2 * x2 - a2 * y2) - a1 * y1
                y[t, c] = y0
                x2 = x1
                x1 = x0
                y2 = y1
                y1 = y0
            state[base + X1] = x1
            state[base + X2] = x2
            state[base + Y1] = y1
            state[base + Y2] = y2


@njit(cache=True)
def sos_steady_state(coef: np.ndarray, state: np.ndarray, x0: np.ndarray) -> None:
    """Set ``state`` (layout of :func:`sos_block`) to the steady state for the constant input ``x0`` per channel.

    Each section then sees its input ``u`` and outputs ``g u`` forever, with
    ``g = (b0 + b1 + b2) / (1 + a1 + a2)`` its DC gain: what scipy's
    ``sosfilt_zi(sos) * x0`` gives in its own (transposed) state layout. A
    constant input then passes without a start-up transient (a gravity step
    through a high-pass gives 0 from the first sample, not -9.8 m/s^2).
    Stable sections have no pole at z = 1, so ``1 + a1 + a2 != 0``.
    """
    channels = x0.shape[0]
    sections = coef.shape[0] // SECTION_PARAMS
    for c in range(channels):
        u = x0[c]
        for k in range(sections):
            at = SECTION_PARAMS * k
            g = (coef[at + B0] + coef[at + B1] + coef[at + B2]) / (1.0 + coef[at + A1] + coef[at + A2])
            base = (c * sections + k) * SECTION_STATE
            state[base + X1] = u
            state[base + X2] = u
            u = g * u
            state[base + Y1] = u
            state[base + Y2] = u


def lowpass_alpha(cutoff_hz: float, rate_hz: float) -> float:
    """Smoothing factor of a first-order low-pass with its pole at exp(-2 pi fc / fs)."""
    return 1.0 - math.exp(-2.0 * math.pi * cutoff_hz / rate_hz)


@njit(cache=True, fastmath=FASTMATH)
def first_order_lowpass_block(alpha: float, state: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """y[t] = y[t-1] + alpha * (x[t] - y[t-1]) per channel; ``state`` holds y[t-1]."""
    for c in range(x.shape[1]):
        prev = state[c]
        for t in range(x.shape[0]):
            prev = prev + alpha * (x[t, c] - prev)
            y[t, c] = prev
        state[c] = prev


@njit(cache=True)
def difference_block(rate: float, state: np.ndarray, started: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
    """Backward difference times ``rate``: derivative per second.

    The first tick after a reset outputs 0 (no earlier sample); ``started[0]``
    records that one has been seen.
    """
    for t in range(x.shape[0]):
        for c in range(x.shape[1]):
            if started[0] != 0:
                y[t, c] = (x[t, c] - state[c]) * rate
            else:
                y[t, c] = 0.0
            state[c] = x[t, c]
        started[0] = 1
