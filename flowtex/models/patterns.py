"""Patterned textures: surface features along a straight axis, each a ring-down filter (Guruswamy thesis ch. 4).

A :class:`Pattern` is what a pattern file (docs/pattern-format.md, read and written by
:mod:`flowtex.io.patternfile`) holds once read, and what ``patterned_texture`` renders
(:mod:`flowtex.dsp.patterns` plays it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Pattern:
    """Features along a straight axis: position (mm along ``axis`` from ``origin``), amplitude A_k (m/s^2) and filter b_k / a_k."""

    sample_rate_hz: float
    axis: np.ndarray
    origin: np.ndarray
    positions_mm: np.ndarray
    amplitudes: np.ndarray
    b: list[np.ndarray]
    a: list[np.ndarray]
    metadata: dict[str, Any] = field(default_factory=dict)

    def padded(self) -> tuple[np.ndarray, np.ndarray]:
        """(b, a) as (K, P + 1) arrays padded with zeros to the largest order P."""
        order = max(max(len(x) for x in self.b), max(len(x) for x in self.a)) - 1
        b = np.zeros((len(self.b), order + 1))
        a = np.zeros((len(self.a), order + 1))
        for k, (bk, ak) in enumerate(zip(self.b, self.a, strict=True)):
            b[k, :len(bk)] = bk
            a[k, :len(ak)] = ak
        return b, a
