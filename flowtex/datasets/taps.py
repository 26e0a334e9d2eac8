"""Synthetic tap libraries (decaying sinusoids), for tests, examples and the study scene."""

from __future__ import annotations

import numpy as np

from ..models.taps import TapLibrary


def synthetic_tap_library(speeds: tuple[float, ...] = (20.0, 50.0, 100.0, 200.0), sample_rate_hz: float = 1000.0,
                          duration_s: float = 0.1, freq_hz: float = 150.0, decay_s: float = 0.015,
                          gain: float = 0.25, stiffening: float = 0.2, name: str = "synthetic") -> TapLibrary:
    """Decaying sinusoids a_k(t) = gain v_k exp(-t / decay) sin(2 pi f_k t) (m/s^2), for tests and examples.

    Amplitude grows linearly with the incoming speed v_k (mm/s; ``gain`` in
    (m/s^2)/(mm/s)) as momentum does (Culbertson & Kuchenbecker 2017); the frequency rises mildly with
    speed, f_k = freq_hz (1 + stiffening v_k / max v), so that interpolated
    transients differ from scaled ones. Hard surfaces: high ``freq_hz``,
    short ``decay_s``.
    """
    speeds_arr = np.asarray(sorted(speeds), dtype=np.float64)
    n = int(round(duration_s * sample_rate_hz))
    t = np.arange(n) / sample_rate_hz
    freqs = freq_hz * (1.0 + stiffening * speeds_arr / speeds_arr[-1])
    tr = gain * speeds_arr[:, None] * np.exp(-t[None, :] / decay_s) * np.sin(2 * np.pi * freqs[:, None] * t[None, :])
    return TapLibrary(speeds_arr, tr, sample_rate_hz, name)
