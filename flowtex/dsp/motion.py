"""Speed estimation and contact detection kernels .

Sources: Kuchenbecker & Culbertson 2014, "Haptic rendering of textures" (tutorial);
Romano & Kuchenbecker 2012, "Creating realistic virtual textures from contact acceleration data" (section 4.1);
Culbertson & Kuchenbecker 2017, "Importance of matching physical friction, hardness, and texture
in creating realistic haptic virtual surfaces" (section 3.3.2).

Units: position in mm, velocity and speed in mm/s, force in N, normal vectors
dimensionless. Every kernel works row by row over a block (``n`` rows), keeps
all of its memory in the caller's ``p`` / ``s`` / ``si`` arrays and allocates
nothing, so any split of a recording into blocks gives identical numbers.

Speed estimator
---------------
velocity = backward difference of position times the rate (mm/s), low-passed
per axis by one biquad (direct form I), then projected onto the tangent plane
(v_t = v - (v.n) n); speed = |v_t|. The biquad is either

* ``lowpass``: the first-order low-pass ``y += alpha (x - y)`` with its pole
  at ``exp(-2 pi fc / fs)`` (the 20 Hz rendering filter of Kuchenbecker & Culbertson 2014 and Romano & Kuchenbecker 2012), or
* ``hatt``: a second-order Butterworth (zeta = 1/sqrt 2) low-pass with its
  corner at 125 rad/s, discretised by the bilinear transform with the corner
  pre-warped (the same digital filter as ``scipy.signal.butter(2, 125/(2 pi),
  fs=fs)``). The seeds say only "2nd-order low-pass at 125 rad/s"; the
  Butterworth damping and the bilinear transform are flowtex's choice.

Stationary-pen fix, streaming (Romano & Kuchenbecker 2012, section 4.1): the position is high-passed at
10 Hz (``x - LP10(x)``, first order) and then low-passed at 100 Hz (first
order); both filters start at the first valid position, so there is no start
transient. When the tangential part of that filtered displacement is shorter
than ``threshold`` (0.06 mm in Romano & Kuchenbecker 2012) the outputs are 0. For steady sliding at
speed v the filtered displacement is about v / (2 pi 10 Hz), so 0.06 mm
gates speeds below about 3.8 mm/s; a threshold of 0 disables the gate. The
velocity filter keeps running while gated, so leaving the gate is smooth.

Invalid samples: a position sample with a NaN/inf component is skipped: the
filters do not advance and the outputs hold their last values. The next valid
sample is differentiated against the last valid one over the whole gap
(``(x - x_last) * fs / (gap + 1)``), i.e. the mean velocity across the gap,
so a dropout neither poisons the state nor produces a spike. A finite sample
whose velocity overflows (a jump near 1e308 mm) is skipped the same way. A normal input
that is non-finite or shorter than 1e-9 is replaced by the last valid normal.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .filters import A1, A2, B0, B1, B2, SECTION_PARAMS, SECTION_STATE, X1, X2, Y1, Y2
from .layout import Field, Layout

# ---- speed estimator layout -------------------------------------------------
SPEED_P = Layout("float", [
    Field("rate", 1, "Hz"),
    Field("biquad", SECTION_PARAMS, "the velocity filter: a flowtex.dsp.filters.SECTION record (b0, b1, b2, a1, a2)"),
    Field("hp_alpha", 1, "10 Hz low-pass used by the high-pass"),
    Field("lp_alpha", 1, "100 Hz low-pass of the high-passed position"),
    Field("threshold", 1, "stationary threshold, mm"),
])
SPEED_S = Layout("float", [
    Field("xprev", 3, "last valid position, mm"),
    Field("normal", 3, "last valid unit normal"),
    Field("biquad", 3 * SECTION_STATE, "per axis the velocity filter's SECTION_MEMORY record (x1, x2, y1, y2)"),
    Field("hp", 3, "10 Hz low-pass state used by the high-pass"),
    Field("lp", 3, "100 Hz low-pass state of the high-passed position"),
    Field("vel", 3, "last output velocity, mm/s"),
    Field("speed", 1, "last output speed, mm/s"),
])
SPEED_SI = Layout("int", [Field("started", 1, "1 once a finite position was seen"),
                          Field("gap", 1, "ticks skipped since the last valid position")])
SP_RATE = SPEED_P.const("rate")
SP_BIQUAD = SPEED_P.const("biquad")
SP_B0, SP_B1, SP_B2, SP_A1, SP_A2 = (SP_BIQUAD + o for o in (B0, B1, B2, A1, A2))
SP_HP_ALPHA = SPEED_P.const("hp_alpha")
SP_LP_ALPHA = SPEED_P.const("lp_alpha")
SP_THRESHOLD = SPEED_P.const("threshold")
SPEED_PARAMS = SPEED_P.size()
SS_XPREV = SPEED_S.const("xprev")
SS_NORMAL = SPEED_S.const("normal")
SS_BIQUAD = SPEED_S.const("biquad")
SS_HP = SPEED_S.const("hp")
SS_LP = SPEED_S.const("lp")
SS_VEL = SPEED_S.const("vel")
SS_SPEED = SPEED_S.const("speed")
SPEED_STATE = SPEED_S.size()
SI_STARTED = SPEED_SI.const("started")
SI_GAP = SPEED_SI.const("gap")
SPEED_ISTATE = SPEED_SI.size()

# ---- contact layout -----------------------------------------------------------
CONTACT_P = Layout("float", [Field("rate", 1, "Hz"), Field("on", 1, "N"), Field("off", 1, "N")])
CONTACT_S = Layout("float", [
    Field("xprev", 3, "last valid position, mm"),
    Field("normal", 3, "last valid unit normal"),
    Field("incoming", 1, "held incoming speed, mm/s"),
    Field("vn", 1, "latest approach speed estimate -(v.n), mm/s"),
])
CONTACT_SI = Layout("int", [Field("started", 1), Field("gap", 1), Field("in_contact", 1)])
CP_RATE = CONTACT_P.const("rate")
CP_ON = CONTACT_P.const("on")
CP_OFF = CONTACT_P.const("off")
CONTACT_PARAMS = CONTACT_P.size()
CS_XPREV = CONTACT_S.const("xprev")
CS_NORMAL = CONTACT_S.const("normal")
CS_INCOMING = CONTACT_S.const("incoming")
CS_VN = CONTACT_S.const("vn")
CONTACT_STATE = CONTACT_S.size()
CI_STARTED = CONTACT_SI.const("started")
CI_GAP = CONTACT_SI.const("gap")
CI_IN = CONTACT_SI.const("in_contact")
CONTACT_ISTATE = CONTACT_SI.size()

MIN_NORMAL = 1e-9
"""A normal vector shorter than this is treated as missing."""


def first_order_biquad(cutoff_hz: float, rate_hz: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of ``y += alpha (x - y)`` with the pole at exp(-2 pi fc / fs)."""
    pole = math.exp(-2.0 * math.pi * cutoff_hz / rate_hz)
    return (1.0 - pole, 0.0, 0.0, -pole, 0.0)


def butter2_biquad(omega_rad_s: float, rate_hz: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of a 2nd-order Butterworth low-pass, corner ``omega`` rad/s.

    Bilinear transform of wc^2 / (s^2 + sqrt(2) wc s + wc^2) with the corner
    pre-warped: K = tan(omega / (2 fs)), norm = 1 + sqrt(2) K + K^2.
    """
    if not 0.0 < omega_rad_s < math.pi * rate_hz:
        raise ValueError(f"corner {omega_rad_s:g} rad/s must be between 0 and Nyquist ({math.pi * rate_hz:g} rad/s)")
    k = math.tan(omega_rad_s / (2.0 * rate_hz))
    norm = 1.0 + math.sqrt(2.0) * k + k * k
    b0 = k * k / norm
    return (b0, 2.0 * b0, b0, 2.0 * (k * k - 1.0) / norm, (1.0 - math.sqrt(2.0) * k + k * k) / norm)


def speed_params(biquad: tuple[float, ...], rate_hz: float, threshold_mm: float) -> np.ndarray:
    """Parameter array for :func:`speed_block` (layout ``SP_*``)."""
    return SPEED_P.pack({"rate": rate_hz, "biquad": biquad,
                         "hp_alpha": 1.0 - math.exp(-2.0 * math.pi * 10.0 / rate_hz),
                         "lp_alpha": 1.0 - math.exp(-2.0 * math.pi * min(100.0, 0.45 * rate_hz) / rate_hz),
                         "threshold": threshold_mm})


def initial_normal_state(size: int, offset: int, normal: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """A zeroed state array of ``size`` with the unit ``normal`` stored at ``offset``."""
    s = np.zeros(size)
    n = np.asarray(normal, dtype=np.float64)
    s[offset:offset + 3] = n / np.linalg.norm(n)
    return s


@njit(cache=True, inline="always")
def update_normal(nrm: np.ndarray, t: int, s: np.ndarray, off: int) -> None:
    """Store the normal of row ``t`` (normalised) in ``s[off:off+3]`` if it is finite and non-zero."""
    a = nrm[t, 0]
    b = nrm[t, 1]
    c = nrm[t, 2]
    length = math.sqrt(a * a + b * b + c * c)
    if length > MIN_NORMAL and math.isfinite(length):
        s[off] = a / length
        s[off + 1] = b / length
        s[off + 2] = c / length


@njit(cache=True, inline="always")
def finite3(x: np.ndarray, t: int) -> bool:
    """True when row ``t`` of the 3-column array ``x`` is finite."""
    return math.isfinite(x[t, 0]) and math.isfinite(x[t, 1]) and math.isfinite(x[t, 2])


@njit(cache=True)
def speed_block(p: np.ndarray, s: np.ndarray, si: np.ndarray, pos: np.ndarray, nrm: np.ndarray,
                speed: np.ndarray, vel: np.ndarray) -> None:
    """Tangential speed and velocity (mm/s) from position (mm); see the module docstring."""
    rate = p[SP_RATE]
    b0 = p[SP_B0]
    b1 = p[SP_B1]
    b2 = p[SP_B2]
    a1 = p[SP_A1]
    a2 = p[SP_A2]
    ahp = p[SP_HP_ALPHA]
    alp = p[SP_LP_ALPHA]
    thr = p[SP_THRESHOLD]
    for t in range(pos.shape[0]):
        update_normal(nrm, t, s, SS_NORMAL)
        if not finite3(pos, t):
            si[SI_GAP] += 1
            for c in range(3):
                vel[t, c] = s[SS_VEL + c]
            speed[t, 0] = s[SS_SPEED]
            continue
        if si[SI_STARTED] == 0:
            si[SI_STARTED] = 1
            for c in range(3):
                s[SS_XPREV + c] = pos[t, c]
                s[SS_HP + c] = pos[t, c]
                s[SS_LP + c] = 0.0
        scale = rate / (si[SI_GAP] + 1.0)
        d0 = (pos[t, 0] - s[SS_XPREV]) * scale
        d1 = (pos[t, 1] - s[SS_XPREV + 1]) * scale
        d2 = (pos[t, 2] - s[SS_XPREV + 2]) * scale
        if not math.isfinite(d0 * d0 + d1 * d1 + d2 * d2):  # finite but absurd (overflowing) jump: skip it too
            si[SI_GAP] += 1
            for c in range(3):
                vel[t, c] = s[SS_VEL + c]
            speed[t, 0] = s[SS_SPEED]
            continue
        si[SI_GAP] = 0
        n0 = s[SS_NORMAL]
        n1 = s[SS_NORMAL + 1]
        n2 = s[SS_NORMAL + 2]
        # velocity filter and stationary displacement filter, per axis
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        for c in range(3):
            x = pos[t, c]
            v = (x - s[SS_XPREV + c]) * scale
            s[SS_XPREV + c] = x
            base = SS_BIQUAD + SECTION_STATE * c
            x1 = s[base + X1]
            x2 = s[base + X2]
            y1 = s[base + Y1]
            y2 = s[base + Y2]
            y = b0 * v + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
            s[base + X1] = v
            s[base + X2] = x1
            s[base + Y1] = y
            s[base + Y2] = y1
            lp10 = s[SS_HP + c] + ahp * (x - s[SS_HP + c])
            s[SS_HP + c] = lp10
            disp = s[SS_LP + c] + alp * ((x - lp10) - s[SS_LP + c])
            s[SS_LP + c] = disp
            if c == 0:
                f0 = y
                d0 = disp
            elif c == 1:
                f1 = y
                d1 = disp
            else:
                f2 = y
                d2 = disp
        vn = f0 * n0 + f1 * n1 + f2 * n2
        t0 = f0 - vn * n0
        t1 = f1 - vn * n1
        t2 = f2 - vn * n2
        dn = d0 * n0 + d1 * n1 + d2 * n2
        e0 = d0 - dn * n0
        e1 = d1 - dn * n1
        e2 = d2 - dn * n2
        if thr > 0.0 and e0 * e0 + e1 * e1 + e2 * e2 < thr * thr:
            t0 = 0.0
            t1 = 0.0
            t2 = 0.0
        sp = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        vel[t, 0] = t0
        vel[t, 1] = t1
        vel[t, 2] = t2
        speed[t, 0] = sp
        s[SS_VEL] = t0
        s[SS_VEL + 1] = t1
        s[SS_VEL + 2] = t2
        s[SS_SPEED] = sp


@njit(cache=True)
def contact_block(p: np.ndarray, s: np.ndarray, si: np.ndarray, force: np.ndarray, pos: np.ndarray, nrm: np.ndarray,
                  in_contact: np.ndarray, incoming: np.ndarray, onset: np.ndarray) -> None:
    """Contact state with hysteresis, onset pulse and incoming (approach) speed.

    Contact begins on the first tick with ``force >= on`` and ends on the first
    tick with ``force < off`` (``off <= on``). The approach speed of a tick is
    ``-(v . n)`` with ``v`` the backward-difference velocity of the position
    (mm/s; over the whole gap after invalid samples), clamped at 0 (a tool
    moving away has no incoming speed). At onset it is latched and held while
    in contact; it reads 0 out of contact. A NaN/inf force keeps the contact
    state unchanged (no onset); an invalid position keeps the last approach
    speed estimate.
    """
    rate = p[CP_RATE]
    on = p[CP_ON]
    off = p[CP_OFF]
    for t in range(force.shape[0]):
        update_normal(nrm, t, s, CS_NORMAL)
        if finite3(pos, t):
            if si[CI_STARTED] != 0:
                scale = rate / (si[CI_GAP] + 1.0)
                vn = 0.0
                for c in range(3):
                    vn -= (pos[t, c] - s[CS_XPREV + c]) * scale * s[CS_NORMAL + c]
                if math.isfinite(vn):
                    s[CS_VN] = vn if vn > 0.0 else 0.0
            si[CI_STARTED] = 1
            si[CI_GAP] = 0
            for c in range(3):
                s[CS_XPREV + c] = pos[t, c]
        elif si[CI_STARTED] != 0:
            si[CI_GAP] += 1
        f = force[t, 0]
        pulse = 0.0
        if math.isfinite(f):
            if si[CI_IN] == 0:
                if f >= on:
                    si[CI_IN] = 1
                    s[CS_INCOMING] = s[CS_VN]
                    pulse = 1.0
            elif f < off:
                si[CI_IN] = 0
                s[CS_INCOMING] = 0.0
        in_contact[t, 0] = float(si[CI_IN])
        incoming[t, 0] = s[CS_INCOMING]
        onset[t, 0] = pulse
