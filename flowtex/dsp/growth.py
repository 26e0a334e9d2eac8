"""Whether a signal grows exponentially: an unstable recursion seen before it reaches inf.

``flowtex plugin check`` runs a node's kernel on bounded noise for a few hundred ticks; a recursion whose pole left
the unit circle grows by the same factor every window, while everything a stable node does -- a stable filter starting
up, an integrator of the noise, a counter or a ramp (polynomial growth) -- grows ever more slowly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["diverging"]

GROWTH_WINDOWS = 3
"""Windows of :data:`GROWTH_WINDOW` ticks at the end of the signal in which :func:`diverging` looks for growth."""
GROWTH_WINDOW = 100
"""Ticks per window."""
GROWTH_FACTOR = 10.0
"""Growth of the largest magnitude from one window to the next that counts as divergence (a pole of radius r grows
r**100 per window: 10x for r >= 1.024)."""
STEADY_GROWTH = 0.8
"""The later window's growth must be at least this fraction of the earlier's: exponential growth keeps its rate, while
polynomial growth t**k slows from one window to the next (at the end of a 600-tick run: (499/399)**k, then
(599/499)**k, 0.96**k as fast, under this for every k whose growth reaches :data:`GROWTH_FACTOR`), as does the start-up of a stable
high-order filter approaching its level."""


def diverging(y: np.ndarray) -> str | None:
    """How output ``y`` (ticks x width, finite) grows, when its largest magnitude grows exponentially over the last
    :data:`GROWTH_WINDOWS` windows (by :data:`GROWTH_FACTOR` or more from each to the next, at a steady rate: an
    unstable recursion that has not reached inf yet), else None."""
    ends = range(y.shape[0] - GROWTH_WINDOWS * GROWTH_WINDOW, y.shape[0] + 1, GROWTH_WINDOW)
    if ends[0] < 0:
        return None
    peaks = [float(np.max(np.abs(y[a:b]), initial=0.0)) for a, b in zip(ends[:-1], ends[1:], strict=False)]
    if not peaks[0] > 0.0:
        return None
    growth = [later / earlier for earlier, later in zip(peaks, peaks[1:], strict=False)]
    if all(g >= GROWTH_FACTOR for g in growth) and all(b >= STEADY_GROWTH * a for a, b in zip(growth, growth[1:], strict=False)):
        return ", ".join(f"|max| {v:.3g} at ticks {a}-{a + GROWTH_WINDOW - 1}" for v, a in zip(peaks, ends, strict=False))
    return None
    peaks = [float(np.max(np.abs(y[a:b]), initial=0.0)) for a, b in zip(ends[:-1], ends[1:], strict=False)]
    if peaks[0] > 0.0 and all(later >= GROWTH_FACTOR * earlier for earlier, later in zip(peaks, peaks[1:], strict=False)):
        return ", ".join(f"|max| {v:.3g} at ticks {a}-{a + GROWTH_WINDOW - 1}" for v, a in zip(peaks, ends, strict=False))
    return None
