"""Spectral comparison helpers: Welch PSD and the Goodness-of-Fit Criterion (GFC).

scipy.signal is imported inside the functions: importing it costs ~0.6 s,
which graph loading should not pay.
"""

from __future__ import annotations

import numpy as np


def gfc(a: np.ndarray, b: np.ndarray) -> float:
    """Goodness-of-Fit Criterion |sum A B| / (sqrt(sum A^2) sqrt(sum B^2)) of two spectra.

    Source: Culbertson et al. 2012, "Refined methods for creating realistic haptic virtual textures from tool-mediated contact acceleration data".

    ``a`` and ``b`` are sampled at the same frequencies; magnitudes are
    taken (``abs``) first. Culbertson et al. 2012 apply it to amplitude spectra (|DFT|), so
    pass ``sqrt(psd)`` when comparing power spectral densities. 1 means the
    same shape up to a scale factor; their perceptual threshold was 0.90.
    Returns 0.0 if either spectrum is all zero.
    """
    a = np.abs(np.asarray(a, dtype=np.float64)).ravel()
    b = np.abs(np.asarray(b, dtype=np.float64)).ravel()
    if a.shape != b.shape:
        raise ValueError(f"spectra must have the same length, got {a.size} and {b.size}")
    den = np.sqrt(np.sum(a * a)) * np.sqrt(np.sum(b * b))
    if den == 0.0:
        return 0.0
    return float(abs(np.sum(a * b)) / den)


def welch_psd(x: np.ndarray, rate_hz: float, nperseg: int = 1024) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch PSD of a real signal (Hann window, 50 % overlap, mean removed).

    Returns (frequencies in Hz, PSD in units(x)^2 / Hz), the scaling of
    :func:`flowtex.dsp.arma.arma_psd` with ``onesided=True``.
    """
    import scipy.signal

    x = np.asarray(x, dtype=np.float64).ravel()
    nperseg = int(min(nperseg, x.size))
    freqs, psd = scipy.signal.welch(x, fs=rate_hz, window="hann", nperseg=nperseg, detrend="constant",
                                    scaling="density", return_onesided=True)
    return freqs, psd
