"""Fit quality against data or truth: model sets evaluated at (speed, force) points, LSD between models.

Every spectral figure uses the one-sided PSD in physical units,
S(f) = 2 g^2 sigma^2 |C/A(e^{j 2 pi f / fs})|^2 / fs (flowtex.dsp.arma.arma_psd),
and the LSD of flowtex.dsp.spectral.lsd_db (above 15 Hz, 40 dB range).
"""

from __future__ import annotations

import numpy as np

from ..dsp.arma import arma_psd, arma_psd_rows
from ..dsp.interp import initial_state, texture_lookup_block
from ..dsp.spectral import lsd_db
from ..models.rendering import texture_table
from ..models.texture import TextureModelSet


def models_at(ms: TextureModelSet, speeds: np.ndarray, forces: np.ndarray, outside: str | None = None,
              interpolation: str | None = None) -> list[tuple[np.ndarray, np.ndarray, float, float]]:
    """(ar, ma, gain, variance) that ``texture_lookup`` renders at each (speed mm/s, force N): the same kernel and rule.

    ``outside`` / ``interpolation``: as the node's parameters (None: the set's own rule, flowtex.models.rendering).
    """
    ar, ma, gain, var = model_rows_at(ms, speeds, forces, outside, interpolation)
    return [(ar[k].copy(), ma[k].copy(), float(gain[k]), float(var[k])) for k in range(gain.shape[0])]


def model_rows_at(ms: TextureModelSet, speeds: np.ndarray, forces: np.ndarray, outside: str | None = None,
                  interpolation: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`models_at` as arrays: ar (n, p + 1), ma (n, q + 1), gain (n,), variance (n,), row k for point k."""
    speeds = np.asarray(speeds, float).reshape(-1, 1)
    forces = np.asarray(forces, float).reshape(-1, 1)
    tab = texture_table(ms, interpolation, outside)
    n = speeds.shape[0]
    ar = np.empty((n, ms.ar_order + 1))
    ma = np.empty((n, ms.ma_order + 1))
    gain = np.empty((n, 1))
    var = np.empty((n, 1))
    s0, si0 = initial_state(ms.ar_order, ms.ma_order)
    for k in range(n):  # a fresh state per point: no smoothing or holding across queries
        s, si = s0.copy(), si0.copy()
        texture_lookup_block(tab, s, si, speeds[k:k + 1], forces[k:k + 1], ar[k:k + 1], ma[k:k + 1], gain[k:k + 1], var[k:k + 1])
    return ar, ma, gain[:, 0], var[:, 0]


def psds_at(ms: TextureModelSet, speeds: np.ndarray, forces: np.ndarray, freqs_hz: np.ndarray) -> np.ndarray:
    """PSD (arma_psd, at the set's own rate) of the model :func:`models_at` gives at each point: one row per point."""
    ar, ma, gain, var = model_rows_at(ms, speeds, forces)
    return arma_psd_rows(ar, ma, gain, var, freqs_hz, ms.sample_rate)


def set_lsd_db(fitted: TextureModelSet, truth: TextureModelSet, speeds: np.ndarray, forces: np.ndarray,
               nfreq: int = 512) -> np.ndarray:
    """LSD (dB) between two model sets at each (speed, force) point, both interpolated as texture_lookup does.

    Each set's PSD is taken at its own sample rate, over their common band (up to the lower Nyquist).
    """
    nyquist = 0.5 * min(truth.sample_rate, fitted.sample_rate)
    freqs = np.linspace(0.0, nyquist, nfreq + 1)[1:-1]
    fit_psd, true_psd = psds_at(fitted, speeds, forces, freqs), psds_at(truth, speeds, forces, freqs)
    return np.array([lsd_db(a, b, freqs) for a, b in zip(fit_psd, true_psd, strict=True)])


def model_lsd_db(ar: np.ndarray, ma: np.ndarray, gain: float, variance: float, truth: tuple, rate: float, nfreq: int = 512) -> float:
    """LSD (dB) of one model (ar, ma, gain, variance) against ``truth`` = (ar, ma, gain, variance) at ``rate`` Hz."""
    freqs = np.linspace(0.0, rate / 2, nfreq + 1)[1:-1]
    return lsd_db(arma_psd(ar, ma, gain, variance, freqs, rate), arma_psd(*truth, freqs, rate), freqs)


def common_band(original: TextureModelSet, other: TextureModelSet, points: int) -> np.ndarray:
    """``points`` frequencies (Hz) where two sets' spectra are compared: 15 Hz to 0.9 x the lower Nyquist."""
    return np.linspace(15.0, 0.45 * min(original.sample_rate, other.sample_rate), points)


def path_lsd_db(original: TextureModelSet, other: TextureModelSet, speeds: np.ndarray, forces: np.ndarray,
                nfreq: int = 1500) -> float:
    """LSD (dB, 15 Hz to 0.9 x the lower Nyquist) between two sets' expected spectra along a (speed, force) path.

    At each point the model texture_lookup builds (:func:`models_at`), its PSD at its set's rate; the PSDs
    averaged over the path are what a long render along it shows, without the noise of a render. 0 when both are
    silent all along it.
    """
    f = common_band(original, other, nfreq)
    got, want = np.mean(psds_at(other, speeds, forces, f), axis=0), np.mean(psds_at(original, speeds, forces, f), axis=0)
    if not np.any(got) and not np.any(want):  # both silent along the path (a silent set, or one saturating in its silent
        return 0.0  # corners): nothing differs, where the logs of two zeros gave an infinite distance
    return lsd_db(got, want, f)


def lissajous_path(ms: TextureModelSet, points: int = 300, cycles: tuple[float, float] = (7.3, 11.1),
                   phase: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(speeds mm/s, forces N): a Lissajous figure over 5 %..95 % of the set's speed and force range, ``points`` long.

    ``cycles``: the speed's and the force's number of periods along it; ``phase``: the force's phase (radians).
    """
    t = np.linspace(0.0, 1.0, points)
    return (ms.max_speed * (0.5 + 0.45 * np.sin(2 * np.pi * cycles[0] * t)),
            ms.max_force * (0.5 + 0.45 * np.sin(2 * np.pi * cycles[1] * t + phase)))
