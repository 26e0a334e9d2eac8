"""Tap transient playback.

Source: Culbertson & Kuchenbecker 2017, "Importance of matching physical friction, hardness, and texture
in creating realistic haptic virtual surfaces", section 3.3.2.

A tap library holds K transients (accelerations, m/s^2) of L samples each,
recorded at incoming speeds s_0 < ... < s_{K-1} (mm/s). For an incoming speed
v the played transient is

* v <= s_0:            (v / s_0) * T_0   (v < 0 counts as 0: silence),
* v >= s_{K-1}:        T_{K-1},
* s_j <= v <= s_{j+1}: (1 - u) T_j + u T_{j+1},  u = (v - s_j) / (s_{j+1} - s_j),

and the output force is F = m * a (N). Playback starts on the tick contact
begins (rising edge of ``in_contact``), restarts on every new contact and
ends (F = 0) after L samples, whether or not contact has ended.

Parameter layout (``p``): [mass, K, L, s_0..s_{K-1}, T_0[0..L-1], ..., T_{K-1}[..]].
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .layout import Field, Layout

TAP_P = Layout("float", [
    Field("mass", 1, "kg"),
    Field("count", 1, "K transients"),
    Field("length", 1, "L samples each"),
    Field("speeds", "k", "incoming speed of each transient, mm/s, increasing"),
    Field("transients", "k * length", "the K transients one after the other, m/s^2"),
], sizes=("k", "length"))
TAP_S = Layout("float", [Field("w_lo", 1, "weight of the lower transient"), Field("w_hi", 1, "weight of the upper one"),
                         Field("prev", 1, "contact state of the previous tick")])
TAP_SI = Layout("int", [Field("lo", 1, "lower transient"), Field("hi", 1, "upper transient"),
                        Field("pos", 1, "sample playing (L: none)")])
TP_MASS = TAP_P.const("mass")
TP_COUNT = TAP_P.const("count")
TP_LENGTH = TAP_P.const("length")
TP_SPEEDS = TAP_P.const("speeds")
TS_W_LO = TAP_S.const("w_lo")
TS_W_HI = TAP_S.const("w_hi")
TS_PREV = TAP_S.const("prev")
TAP_STATE = TAP_S.size()
TI_LO = TAP_SI.const("lo")
TI_HI = TAP_SI.const("hi")
TI_POS = TAP_SI.const("pos")
TAP_ISTATE = TAP_SI.size()


def tap_params(mass_kg: float, speeds: np.ndarray, transients: np.ndarray) -> np.ndarray:
    """Pack mass, speeds (K, mm/s, increasing) and transients (K x L, m/s^2) for :func:`tap_block`."""
    speeds = np.asarray(speeds, dtype=np.float64)
    transients = np.asarray(transients, dtype=np.float64)
    k, length = transients.shape
    if speeds.shape != (k,):
        raise ValueError(f"{k} transients need {k} speeds, got {speeds.shape}")
    return TAP_P.pack({"mass": mass_kg, "count": float(k), "length": float(length), "speeds": speeds, "transients": transients},
                      k=k, length=length)


def initial_tap_state(length: int) -> tuple[np.ndarray, np.ndarray]:
    """Idle state: nothing playing (position = L), previous contact 0."""
    return TAP_S.zeros(), TAP_SI.pack({"pos": length})


@njit(cache=True)
def tap_weights(p: np.ndarray, v: float) -> tuple[int, int, float, float]:
    """(lo, hi, w_lo, w_hi): the played transient is w_lo T_lo + w_hi T_hi."""
    k = int(p[TP_COUNT])
    s0 = p[TP_SPEEDS]
    if not (v > 0.0):  # also NaN
        return 0, 0, 0.0, 0.0
    if v <= s0:
        return 0, 0, v / s0, 0.0
    if v >= p[TP_SPEEDS + k - 1]:
        return k - 1, k - 1, 1.0, 0.0
    j = 0
    while p[TP_SPEEDS + j + 1] < v:
        j += 1
    lo = p[TP_SPEEDS + j]
    hi = p[TP_SPEEDS + j + 1]
    u = (v - lo) / (hi - lo)
    return j, j + 1, 1.0 - u, u


@njit(cache=True)
def tap_block(p: np.ndarray, s: np.ndarray, si: np.ndarray, contact: np.ndarray, speed: np.ndarray, out: np.ndarray) -> None:
    """Play the speed-interpolated transient from each contact onset; F = m a (N)."""
    mass = p[TP_MASS]
    k = int(p[TP_COUNT])
    length = int(p[TP_LENGTH])
    base = TP_SPEEDS + k
    for t in range(contact.shape[0]):
        c = contact[t, 0]
        now = 1.0 if c > 0.5 else (0.0 if c <= 0.5 else s[TS_PREV])  # NaN keeps the previous state
        if now > 0.5 and s[TS_PREV] < 0.5:
            lo, hi, wlo, whi = tap_weights(p, speed[t, 0])
            si[TI_LO] = lo
            si[TI_HI] = hi
            s[TS_W_LO] = wlo
            s[TS_W_HI] = whi
            si[TI_POS] = 0
        s[TS_PREV] = now
        pos = si[TI_POS]
        if pos < length:
            a = s[TS_W_LO] * p[base + si[TI_LO] * length + pos] + s[TS_W_HI] * p[base + si[TI_HI] * length + pos]
            out[t, 0] = mass * a
            si[TI_POS] = pos + 1
        else:
            out[t, 0] = 0.0


