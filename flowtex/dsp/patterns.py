"""Patterned textures (Guruswamy thesis ch. 4): band edges, segmentation by rising peaks, and the ring-down rendering kernel.

Rendering (``pattern_block``): features sit at positions x_k (mm) along the pattern's
axis u. Each tick the tool position is projected, x = u . (position - origin); every
feature crossed since the previous tick (in either direction) starts a ring-down:
filter k excited by an impulse of amplitude A_k. The output is the **sum** of all
active ring-downs; a new feature never truncates an older one (Guruswamy's time aliasing).
At most ``max_active`` ring-downs play at once; when all slots are busy the oldest is
replaced. A ring-down ends after ``length_k`` ticks, when its impulse response has fallen
for good below RING_DECAY (1e-6) of its peak (dsp.prony.ring_length).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .layout import Field, Layout

PARAMS = Layout("float", [
    Field("k", 1, "features K"),
    Field("order", 1, "filter order P (coefficients per filter: P + 1)"),
    Field("slots", 1, "most ring-downs at once"),
    Field("axis", 3, "the pattern's axis"),
    Field("origin", 3, "origin of the axis, mm"),
    Field("positions", "k", "feature positions along the axis, mm, sorted"),
    Field("amplitudes", "k", "A_k, m/s^2"),
    Field("lengths", "k", "ring-down length of each feature's filter, ticks"),
    Field("b", "k * (order + 1)", "numerators, one row per feature"),
    Field("a", "k * (order + 1)", "denominators (a[0] = 1), one row per feature"),
], sizes=("k", "order"))
"""The kernel's parameters for K features with filters of order P."""
STATE = Layout("float", [
    Field("xprev", 1, "position along the axis on the previous tick, mm"),
    Field("input", "slots", "per slot: the impulse to feed on its next tick"),
    Field("z", "slots * zord", "per slot: its filter's state"),
], sizes=("slots", "order"), derived={"zord": "max(order, 1)"})
ISTATE = Layout("int", [
    Field("started", 1, "1 once a position was seen"),
    Field("filter", "slots", "per slot: the feature playing (-1: free)"),
    Field("age", "slots", "per slot: ticks played"),
], sizes=("slots",))
H_K = PARAMS.const("k")
H_P = PARAMS.const("order")
H_SLOTS = PARAMS.const("slots")
H_AXIS = PARAMS.const("axis")
H_ORIGIN = PARAMS.const("origin")
_param_offsets = PARAMS.kernel_offsets()
"""(o_k, o_order, o_slots, o_axis, o_origin, o_positions, o_amplitudes, o_lengths, o_b, o_a) for (k, order)."""
_state_offsets = STATE.kernel_offsets()
"""(zord, o_xprev, o_input, o_z) for (slots, order), generated from :data:`STATE`."""
_istate_offsets = ISTATE.kernel_offsets()
"""(o_started, o_filter, o_age) for slots, generated from :data:`ISTATE`."""
RING_DECAY = 1e-6
"""A ring-down stops when its slowest pole has decayed to this fraction."""


def smoothed_spectrum_db(psd: np.ndarray, bins: int = 9) -> np.ndarray:
    """The PSD in dB, low-passed along frequency by a centred moving average over ``bins`` bins (edges: shorter windows)."""
    db = 10.0 * np.log10(np.maximum(np.asarray(psd, dtype=np.float64), 1e-300))
    kernel = np.ones(bins)
    num = np.convolve(db, kernel, mode="same")
    den = np.convolve(np.ones_like(db), kernel, mode="same")
    return num / den


def band_edges(freqs: np.ndarray, psd: np.ndarray, smooth_hz: float = 100.0) -> tuple[float, float]:
    """Edges (Hz) of the band around the dominant peak: the minima either side of the smoothed spectrum's global maximum.

    The dB spectrum is smoothed over ``smooth_hz`` (default 100 Hz, at least 3 bins):
    wide enough to average out the harmonics of the feature rate (speed / spacing,
    30 Hz for 2 mm at 60 mm/s), which would otherwise put a "minimum" between every
    pair of harmonics and give a band far too narrow.
    """
    df = float(freqs[1] - freqs[0]) if freqs.size > 1 else 1.0
    bins = max(3, int(round(smooth_hz / df)) | 1)
    s = smoothed_spectrum_db(psd, bins)
    k = int(np.argmax(s[1:])) + 1  # skip the DC bin
    lo = k
    while lo > 1 and s[lo - 1] < s[lo]:
        lo -= 1
    hi = k
    while hi < s.size - 1 and s[hi + 1] < s[hi]:
        hi += 1
    return float(freqs[lo]), float(freqs[hi])


def segment_starts(x: np.ndarray, min_peak_fraction: float = 0.25, guard: int = 2, min_gap: int = 1) -> np.ndarray:
    """Start ticks of segments of the (band-passed) signal ``x`` by Guruswamy's rising-peak rule.

    Peaks are the local maxima of |x|. A feature starts with a run of rising
    peaks (each larger than the peak before it) that exceed ``min_peak_fraction``
    times the 95th percentile of all peaks (smaller rises are noise in a
    ring-down's tail). One run is one feature: a zero-phase band-pass spreads an
    onset over several half-cycles that all rise, and each used to start a
    segment of its own. A run whose first peak comes less than ``min_gap`` ticks
    after the previous feature's highest peak continues that feature (the
    band-pass cannot resolve features closer than its own response; two
    resonances beating inside one feature make such runs). The segment begins at
    the local minimum of |x| before the run's first peak, moved ``guard`` ticks
    earlier: the band-pass blurs onsets, and an early start only costs the full-band
    onset search (fit.pattern) a few ticks, a late one loses the onset.
    """
    starts, _tops = feature_onsets(x, min_peak_fraction, guard, min_gap)
    return starts


def feature_onsets(x: np.ndarray, min_peak_fraction: float = 0.25, guard: int = 2,
                   min_gap: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(segment starts, each feature's highest peak tick) by the rule of :func:`segment_starts`."""
    ax = np.abs(np.asarray(x, dtype=np.float64))
    empty = np.zeros(0, np.int64)
    if ax.size < 3:
        return empty, empty
    inner = ax[1:-1]
    peaks = np.nonzero((inner > ax[:-2]) & (inner >= ax[2:]))[0] + 1
    if peaks.size == 0:
        return empty, empty
    floor = min_peak_fraction * np.percentile(ax[peaks], 95)
    starts: list[int] = []
    tops: list[int] = []
    prev_height = 0.0
    rising = False
    for pk in peaks:
        h = ax[pk]
        if h > floor and h > prev_height:
            if not rising and (not tops or pk - tops[-1] >= min_gap):
                j = pk
                while j > 0 and ax[j - 1] < ax[j]:  # back to the local minimum just before the peak (Guruswamy thesis sec. 4.3.3)
                    j -= 1
                starts.append(max(j - guard, starts[-1] + 1 if starts else 0))
                tops.append(int(pk))
            elif h > ax[tops[-1]]:
                tops[-1] = int(pk)
            rising = True
        else:
            rising = False
        prev_height = h
    return np.asarray(starts, np.int64), np.asarray(tops, np.int64)


def pattern_params(axis: np.ndarray, origin: np.ndarray, positions: np.ndarray, amplitudes: np.ndarray,
                   lengths: np.ndarray, b: np.ndarray, a: np.ndarray, max_active: int) -> np.ndarray:
    """Pack the kernel's parameter vector; ``b``, ``a`` are (K, P + 1) with a[:, 0] == 1, positions sorted."""
    k, width = b.shape
    return PARAMS.pack({"k": k, "order": width - 1, "slots": max_active, "axis": axis, "origin": origin, "positions": positions,
                        "amplitudes": amplitudes, "lengths": lengths.astype(np.float64), "b": b, "a": a}, k=k, order=width - 1)


def pattern_state(order: int, max_active: int) -> tuple[np.ndarray, np.ndarray]:
    """Float state [x_prev, slot input (S), slot z (S x P)]; int state [started, slot filter (S), slot age (S)]."""
    return STATE.zeros(slots=max_active, order=order), ISTATE.pack({"filter": -1}, slots=max_active)


@njit(cache=True)
def _start(p, s, si, k, amp, slots, order) -> None:
    _, _, o_in, o_z = _state_offsets(slots, order)
    _, o_f, o_age = _istate_offsets(slots)
    best = 0
    best_age = -1
    for j in range(slots):  # a free slot, else the oldest ring-down
        if si[o_f + j] < 0:
            best = j
            break
        if si[o_age + j] > best_age:
            best_age = si[o_age + j]
            best = j
    si[o_f + best] = k
    si[o_age + best] = 0
    s[o_in + best] = amp
    z0 = o_z + best * order
    for i in range(order):
        s[z0 + i] = 0.0


@njit(cache=True)
def pattern_block(p, s, si, position, in_contact, y) -> None:
    """Render the patterned texture for a block: position (n, 3) mm, in_contact (n, 1), y (n, 1) m/s^2."""
    nk = int(p[H_K])
    order = int(p[H_P])
    slots = int(p[H_SLOTS])
    _, _, _, _, _, o_pos, o_amp, o_len, b0, a0 = _param_offsets(nk, order)
    pos = p[o_pos:o_pos + nk]
    amps = p[o_amp:o_amp + nk]
    lens = p[o_len:o_len + nk]
    w = order + 1
    zord, o_x, o_in, o_z = _state_offsets(slots, order)
    o_st, o_f, o_age = _istate_offsets(slots)
    for t in range(position.shape[0]):
        x = (p[H_AXIS] * (position[t, 0] - p[H_ORIGIN]) + p[H_AXIS + 1] * (position[t, 1] - p[H_ORIGIN + 1])
             + p[H_AXIS + 2] * (position[t, 2] - p[H_ORIGIN + 2]))
        if si[o_st] == 1 and in_contact[t, 0] >= 0.5 and x != s[o_x]:
            if x > s[o_x]:
                i0 = np.searchsorted(pos, s[o_x], side="right")
                i1 = np.searchsorted(pos, x, side="right")
            else:
                i0 = np.searchsorted(pos, x, side="left")
                i1 = np.searchsorted(pos, s[o_x], side="left")
            for k in range(i0, i1):
                _start(p, s, si, k, amps[k], slots, zord)
        si[o_st] = 1
        s[o_x] = x
        acc = 0.0
        for j in range(slots):
            k = si[o_f + j]
            if k < 0:
                continue
            u = s[o_in + j]
            s[o_in + j] = 0.0
            bk = b0 + k * w
            ak = a0 + k * w
            z = o_z + j * zord
            out = p[bk] * u + s[z]
            for i in range(order - 1):
                s[z + i] = p[bk + i + 1] * u - p[ak + i + 1] * out + s[z + i + 1]
            if order >= 1:
                s[z + order - 1] = p[bk + order] * u - p[ak + order] * out
            acc += out
            si[o_age + j] += 1
            if si[o_age + j] >= lens[k]:
                si[o_f + j] = -1
        y[t, 0] = acc
