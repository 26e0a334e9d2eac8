"""Filter design at build time, with scipy.signal (never hand-written)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def butterworth_sos(kind: str, order: int, cutoff_hz: Sequence[float], rate_hz: float) -> np.ndarray:
    """Digital Butterworth as second-order sections (scipy ``butter``, bilinear transform).

    ``kind`` is lowpass/highpass (one cutoff) or bandpass/bandstop (two).
    Raises ``ValueError`` with a user-readable message on bad cutoffs.
    """
    nyquist = rate_hz / 2.0
    cut = [float(c) for c in cutoff_hz]
    band = kind in ("bandpass", "bandstop")
    if band and len(cut) != 2:
        raise ValueError(f"{kind} needs cutoff_hz: [low, high], got {len(cut)} value(s)")
    if not band and len(cut) != 1:
        raise ValueError(f"{kind} needs one cutoff_hz, got {len(cut)} values")
    for c in cut:
        if not 0.0 < c < nyquist:
            raise ValueError(f"cutoff {c:g} Hz must lie between 0 and the Nyquist frequency {nyquist:g} Hz")
    if band and not cut[0] < cut[1]:
        raise ValueError(f"band edges must increase, got [{cut[0]:g}, {cut[1]:g}]")
    from scipy import signal  # imported here: scipy.signal takes ~0.6 s to import

    wn = cut if band else cut[0]
    return signal.butter(order, wn, btype=kind, fs=rate_hz, output="sos")
