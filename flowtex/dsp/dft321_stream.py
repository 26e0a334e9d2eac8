"""Streaming DFT321: frame-wise overlap-add version of :func:`flowtex.dsp.dft321.dft321`.

Every ``hop`` samples the last ``frame`` samples of the three axes are
windowed, transformed (in-place radix-2 FFT for power-of-two frames, else a
direct real DFT from precomputed cos/sin tables; neither allocates), combined bin by bin as in the offline function (magnitude
root-sum-square, phase of the sum; no spectral smoothing), transformed back,
multiplied by the synthesis window (all ones for ``hann`` and ``hamming``),
scaled by 1 / (overlap-add sum of analysis x synthesis window) and
overlap-added. The window pairs are COLA at the allowed hops, so one moving
axis comes back exactly, delayed by ``frame - 1`` samples:

    y[t] = x_axis[t - (frame - 1)]

Latency: the frame ending at tick e is processed at tick e, when (e + 1) is
a multiple of ``hop``; after it, samples e-frame+1 .. e-frame+hop have
received every frame that covers them, and are played out one per tick over
the next ``hop`` ticks, always ``frame - 1`` ticks after they came in.

Power: frames whose phases were changed interfere when overlap-added, so the
output loses power. Measured without correction: three differently coloured
noises lose 0.3 % (Hann, hop = frame/2) to 0.8 % (sqrt-Hann); three white
noises of equal power, the worst case, lose 3.5-4 % (Hann, frame/2) and up to
10 % (hop = frame/8). The optional correction (``correct_power``) multiplies
the overlap-added output by sqrt(E_in / E_out), both exponentially weighted
energies over ~POWER_TAU_FRAMES frames: E_in of the input sample being played
out (sum over the axes), E_out of the uncorrected output. With one moving axis
the two are equal to rounding, so the gain is 1 and the identity holds.

Why not rocket-fft's ``np.fft.rfft`` inside numba: it allocates its result
arrays on every hop, and the node must not allocate while ticking. The
in-place radix-2 FFT here (three complex FFTs per frame) is as fast at frames 64-128 and
faster at 32; the direct DFT (O(frame^2) per hop) is slower at all three; see benchmarks/bench_dft321.py.

Before the first sample the input is taken as zero (the first frames are
zero-padded). A NaN or inf input sample spoils the frames that contain it
(about 2 frames of output) and then leaves the state: the node recovers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .layout import Field, Layout

WINDOWS = ("hann", "hamming", "sqrt_hann")
MAX_FRAME = 1024
PARAMS = Layout("float", [
    Field("frame", 1, "frame length N"),
    Field("hop", 1, "samples between frames"),
    Field("lam", 1, "forgetting factor of the power correction (0: off)"),
    Field("fft", 1, "1 for the fft method, 0 for dft"),
    Field("wa", "n", "analysis window"),
    Field("ws", "n", "synthesis window, scaled"),
    Field("tables", "tables", "fft: bit reversal (N), cos and -sin twiddles (N/2 each); dft: cos and sin (m x N each), "
                              "inverse weights (m)"),
], sizes=("n", "tables"))
"""The kernel's parameters for frame ``n`` and transform tables of ``tables`` values (:func:`param_sizes`)."""
STATE = Layout("float", [
    Field("ring", "3 * n", "input ring, one N-row per axis"),
    Field("acc", "n", "overlap-add ring"),
    Field("work", "6 * n + 2 * m", "scratch of one frame"),
    Field("energy", 2, "input energy, uncorrected output energy"),
], sizes=("n",), derived={"m": "n // 2 + 1"})
ISTATE = Layout("int", [Field("tick", 1, "ticks seen")])
P_FRAME = PARAMS.const("frame")
P_HOP = PARAMS.const("hop")
P_LAM = PARAMS.const("lam")
P_FFT = PARAMS.const("fft")
P_WA = PARAMS.const("wa")
SI_TICK = ISTATE.const("tick")
_state_offsets = STATE.kernel_offsets()
"""(m, o_ring, o_acc, o_work, o_energy) for frame n, generated from :data:`STATE`."""
POWER_TAU_FRAMES = 8.0
"""Time constant of the power correction, in frames."""


def latency_samples(frame: int) -> int:
    """Fixed delay of the streaming DFT321 from input to output, in samples."""
    return frame - 1


def check_config(frame: int, hop: int, window: str) -> None:
    """Raise ValueError (naming the parameter first: 'frame: ...') for a frame/hop/window that is not COLA."""
    if not 4 <= frame <= MAX_FRAME:
        raise ValueError(f"frame: must lie between 4 and {MAX_FRAME} samples, got {frame}")
    if window not in WINDOWS:
        raise ValueError(f"window: must be one of {', '.join(WINDOWS)}, got {window!r}")
    if hop < 1 or frame % hop != 0 or hop > frame // 2:
        raise ValueError(f"hop: must divide frame ({frame}) and be at most frame/2 for an exact overlap-add "
                         f"(e.g. {frame // 2} or {frame // 4}), got {hop}")


def windows(frame: int, hop: int, window: str) -> tuple[np.ndarray, np.ndarray]:
    """(analysis, synthesis) windows, the synthesis one scaled so that the overlap-add sum is exactly 1."""
    from scipy import signal

    check_config(frame, hop, window)
    base = signal.get_window("hann" if window == "sqrt_hann" else window, frame, fftbins=True)
    if window == "sqrt_hann":
        wa = np.sqrt(base)
        ws = wa.copy()
    else:
        wa, ws = base, np.ones(frame)
    ola = (wa * ws).reshape(-1, hop).sum(axis=0)  # overlap-add sum at each phase of the hop
    if np.ptp(ola) > 1e-9 * ola.max():
        raise ValueError(f"hop: {window} window of {frame} samples is not COLA at hop {hop}")
    return wa, ws / ola.mean()


def is_power_of_two(n: int) -> bool:
    return n >= 2 and n & (n - 1) == 0


def stream_params(frame: int, hop: int, window: str, correct_power: bool = True, method: str = "auto") -> np.ndarray:
    """Kernel parameters: header, analysis window, scaled synthesis window, then transform tables.

    ``method``: ``fft`` (in-place radix-2, power-of-two frames: bit-reversal
    table and twiddles), ``dft`` (direct real DFT, any frame: cos/sin tables
    and inverse weights), ``auto`` (fft when the frame is a power of two).
    """
    wa, ws = windows(frame, hop, window)
    if method == "auto":
        method = "fft" if is_power_of_two(frame) else "dft"
    if method == "fft" and not is_power_of_two(frame):
        raise ValueError(f"frame: the fft method needs a power of two, got {frame}; use method dft or frame {1 << frame.bit_length()}")
    lam = math.exp(-1.0 / (POWER_TAU_FRAMES * frame)) if correct_power else 0.0
    head = {"frame": frame, "hop": hop, "lam": lam, "fft": 1.0 if method == "fft" else 0.0, "wa": wa, "ws": ws}
    if method == "fft":
        bits = frame.bit_length() - 1
        rev = np.array([int(format(j, f"0{bits}b")[::-1], 2) for j in range(frame)], dtype=np.float64)
        ang = 2.0 * np.pi * np.arange(frame // 2) / frame
        tables = np.concatenate([rev, np.cos(ang), -np.sin(ang)])
        return PARAMS.pack({**head, "tables": tables}, n=frame, tables=tables.size)
    m = frame // 2 + 1
    k = np.arange(m)[:, None]
    j = np.arange(frame)[None, :]
    ang = 2.0 * np.pi * ((k * j) % frame) / frame  # exact integer phase before the float multiply
    weights = np.full(m, 2.0 / frame)
    weights[0] = 1.0 / frame
    if frame % 2 == 0:
        weights[-1] = 1.0 / frame
    tables = np.concatenate([np.cos(ang).ravel(), np.sin(ang).ravel(), weights])
    return PARAMS.pack({**head, "tables": tables}, n=frame, tables=tables.size)


def param_sizes(p: np.ndarray) -> dict[str, int]:
    """The sizes (n, tables) of :data:`PARAMS` that the packed parameters ``p`` were laid out for."""
    n = int(p[P_FRAME])
    return {"n": n, "tables": p.size - PARAMS.size(n=n, tables=0)}


def stream_state_sizes(frame: int) -> tuple[int, int]:
    """(float state, int state) sizes: input ring 3N, overlap-add ring N, work 6N + 2m, two energies; tick."""
    return STATE.size(n=frame), ISTATE.size()


@njit(cache=True, nogil=True, inline="always")
def _combine(sq, sr, si_, w):
    """Magnitude sqrt(sq) with the phase of sr + j si_, times w; phase 0 where the sum is 0."""
    mag = math.sqrt(sq)
    h = math.hypot(sr, si_)
    if h > 0.0:
        return w * mag * sr / h, w * mag * si_ / h
    return w * mag, 0.0


@njit(cache=True, nogil=True)
def _fft_inplace(re, im, nf, tr, ti):
    """Radix-2 decimation-in-time butterflies on data already in bit-reversed order (no allocation)."""
    size = 2
    while size <= nf:
        half = size // 2
        step = nf // size
        for start in range(0, nf, size):
            for k in range(half):
                wr = tr[k * step]
                wi = ti[k * step]
                a = start + k
                b = a + half
                xr = re[b] * wr - im[b] * wi
                xi = re[b] * wi + im[b] * wr
                re[b] = re[a] - xr
                im[b] = im[a] - xi
                re[a] += xr
                im[a] += xi
        size *= 2


@njit(cache=True, nogil=True)
def _frame_fft(p, ring, acc, work, start, nf):
    """FFT path: frame (ring from slot ``start``) -> DFT321 -> overlap-added into acc.

    Three N-point complex FFTs per frame: axes 0 and 1 share one (x0 + j x1,
    separated by conjugate symmetry), axis 2 has its own, and the inverse is
    ifft(Y) = conj(fft(conj(Y))) / N, of which only the real part is needed.
    """
    o = P_WA
    wa = p[o:o + nf]
    ws = p[o + nf:o + 2 * nf]
    rev = p[o + 2 * nf:o + 3 * nf]
    tr = p[o + 3 * nf:o + 3 * nf + nf // 2]
    ti = p[o + 3 * nf + nf // 2:o + 4 * nf]
    zr = work[0:nf]
    zi = work[nf:2 * nf]
    cr = work[2 * nf:3 * nf]
    ci = work[3 * nf:4 * nf]
    yr = work[4 * nf:5 * nf]
    yi = work[5 * nf:6 * nf]
    for j in range(nf):
        q = start + j
        if q >= nf:
            q -= nf
        d = int(rev[j])
        zr[d] = ring[q] * wa[j]
        zi[d] = ring[nf + q] * wa[j]
        cr[d] = ring[2 * nf + q] * wa[j]
        ci[d] = 0.0
    _fft_inplace(zr, zi, nf, tr, ti)
    _fft_inplace(cr, ci, nf, tr, ti)
    scale = 1.0 / nf
    for k in range(nf // 2 + 1):  # Y is Hermitian: bins above N/2 are conjugates
        km = nf - k if k > 0 else 0
        br = zr[km]
        bi = -zi[km]
        x0r = 0.5 * (zr[k] + br)
        x0i = 0.5 * (zi[k] + bi)
        x1r = 0.5 * (zi[k] - bi)
        x1i = -0.5 * (zr[k] - br)
        sq = x0r * x0r + x0i * x0i + x1r * x1r + x1i * x1i + cr[k] * cr[k] + ci[k] * ci[k]
        vr, vi = _combine(sq, x0r + x1r + cr[k], x0i + x1i + ci[k], scale)
        d = int(rev[k])
        yr[d] = vr
        yi[d] = -vi
        if 0 < k < nf - k:
            d = int(rev[nf - k])
            yr[d] = vr
            yi[d] = vi
    _fft_inplace(yr, yi, nf, tr, ti)
    for j in range(nf):
        q = start + j
        if q >= nf:
            q -= nf
        acc[q] += yr[j] * ws[j]


@njit(cache=True, nogil=True)
def _frame_dft(p, ring, acc, work, start, nf):
    """Direct real-DFT path (any frame length): same result as :func:`_frame_fft`."""
    m = nf // 2 + 1
    o = P_WA
    wa = p[o:o + nf]
    ws = p[o + nf:o + 2 * nf]
    ct = o + 2 * nf
    st = ct + m * nf
    wt = st + m * nf
    fr = work[0:3 * nf]
    yr = work[3 * nf:3 * nf + m]
    yi = work[3 * nf + m:3 * nf + 2 * m]
    for a in range(3):
        for j in range(nf):
            q = start + j
            if q >= nf:
                q -= nf
            fr[a * nf + j] = ring[a * nf + q] * wa[j]
    for k in range(m):
        sq = 0.0
        sr = 0.0
        sim = 0.0
        row = k * nf
        for a in range(3):
            re = 0.0
            im = 0.0
            base = a * nf
            for j in range(nf):
                v = fr[base + j]
                re += v * p[ct + row + j]
                im -= v * p[st + row + j]
            sq += re * re + im * im
            sr += re
            sim += im
        yr[k], yi[k] = _combine(sq, sr, sim, p[wt + k])
    for j in range(nf):
        v = 0.0
        for k in range(m):
            v += yr[k] * p[ct + k * nf + j] - yi[k] * p[st + k * nf + j]
        q = start + j
        if q >= nf:
            q -= nf
        acc[q] += v * ws[j]


@njit(cache=True, nogil=True)
def dft321_stream_block(p, s, si, x, y):
    """Advance by ``x.shape[0]`` ticks: x (n, 3) in, y (n, 1) out. ``si[SI_TICK]`` counts ticks."""
    nf = int(p[P_FRAME])
    hop = int(p[P_HOP])
    lam = p[P_LAM]
    fft = p[P_FFT] > 0.5
    _, o_ring, o_acc, o_work, en = _state_offsets(nf)  # s[en]: input energy, s[en + 1]: uncorrected output energy
    ring = s[o_ring:o_ring + 3 * nf]
    acc = s[o_acc:o_acc + nf]
    work = s[o_work:en]
    t = si[SI_TICK]
    for r in range(x.shape[0]):
        pos = t % nf
        for a in range(3):
            ring[a * nf + pos] = x[r, a]
        if (t + 1) % hop == 0:
            start = (t + 1) % nf  # ring slot of the frame's oldest sample
            if fft:
                _frame_fft(p, ring, acc, work, start, nf)
            else:
                _frame_dft(p, ring, acc, work, start, nf)
        out = (t + 1) % nf  # slot of sample t - (nf - 1): complete now
        v = acc[out]
        acc[out] = 0.0
        if lam > 0.0:
            e_in = 0.0
            if t >= nf - 1:
                for a in range(3):
                    e_in += ring[a * nf + out] * ring[a * nf + out]
            s[en] = lam * s[en] + e_in
            s[en + 1] = lam * s[en + 1] + v * v
            if not (math.isfinite(s[en]) and math.isfinite(s[en + 1])):
                s[en] = 0.0  # a NaN/inf input passes through once; the correction restarts instead of staying NaN
                s[en + 1] = 0.0
            elif s[en + 1] > 0.0:
                v *= math.sqrt(s[en] / s[en + 1])
        y[r, 0] = v
        t += 1
    si[SI_TICK] = t


def dft321_stream(x: np.ndarray, frame: int = 128, hop: int = 64, window: str = "hann", correct_power: bool = True,
                  method: str = "auto") -> np.ndarray:
    """Run the streaming DFT321 over a whole (n, 3) array from a fresh state; returns (n,), same unit.

    Output sample t is the DFT321 of the frames around input sample
    t - (frame - 1) (see the module docstring). Raises ValueError on a bad config.
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3:
        raise ValueError(f"dft321_stream needs an array of shape (n, 3), got shape {x.shape}")
    p = stream_params(frame, hop, window, correct_power, method)
    nfs, nis = stream_state_sizes(frame)
    s, si = np.zeros(nfs), np.zeros(nis, np.int64)
    y = np.zeros((x.shape[0], 1))
    dft321_stream_block(p, s, si, x, y)
    return y[:, 0]
