"""Anti-imaging lowpass filters for upsampled texture models, as (poles, zeros) at the new rate.

An upsampled model (flowtex.dsp.arma_resample) must keep its spectrum below the
old Nyquist and put (nearly) nothing above it. Two fixed lowpasses, the same for
every model of a set (so that a set's LSFs stay interpolable and its level
convention one constant), are cascaded with the fitted roots:

* :func:`fir_lowpass` removes the images of a model fitted at a lower rate and
  stretched by z -> z^m (upsampling by more than 2x);
* :func:`elliptic_lowpass` gives a model fitted at the new rate itself (2x and
  below) a steep edge at the old Nyquist, for models whose spectrum is still
  high there (flat, rough surfaces): their own roots cannot both follow the
  band and fall 30 dB within a few percent of the band.

Both are monic and minimum phase with every zero pulled to radius
:data:`ZERO_RADIUS` (valid, resolvable LSFs); their passband ripple is
compensated inside the fit.
"""

from __future__ import annotations

import math

import numpy as np

from .poly import power_spectrum

ZERO_RADIUS = 0.9999
"""The lowpasses' zeros (designed on the unit circle) are pulled to this radius: valid, resolvable LSFs."""

IMAGE_ATTENUATION_DB = 40.0
"""Least stopband attenuation of the FIR lowpass of stretched models (the band's images then carry <= ~0.01 % of
its power; measured above the old Nyquist, all of it: <= 0.06 %)."""

EDGE_RIPPLE_DB, EDGE_ATTENUATION_DB = 0.1, 30.0
"""The elliptic lowpass: passband ripple and least stopband attenuation (dB). 30 dB keeps a band that is flat up to
the old Nyquist well under the 2 % of power allowed above it (0.1 % for a flat band at 2x)."""


def _pulled(zeros: np.ndarray) -> np.ndarray:
    """Zeros reflected into the unit circle (same magnitude response up to a gain) and pulled to <= ZERO_RADIUS."""
    z = np.asarray(zeros, dtype=np.complex128)
    z = np.where(np.abs(z) > 1.0, 1.0 / np.conj(z), z)
    return z * np.minimum(1.0, ZERO_RADIUS / np.maximum(np.abs(z), 1e-300))


def fir_lowpass(rate_from: float, rate_to: float, m: int, band_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """(poles, zeros) at ``rate_to`` of the lowpass that removes the images of a model stretched by z -> z^m.

    An all-zero (FIR) equiripple lowpass (scipy.signal.remez, stopband weighted
    30x), made minimum phase: passband up to the old Nyquist, stopband from its
    first image (rate_to / m - rate_from / 2), the fewest taps (odd, >= 9) that
    reach :data:`IMAGE_ATTENUATION_DB`; when the images start at the old Nyquist
    itself, the passband ends at ``band_edge`` x the old Nyquist. Why no poles:
    an elliptic lowpass puts high-Q poles at the band edge, among the stretched
    model's own crowded poles, and its coefficients then miss the spectrum
    (measured: 0.80 dB for one of 30 HaTT-like models at 4x, 0.08 dB with this FIR).
    """
    import scipy.signal

    wp = rate_from / rate_to  # old Nyquist over new Nyquist
    ws = 2.0 / m - wp  # first image of the old Nyquist
    if ws < 1.2 * wp:  # stretched by (nearly) the whole ratio: images start at the old Nyquist; pass only the fitted band
        wp, ws = band_edge * wp, 2.0 / m - band_edge * wp
    f = np.linspace(0.0, 1.0, 4097)
    for taps in range(9, 202, 2):
        h = scipy.signal.remez(taps, [0.0, 0.5 * wp, 0.5 * ws, 0.5], [1.0, 0.0], weight=[1.0, 30.0])
        mag = np.sqrt(power_spectrum(np.array([1.0]), h, math.pi * f))
        if 20.0 * math.log10(np.max(mag[f <= wp]) / np.max(mag[f >= ws])) >= IMAGE_ATTENUATION_DB:
            break
    return np.zeros(0, dtype=np.complex128), _pulled(np.roots(h))


def elliptic_lowpass(rate_from: float, rate_to: float, band_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """(poles, zeros) at ``rate_to`` > ``rate_from`` of an elliptic lowpass from ``band_edge`` x the old Nyquist to it.

    Passband ripple :data:`EDGE_RIPPLE_DB`, stopband from the old Nyquist
    (rate_from / 2) at :data:`EDGE_ATTENUATION_DB`, the least order that does
    it (scipy.signal.ellipord: 6 from 1 to 2 kHz with ``band_edge`` 0.92).
    At 2x its poles reach radius ~0.96, far from the crowding that rules it out
    for stretched models (:func:`fir_lowpass`).
    """
    import scipy.signal

    nyq = 0.5 * rate_to
    wp, ws = band_edge * 0.5 * rate_from / nyq, 0.5 * rate_from / nyq
    n, wn = scipy.signal.ellipord(wp, ws, EDGE_RIPPLE_DB, EDGE_ATTENUATION_DB)
    zeros, poles, _ = scipy.signal.ellip(n, EDGE_RIPPLE_DB, EDGE_ATTENUATION_DB, wn, output="zpk")
    return np.asarray(poles, dtype=np.complex128), _pulled(zeros)
