"""Error figures between a configuration's output and the reference's (``flowtex bench``).

* ``lsd``: log-spectral distance, dB (:func:`flowtex.dsp.spectral.lsd_db` over every frequency, PSDs floored at
  :data:`PSD_FLOOR`): sqrt(mean over frequency of (10 log10(P_ref / P))^2), Welch PSDs (:func:`flowtex.dsp.spectral.welch_psd`); for vibrations, whose
  perceived content is spectral and whose samples differ with every noise path;
* ``rms``: root mean square of the sample-wise difference, in the signal's unit;
* ``gfc``: 1 - GFC of the amplitude spectra (0 = same spectral shape), 003.
"""

from __future__ import annotations

import math

import numpy as np

from .spectral import gfc, lsd_db, welch_psd

PSD_FLOOR = 1e-20
"""PSD values below this ((unit)^2/Hz) are raised to it before taking logs (silent bands)."""


def signal_error(metric: str, reference: np.ndarray, signal: np.ndarray, rate_hz: float) -> float:
    """Error of ``signal`` against ``reference`` (same shape; vectors: mean over components)."""
    ref = np.asarray(reference, dtype=np.float64).reshape(reference.shape[0], -1)
    sig = np.asarray(signal, dtype=np.float64).reshape(signal.shape[0], -1)
    if metric == "rms":
        return float(np.sqrt(np.mean((ref - sig) ** 2)))
    values = []
    for c in range(ref.shape[1]):
        freqs, p_ref = welch_psd(ref[:, c], rate_hz, 256)
        _, p_sig = welch_psd(sig[:, c], rate_hz, 256)
        if metric == "lsd":  # every frequency (no band, no range), silent bands floored
            values.append(lsd_db(p_sig, p_ref, freqs, min_freq_hz=-math.inf, range_db=None, floor=PSD_FLOOR))
        elif metric == "gfc":
            values.append(1.0 - gfc(np.sqrt(p_ref), np.sqrt(p_sig)))
        else:
            raise ValueError(f"unknown metric {metric!r}")
    return float(np.mean(values))


def pareto_front(cost: np.ndarray, error: np.ndarray) -> np.ndarray:
    """Boolean mask of points no other point beats in both cost and error (ties: both kept)."""
    cost = np.asarray(cost, dtype=np.float64)
    error = np.asarray(error, dtype=np.float64)
    keep = np.ones(cost.size, dtype=bool)
    for i in range(cost.size):
        better = (cost <= cost[i]) & (error <= error[i]) & ((cost < cost[i]) | (error < error[i]))
        keep[i] = not better.any()
    return keep
