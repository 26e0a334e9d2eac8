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
sample) and stores float32 samples. A NaN or inf output enters the filter as 0 (an inf would
fill the filter's history and play at the clip for a filter length) and is counted per
channel (:attr:`Interpolator.nonfinite`).
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


def interpolation_filter(up: int, atten_db: float = DEFAULT_ATTEN_DB, passband: float = DEFAULT_PASSBAND,
                         down: int = 1) -> np.ndarray:
    """Minimum-phase low-pass FIR at ``up`` times the tick rate for interpolation by ``up / down`` (DC gain 1)."""
    from scipy import signal

    if int(up) != up or up < 1 or int(down) != down or down < 1:
        raise ValueError(f"the interpolation ratio must be positive integers up/down, got {up}/{down}")
    if up == 1:
        return np.ones(1)
    h = resampling_fir(int(up), int(down), atten_db, passband)
    hm = signal.minimum_phase(h, method="homomorphic", half=False)
    return hm / hm.sum()


def frames_before(k: int, up: int, down: int = 1) -> int:
    """Audio frames of the ticks before tick ``k`` at the ratio up/down: ceil(k * up / down) (frame n plays at tick n * down // up)."""
    return -(-int(k) * int(up) // int(down))


def low_frequency_delay(h: np.ndarray, rate_hz: float, freq_hz: float = 50.0) -> float:
    """Group delay of ``h`` (running at ``rate_hz``) at ``freq_hz``, in seconds."""
    from scipy import signal

    _, gd = signal.group_delay((h, [1.0]), w=[freq_hz], fs=rate_hz)
    return float(gd[0]) / rate_hz


class Interpolator:
    """State of one interpolation run: ``up / down`` audio samples per tick (a whole number when ``down`` is 1;
    e.g. 441/10 from 1 kHz to 44.1 kHz) for ``width`` channels.

    ``lo``, ``hi``: clip per channel in graph units; ``scale``: graph units per full-scale sample.
    Audio frame ``n`` is the up-sampled (rate ``up`` x tick rate) sample ``n * down``: tick ``n * down // up``, phase
    ``n * down % up``.
    """

    def __init__(self, up: int, width: int, scale: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 atten_db: float = DEFAULT_ATTEN_DB, passband: float = DEFAULT_PASSBAND, down: int = 1) -> None:
        self.up = int(up)
        self.down = int(down)
        self.width = int(width)
        self.h = interpolation_filter(self.up, atten_db, passband, self.down)
        self.params = stream_params(self.h, self.up, 1) if self.up > 1 else np.array([1.0, 1.0, 1.0, 1.0, 1.0])
        n_float = stream_state_sizes(self.h, self.up, 1, self.width)[0] if self.up > 1 else 3 * self.width
        self.state = np.zeros(n_float)
        self.istate = np.zeros(4 + self.width, dtype=np.int64)
        """next tick, ring slot of the newest tick value, next audio frame, that frame's phase (up-sampled samples into its
        tick), then per channel the ticks whose value was NaN or inf (:attr:`nonfinite`)"""
        self.inv_scale = 1.0 / np.asarray(scale, dtype=np.float64).reshape(self.width)
        self.lo = np.asarray(lo, dtype=np.float64).reshape(self.width)
        self.hi = np.asarray(hi, dtype=np.float64).reshape(self.width)

    @property
    def max_frames(self) -> int:
        """The most frames one tick gives."""
        return -(-self.up // self.down)

    def frames(self, n: int) -> int:
        """Frames the next ``n`` ticks give."""
        k = int(self.istate[0])
        return frames_before(k + n, self.up, self.down) - frames_before(k, self.up, self.down)

    @property
    def nonfinite(self) -> np.ndarray:
        """Per channel, the ticks rendered so far whose value was NaN or inf (played as 0)."""
        return self.istate[4:]

    def reset(self) -> None:
        """Back to silence (the state of a new run; counts to 0)."""
        self.state[:] = 0.0
        self.istate[:] = 0

    def render(self, x: np.ndarray, out: np.ndarray) -> int:
        """``x`` (n, width) tick values in graph units -> the first :meth:`frames` (n) rows of ``out`` (float32); returns that count."""
        return render_ticks(self.params, self.state, self.istate, x, self.inv_scale, self.lo, self.hi, self.down, out)


@njit(cache=True, nogil=True, inline="always")
def _frame(coef, s, g, pos, span, hist, up, lo, hi, inv_scale, out, m):
    """Audio frame ``m`` (every channel) from polyphase branch ``g / hist``: dot product, NaN -> 0, clip, scale, float32."""
    for q in range(out.shape[1]):
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
        out[m, q] = np.float32(acc * inv_scale[q])


@njit(cache=True, nogil=True)
def render_ticks(p, s, si, x, inv_scale, lo, hi, down, out):
    """Interpolate ``x`` (n, w) by ``up / down`` (``up = p[1]``), clip, scale, into ``out`` float32; returns the frames written.

    ``si``: next tick, ring slot, next frame, phase, then one count per channel of the NaN/inf values of ``x`` (each
    entering the filter as 0).

    The up-sampling path of :func:`flowtex.dsp.resample_stream.resample_block` (same parameter and state
    layout, same products summed in the same order, so for ``down == 1`` the same samples), written for one tick
    in and its frames out, with every ``down``-th up-sampled sample kept: calling ``resample_block`` once per tick
    cost ~20x more per sample (benchmarks/bench_audio.py's setting)."""
    up = int(p[1]) if p.shape[0] > 5 else 1
    w = x.shape[1]
    hist = int(p[3]) if up > 1 else 1
    coef = p[4:]
    span = 2 * hist
    kt = si[0]
    pos = si[1]
    nout = si[2]
    ph = si[3]  # nout * down - kt * up, kept by additions: the next frame is in this tick while 0 <= ph < up
    m = 0
    for k in range(x.shape[0]):
        pos = pos + 1 if pos + 1 < hist else 0
        for q in range(w):
            v = x[k, q]
            if not v - v == 0.0:  # NaN or inf (inf - inf is NaN): enters the filter as 0 (it would poison its history)
                v = 0.0
                si[4 + q] += 1
            s[q * span + pos] = v
            s[q * span + pos + hist] = v
        if down == 1:  # a whole ratio: a counted loop (faster than the phase test below), the same frames
            for r in range(up):
                _frame(coef, s, r * hist, pos, span, hist, up, lo, hi, inv_scale, out, m)
                m += 1
            nout += up
            ph += up * down
        else:
            while ph < up:
                _frame(coef, s, ph * hist, pos, span, hist, up, lo, hi, inv_scale, out, m)
                m += 1
                nout += 1
                ph += down
        kt += 1
        ph -= up
    si[0] = kt
    si[1] = pos
    si[2] = nout
    si[3] = ph
    return m
