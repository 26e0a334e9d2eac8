"""Band-limited interpolation of a graph's tick-rate outputs up to an audio rate, one tick at a time.

A signal computed at the tick rate ``f_t`` (1 kHz) and held or linearly
interpolated up to the audio rate ``f_a = U f_t`` puts images of its spectrum
around every multiple of ``f_t``. Here each tick's value is zero-stuffed to U
samples and filtered by a minimum-phase low-pass FIR (the Kaiser-window
resampling filter of :func:`flowtex.dsp.filter_design.resampling_fir`, passband
``passband * f_t / 2``, stopband from ``f_t / 2``, ``atten_db`` down, turned
minimum phase by scipy's homomorphic method with the full magnitude kept).
Minimum phase puts the filter's energy first: the delay at the low frequencies
where texture power lives is ~2 ms instead of the linear-phase filter's
(len - 1) / 2 samples (18 ms at 8 kHz, 60 dB), at the cost of a non-constant
group delay near the band edge (docs/live.md, "Audio output").

:func:`render_ticks` runs the polyphase up-sampling of
:mod:`flowtex.dsp.resample_stream` one tick at a time (state carried between calls, so cutting a
run into blocks changes no sample), then clips each channel to ``[lo, hi]``
(graph units), divides by the channel's scale (graph units per full-scale
sample) and stores float32 samples. A NaN output enters the filter as 0.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .filter_design import resampling_fir
from .resample_stream import stream_params, stream_state_sizes

DEFAULT_ATTEN_DB = 60.0
"""Stopband attenuation of the interpolation filter, dB (images of the tick-rate spectrum)."""

DEFAULT_PASSBAND = 0.8
"""Passband edge as a fraction of half the tick rate (400 Hz at 1 kHz)."""


def interpolation_filter(up: int, atten_db: float = DEFAULT_ATTEN_DB, passband: float = DEFAULT_PASSBAND) -> np.ndarray:
    """Minimum-phase low-pass FIR at the audio rate for interpolation by the integer ``up`` (DC gain 1)."""
    from scipy import signal

    if int(up) != up or up < 1:
        raise ValueError(f"the interpolation factor must be a positive integer, got {up}")
    if up == 1:
        return np.ones(1)
    h = resampling_fir(int(up), 1, atten_db, passband)
    hm = signal.minimum_phase(h, method="homomorphic", half=False)
    return hm / hm.sum()


def low_frequency_delay(h: np.ndarray, rate_hz: float, freq_hz: float = 50.0) -> float:
    """Group delay of ``h`` (running at ``rate_hz``) at ``freq_hz``, in seconds."""
    from scipy import signal

    _, gd = signal.group_delay((h, [1.0]), w=[freq_hz], fs=rate_hz)
    return float(gd[0]) / rate_hz


class Interpolator:
    """State of one interpolation run: ``up`` audio samples per tick for ``width`` channels.

    ``lo``, ``hi``: clip per channel in graph units; ``scale``: graph units per full-scale sample.
    """

    def __init__(self, up: int, width: int, scale: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 atten_db: float = DEFAULT_ATTEN_DB, passband: float = DEFAULT_PASSBAND) -> None:
        self.up = int(up)
        self.width = int(width)
        self.h = interpolation_filter(self.up, atten_db, passband)
        self.params = stream_params(self.h, self.up, 1) if self.up > 1 else np.array([1.0, 1.0, 1.0, 1.0, 1.0])
        n_float, n_int = stream_state_sizes(self.h, self.up, 1, self.width) if self.up > 1 else (3 * self.width, 2)
        self.state = np.zeros(n_float)
        self.istate = np.zeros(n_int, dtype=np.int64)
        self.inv_scale = 1.0 / np.asarray(scale, dtype=np.float64).reshape(self.width)
        self.lo = np.asarray(lo, dtype=np.float64).reshape(self.width)
        self.hi = np.asarray(hi, dtype=np.float64).reshape(self.width)
        self.scratch = np.zeros((self.up, self.width))

    def reset(self) -> None:
        """Back to silence (the state of a new run)."""
        self.state[:] = 0.0
        self.istate[:] = 0

    def render(self, x: np.ndarray, out: np.ndarray) -> None:
        """``x`` (n, width) tick values in graph units -> ``out`` (n * up, width) float32 samples."""
        render_ticks(self.params, self.state, self.istate, x, self.inv_scale, self.lo, self.hi, self.scratch, out)


@njit(cache=True, nogil=True)
def render_ticks(p, s, si, x, inv_scale, lo, hi, scratch, out):
    """Interpolate ``x`` (n, w) by ``up = scratch.shape[0]``, clip, scale, into ``out`` (n * up, w) float32.

    The up-sampling path of :func:`flowtex.dsp.resample_stream.resample_block` (same parameter and state
    layout, same products summed in the same order, so the same samples), written for one tick in, ``up``
    samples out: calling ``resample_block`` once per tick cost ~20x more per sample (measured in
    benchmarks/bench_audio.py's setting)."""
    up = scratch.shape[0]
    w = x.shape[1]
    hist = int(p[3]) if up > 1 else 1
    coef = p[4:]
    span = 2 * hist
    pos = si[1]
    for k in range(x.shape[0]):
        pos = pos + 1 if pos + 1 < hist else 0
        for q in range(w):
            v = x[k, q]
            v = v if v == v else 0.0  # a NaN output enters the filter as 0 (it would poison its history)
            s[q * span + pos] = v
            s[q * span + pos + hist] = v
        for r in range(up):
            g = r * hist
            for q in range(w):
                base = q * span + pos + 1
                if up > 1:
                    acc = 0.0
                    for j in range(hist):
                        acc += coef[g + j] * s[base + j]
                else:
                    acc = s[base + hist - 1]
                if not acc == acc:
                    acc = 0.0
                elif acc < lo[q]:
                    acc = lo[q]
                elif acc > hi[q]:
                    acc = hi[q]
                out[k * up + r, q] = np.float32(acc * inv_scale[q])
    si[1] = pos
