"""Tap libraries: recorded tapping transients labelled by incoming speed (synthetic ones: :mod:`flowtex.datasets.taps`).

A :class:`TapLibrary` holds K transients (accelerations in m/s^2, all L
samples long at ``sample_rate_hz``) recorded at K distinct incoming speeds
(mm/s), sorted by speed. Playback rules are in :mod:`flowtex.dsp.taps` and
Culbertson & Kuchenbecker 2017, "Importance of matching physical friction, hardness, and texture
in creating realistic haptic virtual surfaces", section 3.3.2; the file format is in docs/tap-library.md and
:mod:`flowtex.io.taplib`.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..pyvalues import positive_rate


@dataclass(frozen=True)
class TapLibrary:
    """Transients ``(K, L)`` in m/s^2 at increasing ``speeds`` ``(K,)`` in mm/s, sampled at ``sample_rate_hz``."""

    speeds: np.ndarray
    transients: np.ndarray
    sample_rate_hz: float
    name: str = ""

    def __post_init__(self) -> None:
        speeds = np.asarray(self.speeds, dtype=np.float64)
        tr = np.asarray(self.transients, dtype=np.float64)
        if speeds.ndim != 1 or speeds.size == 0:
            raise ValueError("a tap library needs at least one speed")
        if tr.ndim != 2 or tr.shape[0] != speeds.size or tr.shape[1] == 0:
            raise ValueError(f"transients must have shape ({speeds.size}, L) with L >= 1, got {tr.shape}")
        if not (np.all(np.isfinite(speeds)) and np.all(speeds > 0)):
            raise ValueError("speeds must be finite and > 0 mm/s")
        if np.any(np.diff(speeds) <= 0):
            raise ValueError("speeds must be strictly increasing (sort the taps; merge or drop taps with equal speeds)")
        if not np.all(np.isfinite(tr)):
            raise ValueError("transients must be finite")
        if not (np.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise ValueError(f"sample rate must be > 0 Hz, got {self.sample_rate_hz!r}")
        object.__setattr__(self, "speeds", speeds)
        object.__setattr__(self, "transients", tr)
        object.__setattr__(self, "sample_rate_hz", float(self.sample_rate_hz))

    @property
    def length(self) -> int:
        """Samples per transient."""
        return int(self.transients.shape[1])

    @property
    def duration_s(self) -> float:
        """Length of a transient in seconds."""
        return self.length / self.sample_rate_hz

    def transient(self, speed_mm_s: float) -> np.ndarray:
        """The acceleration transient (m/s^2) played for an incoming speed, following Culbertson & Kuchenbecker 2017."""
        v = float(speed_mm_s)
        s = self.speeds
        if not v > 0.0:
            return np.zeros(self.length)
        if v <= s[0]:
            return self.transients[0] * (v / s[0])
        if v >= s[-1]:
            return self.transients[-1].copy()
        j = int(np.searchsorted(s, v, side="left")) - 1
        u = (v - s[j]) / (s[j + 1] - s[j])
        return (1.0 - u) * self.transients[j] + u * self.transients[j + 1]


def resample_tap_library(lib: TapLibrary, sample_rate_hz: float) -> TapLibrary:
    """The library at another sample rate (polyphase resampling with scipy, same duration)."""
    from scipy.signal import resample_poly

    sample_rate_hz = positive_rate("resample_tap_library: sample_rate_hz", sample_rate_hz)
    if sample_rate_hz == lib.sample_rate_hz:
        return lib
    ratio = Fraction(sample_rate_hz / lib.sample_rate_hz).limit_denominator(1000)
    tr = resample_poly(lib.transients, ratio.numerator, ratio.denominator, axis=1)
    n = max(1, int(round(lib.duration_s * sample_rate_hz)))
    out = np.zeros((tr.shape[0], n))
    m = min(n, tr.shape[1])
    out[:, :m] = tr[:, :m]
    return TapLibrary(lib.speeds, out, sample_rate_hz, lib.name)


def spectral_centroid(lib: TapLibrary, speeds: tuple[float, ...] = (50.0, 60.0, 70.0, 80.0, 90.0, 100.0)) -> float:
    """Mean tap spectral centroid (Hz) over the transients played at ``speeds`` (Culbertson & Kuchenbecker 2017, eq. 4; hardness predictor).

    SC = sum X(f)^2 f / sum X(f)^2 with X the DFT magnitude of one transient.
    Silent transients are skipped; returns 0 when all are silent.
    """
    from ..dsp.spectral import signal_centroid

    values = [signal_centroid(lib.transient(v), lib.sample_rate_hz) for v in speeds]
    values = [c for c in values if not np.isnan(c)]  # silent transients
    return float(np.mean(values)) if values else 0.0
