"""Rational resampling of whole recordings (offline, zero delay) with a Kaiser-window polyphase FIR.

The ratio rate_out / rate_in is reduced to up/down (both <= MAX_FACTOR); the
filter (:func:`flowtex.dsp.filter_design.resampling_fir`) is applied with
scipy's polyphase ``resample_poly``, which centres the linear-phase filter so
that output sample k lies at time k / rate_out, like input sample k at
k / rate_in: signals stay aligned in time. The streaming (causal, in-graph)
version lives in :mod:`flowtex.dsp.resample_stream`.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from .filter_design import resampling_fir

MAX_FACTOR = 1000
"""Largest up or down factor: the filter has ~50 * max(up, down) taps at 80 dB."""

DEFAULT_ATTEN_DB = 80.0
"""Default stopband attenuation (images and aliases), dB."""


def rational_ratio(rate_in: float, rate_out: float) -> tuple[int, int]:
    """(up, down) in lowest terms with up/down == rate_out/rate_in, both <= MAX_FACTOR.

    Raises ValueError when the rates are not positive and finite or when their
    ratio has no such fraction within 1e-9 (e.g. 1000 -> 1000.5 Hz needs 2001/2000).
    """
    for name, r in (("input", rate_in), ("output", rate_out)):
        if not (np.isfinite(r) and r > 0):
            raise ValueError(f"{name} rate must be a positive number of Hz, got {r}")
    ratio = Fraction(float(rate_out)) / Fraction(float(rate_in))
    frac = ratio.limit_denominator(MAX_FACTOR)
    if frac.numerator > MAX_FACTOR or frac.numerator == 0 or abs(float(frac) / float(ratio) - 1.0) > 1e-9:
        raise ValueError(f"cannot resample {rate_in:g} Hz -> {rate_out:g} Hz: the ratio is not p/q with p, q <= {MAX_FACTOR}")
    return frac.numerator, frac.denominator


def resampled_length(n: int, up: int, down: int) -> int:
    """round(n * up / down), halves rounded up, in exact integer arithmetic."""
    return (2 * n * up + down) // (2 * down)


def resample_signal(x: np.ndarray, rate_in: float, rate_out: float, atten_db: float = DEFAULT_ATTEN_DB,
                    passband: float = 0.8) -> np.ndarray:
    """Resample ``x`` (samples along axis 0, any trailing shape, any unit) from ``rate_in`` to ``rate_out`` Hz.

    Returns float64 of length round(n * rate_out / rate_in) along axis 0, same
    unit, zero delay. Frequencies up to ``passband`` times the lower Nyquist
    frequency pass within 20*log10(1 + 10**(-atten_db/20)) dB; aliases and
    images are ``atten_db`` dB down. The signal is extended past both ends by
    its mean (scipy ``padtype='mean'``), so a constant offset such as gravity
    does not ring at the edges. Raises ValueError on non-finite samples.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 0:
        raise ValueError("resample_signal needs samples along axis 0, got a scalar")
    up, down = rational_ratio(rate_in, rate_out)
    n = x.shape[0]
    n_out = resampled_length(n, up, down)
    if up == down:
        return x.copy()
    if n == 0:
        return np.zeros((0,) + x.shape[1:])
    if not np.all(np.isfinite(x)):
        bad = int(np.argmax(~np.all(np.isfinite(x.reshape(n, -1)), axis=1)))
        raise ValueError(f"signal has a NaN or inf value (first at sample {bad}); clean it before resampling")
    from scipy import signal

    h = resampling_fir(up, down, atten_db, passband)
    y = signal.resample_poly(x, up, down, axis=0, window=h, padtype="mean")
    return np.ascontiguousarray(y[:n_out])
