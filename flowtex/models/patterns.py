"""Patterned textures: surface features along a straight axis, each a ring-down filter (Guruswamy thesis ch. 4).

A :class:`Pattern` is what a pattern file (docs/pattern-format.md, read and written by
:mod:`flowtex.io.patternfile`) holds once read, and what ``patterned_texture`` renders
(:mod:`flowtex.dsp.patterns` plays it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

MAX_ORDER = 32
"""Largest order of a feature's filter (b and a hold at most MAX_ORDER + 1 coefficients)."""


def filter_problem(b: np.ndarray, a: np.ndarray) -> str | None:
    """Why a feature's ring-down filter ``b / a`` cannot be played (count, finiteness, ``a[0]``, stability), or None."""
    if b.ndim != 1 or a.ndim != 1 or not 1 <= b.size <= MAX_ORDER + 1 or not 1 <= a.size <= MAX_ORDER + 1:
        return f"b and a need 1 to {MAX_ORDER + 1} coefficients"
    if not (np.isfinite(b).all() and np.isfinite(a).all()):
        return "b and a must be finite numbers"
    if a[0] != 1.0:
        return f"a[0] must be 1 (normalised denominator), got {a[0]!r}"
    if a.size > 1 and np.max(np.abs(np.roots(a))) >= 1.0:
        return f"the filter is unstable (pole radius {np.max(np.abs(np.roots(a))):.6g} >= 1); refit the pattern"
    return None


@dataclass
class Pattern:
    """Features along a straight axis: position (mm along ``axis`` from ``origin``), amplitude A_k (m/s^2) and filter b_k / a_k.

    Checked when made (ValueError), so that a pattern built in memory cannot make ``patterned_texture`` burst or
    output NaN: a unit ``axis``, a finite ``origin``, K >= 1 finite positions and amplitudes, K playable filters.
    """

    sample_rate_hz: float
    axis: np.ndarray
    origin: np.ndarray
    positions_mm: np.ndarray
    amplitudes: np.ndarray
    b: list[np.ndarray]
    a: list[np.ndarray]
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (isinstance(self.sample_rate_hz, (int, float)) and math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise ValueError(f"sample rate must be a finite number > 0 Hz, got {self.sample_rate_hz!r}")
        axis = np.asarray(self.axis, dtype=np.float64)
        origin = np.asarray(self.origin, dtype=np.float64)
        if axis.shape != (3,) or not np.isfinite(axis).all() or not np.linalg.norm(axis) > 0:
            raise ValueError(f"axis must be a non-zero finite 3-vector, got {self.axis!r}")
        if origin.shape != (3,) or not np.isfinite(origin).all():
            raise ValueError(f"origin must be a finite 3-vector (mm), got {self.origin!r}")
        xs = np.asarray(self.positions_mm, dtype=np.float64)
        amps = np.asarray(self.amplitudes, dtype=np.float64)
        if xs.ndim != 1 or xs.size == 0 or amps.shape != xs.shape or len(self.b) != xs.size or len(self.a) != xs.size:
            raise ValueError(f"positions_mm, amplitudes, b and a need one entry per feature (K >= 1), got "
                             f"{xs.shape}, {amps.shape}, {len(self.b)} and {len(self.a)}")
        if not (np.isfinite(xs).all() and np.isfinite(amps).all()):
            raise ValueError("positions_mm and amplitudes must be finite numbers")
        b = [np.asarray(x, dtype=np.float64) for x in self.b]
        a = [np.asarray(x, dtype=np.float64) for x in self.a]
        for k, (bk, ak) in enumerate(zip(b, a, strict=True)):
            problem = filter_problem(bk, ak)
            if problem:
                raise ValueError(f"feature {k}: {problem}")
        self.axis, self.origin, self.positions_mm, self.amplitudes, self.b, self.a = axis / np.linalg.norm(axis), origin, xs, amps, b, a

    def padded(self) -> tuple[np.ndarray, np.ndarray]:
        """(b, a) as (K, P + 1) arrays padded with zeros to the largest order P."""
        order = max(max(len(x) for x in self.b), max(len(x) for x in self.a)) - 1
        b = np.zeros((len(self.b), order + 1))
        a = np.zeros((len(self.a), order + 1))
        for k, (bk, ak) in enumerate(zip(self.b, self.a, strict=True)):
            b[k, :len(bk)] = bk
            a[k, :len(ak)] = ak
        return b, a
