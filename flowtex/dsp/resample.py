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


PASSBAND = 0.8
"""Default passband of :func:`resample_signal`: frequencies up to this times the lower Nyquist pass unchanged."""


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
        raise ValueError(f"cannot resample {rate_in:.15g} Hz -> {rate_out:.15g} Hz: the ratio is not p/q with p, q <= {MAX_FACTOR}")
    return frac.numerator, frac.denominator


def resampled_length(n: int, up: int, down: int) -> int:
    """round(n * up / down), halves rounded up, in exact integer arithmetic."""
    return (2 * n * up + down) // (2 * down)


def hold_signal(x: np.ndarray, rate_in: float, rate_out: float) -> np.ndarray:
    """``x`` (samples along axis 0) at ``rate_out`` Hz by taking, at each output time, the input sample nearest to it.

    For signals that are states, not waveforms (a contact flag, a surface index): they keep their values, and each
    change moves by at most half an output period, where a filter would ring around the step and leave values the
    signal never had. Length round(n * rate_out / rate_in), as :func:`resample_signal`, so the two align sample for
    sample; output time k / rate_out takes input sample round(k * rate_in / rate_out) (halves up, clipped to the last).
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 0:
        raise ValueError("hold_signal needs samples along axis 0, got a scalar")
    up, down = rational_ratio(rate_in, rate_out)
    n_out = resampled_length(x.shape[0], up, down)
    if x.shape[0] == 0:
        return np.zeros((0,) + x.shape[1:])
    nearest = (2 * np.arange(n_out, dtype=np.int64) * down + up) // (2 * up)
    return np.ascontiguousarray(x[np.minimum(nearest, x.shape[0] - 1)])


def resample_signal(x: np.ndarray, rate_in: float, rate_out: float, atten_db: float = DEFAULT_ATTEN_DB,
                    passband: float = PASSBAND) -> np.ndarray:
    """Resample ``x`` (samples along axis 0, any trailing shape, any unit) from ``rate_in`` to ``rate_out`` Hz.

    Returns float64 of length round(n * rate_out / rate_in) along axis 0, same
    unit, zero delay. Frequencies up to ``passband`` times the lower Nyquist
    frequency pass within 20*log10(1 + 10**(-atten_db/20)) dB; aliases and
    images are ``atten_db`` dB down. Edges (:func:`edge_trend`): the straight
    line through the first and last samples is taken out, the rest is
    resampled with an odd extension about each end sample (scipy
    ``padtype='antireflect'``), and the line is added back at the output
    times exactly. A constant (gravity) or a linear trend (a position ramp)
    therefore comes out exact to round-off at both ends and in between, and
    the speed derived from a resampled ramp is exact too. Raises ValueError
    on non-finite samples.
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
    start, slope = edge_trend(x)
    ramp = slope * np.arange(n).reshape((n,) + (1,) * (x.ndim - 1))
    if n > 1:
        y = signal.resample_poly(x - start - ramp, up, down, axis=0, window=h, padtype="antireflect")[:n_out]
    else:  # one sample: the line is the constant (and scipy's antireflect extension of one sample divides by zero)
        y = np.zeros((n_out,) + x.shape[1:])
    out_times = (np.arange(n_out) * (down / up)).reshape((n_out,) + (1,) * (x.ndim - 1))  # in input samples
    return np.ascontiguousarray(y + start + slope * out_times)


def edge_trend(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(first sample, slope per input sample) of the line through the first and last samples of ``x`` (along axis 0).

    Taking this line out before filtering leaves a signal that is 0 at both
    ends, so its odd extension is continuous in value and slope and a linear
    trend never meets an edge. The per-phase DC gain of a polyphase filter is
    1 only to within its stopband (1e-4 at 80 dB), which on a 4 m ramp is
    0.4 mm alternating from sample to sample (hundreds of mm/s of derived
    speed at 2 kHz); the line, added back analytically, carries no such error.
    """
    n = x.shape[0]
    start = x[0]
    slope = (x[-1] - x[0]) / (n - 1) if n > 1 else np.zeros_like(start)
    return start, slope
