"""WHaT compliance estimation (Guruswamy thesis sec. 5.2, Lang & Andrews): k_c from how RMS vibration grows with normal force.

One streaming kernel serves both the offline fit (``flowtex fit compliance``) and the
``compliance_estimator`` node, so the two agree exactly at the end of a recording:

1. each acceleration axis is high-passed (1st-order Butterworth, ``highpass_hz``,
   default 10 Hz) to remove gravity and drift; the squared magnitude is low-passed
   with the same 1st-order Butterworth as the force (2.5 Hz), so RMS and force share
   one lag: ``a_rms = sqrt(lowpass(|a_hp|^2))`` (m/s^2), ``f_lp = lowpass(f)`` (N);
2. a contact session runs while the contact state is on and the raw force exceeds
   ``force_threshold`` (0.1 N); its first ``settle_s`` (0.2 s, three time constants of
   the 2.5 Hz filters) are skipped because the filtered force and RMS are still rising
   from zero at different rates (sqrt of a filtered square is not a filtered value).
   A tick is binned when, in addition, ``f_lp`` exceeds the force threshold and
   ``a_rms`` exceeds ``vibration_threshold`` (0.02 m/s^2); sessions are joined simply
   by accumulating only their ticks;
3. ``[force_lo, force_hi]`` is split into 24 equal bins; each bin accumulates count,
   sum f, sum a_rms and sum a_rms^2 (ticks outside the range are left out);
4. weighted least squares of bin mean a_rms on bin mean force, w_j = 1/sigma_j
   (sigma_j: the bin's sample standard deviation of a_rms); ``k_c = k_g * slope``.

``k_g`` (N per m/s^2, i.e. kg) is Guruswamy thesis eq. 6's normalisation. ``sigma`` is the fit's
weighted residual standard deviation (m/s^2). The estimate is *not valid*
(an answer, not an error) when: fewer than MIN_BINS (6) bins hold ``min_per_bin`` ticks
(``REASON_TOO_FEW``); every bin's mean RMS vibration is below ``smooth_floor``
(0.1 m/s^2: a smooth surface, ``REASON_SMOOTH``); the slope is not positive
(``REASON_NO_GROWTH``); the weighted R^2 is below ``r2_min`` (0.8: foams,
``REASON_POOR_FIT``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .contact import CONTACT_ON_N
from .layout import Field, Layout

N_BINS = 24
"""Bins along force (Guruswamy thesis sec. 5.2.2)."""
MIN_BINS = 6
"""A fit needs this many filled bins (a quarter of the force range): fewer give wild early slopes when streaming."""
BIN = Layout("float", [Field("count"), Field("sum_f", 1, "N"), Field("sum_a", 1, "sum of a_rms"),
                       Field("sum_a2", 1, "sum of a_rms^2")])
"""One force bin's sums."""
BIN_FIELDS = BIN.size()
B_COUNT, B_SUM_F, B_SUM_A, B_SUM_A2 = (BIN.const(f.name) for f in BIN.fields)
HP_AXIS = Layout("float", [Field("x_prev", 1, "last input, m/s^2"), Field("y", 1, "last output, m/s^2")])
"""One acceleration axis's first-order high-pass state; the state holds 3 of these."""
HP_FIELDS = HP_AXIS.size()
H_X, H_Y = HP_AXIS.const("x_prev"), HP_AXIS.const("y")
FIT = Layout("float", [Field("k_c"), Field("sigma", 1, "m/s^2"), Field("valid", 1, "0/1"),
                       Field("reason", 1, "REASON_* code"), Field("bins", 1, "bins used")])
"""What :func:`compliance_fit` writes."""
FIT_LEN = FIT.size()
F_KC, F_SIGMA, F_VALID, F_REASON, F_BINS = (FIT.const(f.name) for f in FIT.fields)
PARAMS = Layout("float", [
    Field("fb0", 1, "force low-pass b0"), Field("fb1", 1, "force low-pass b1"), Field("fa1", 1, "force low-pass a1"),
    Field("hb0", 1, "acceleration high-pass b0 (b1 = -b0)"), Field("ha1", 1, "acceleration high-pass a1"),
    Field("fthr", 1, "force threshold, N"), Field("athr", 1, "vibration threshold, m/s^2"),
    Field("flo", 1, "lowest binned force, N"), Field("fhi", 1, "highest binned force, N"),
    Field("kg", 1, "k_g, N per m/s^2"), Field("floor", 1, "smooth floor, m/s^2"), Field("r2", 1, "least weighted R^2"),
    Field("minbin", 1, "ticks a bin needs"), Field("settle", 1, "skipped ticks of each session"),
])
"""The kernel's parameters (:func:`compliance_params`)."""
STATE = Layout("float", [
    Field("fx", 1, "force filter x_prev"), Field("fy", 1, "force filter y"),
    Field("mx", 1, "mean-square filter x_prev"), Field("my", 1, "mean-square filter y"),
    Field("rms", 1, "last a_rms"), Field("flp", 1, "last low-passed force"), Field("started", 1, "1.0 once a tick was seen"),
    Field("session", 1, "ticks since the session began"), Field("hp", 3 * HP_FIELDS, "3 HP_AXIS records"),
    Field("bins", N_BINS * BIN_FIELDS, "N_BINS BIN records"),
])
"""The kernel's float state."""
P_FB0, P_FB1, P_FA1, P_HB0, P_HA1, P_FTHR, P_ATHR, P_FLO, P_FHI, P_KG, P_FLOOR, P_R2, P_MINBIN, P_SETTLE = (
    PARAMS.const(f.name) for f in PARAMS.fields)
P_LEN = PARAMS.size()
S_FX, S_FY, S_MX, S_MY, S_RMS, S_FLP, S_STARTED, S_SESSION, S_HP, S_BINS = (STATE.const(f.name) for f in STATE.fields)
STATE_LEN = STATE.size()

REASON_OK, REASON_TOO_FEW, REASON_SMOOTH, REASON_NO_GROWTH, REASON_POOR_FIT = range(5)
REASONS = {
    REASON_OK: "ok",
    REASON_TOO_FEW: "too few contact samples: fewer than 6 of the 24 force bins are filled (stroke longer, over a wider force range)",
    REASON_SMOOTH: "surface too smooth: RMS vibration stays below the floor whatever the force",
    REASON_NO_GROWTH: "vibration does not grow with force (slope <= 0)",
    REASON_POOR_FIT: "poor line fit (weighted R^2 below the minimum; typical of foams)",
}

KC_ER_RANGE_MPA = (0.063, 14.7)
"""Reduced Young's moduli over which Guruswamy thesis fitted the k_c <-> E_r relation (Table 2, Foam B .. Cork)."""


def kc_from_er(er_mpa: float | np.ndarray, extrapolate: bool = False) -> float | np.ndarray:
    """Guruswamy's empirical k_c = 0.0217 + 0.0883 exp(0.149 E_r[MPa]); valid for E_r in KC_ER_RANGE_MPA."""
    er = np.asarray(er_mpa, dtype=np.float64)
    lo, hi = KC_ER_RANGE_MPA
    if not extrapolate and (np.any(er < lo) or np.any(er > hi)):
        raise ValueError(f"E_r must be within {lo:g}..{hi:g} MPa, the range Guruswamy thesis fitted (pass extrapolate=True to go beyond)")
    out = 0.0217 + 0.0883 * np.exp(0.149 * er)
    return float(out) if out.ndim == 0 else out


def er_from_kc(kc: float | np.ndarray, extrapolate: bool = False) -> float | np.ndarray:
    """Inverse of :func:`kc_from_er`: E_r in MPa; valid for k_c in kc_from_er(KC_ER_RANGE_MPA) = 0.111 .. 0.811."""
    kc = np.asarray(kc, dtype=np.float64)
    lo, hi = (kc_from_er(v) for v in KC_ER_RANGE_MPA)
    if not extrapolate and (np.any(kc < lo) or np.any(kc > hi)):
        raise ValueError(f"k_c must be within {lo:.4f}..{hi:.4f}, the range of Guruswamy's fit (pass extrapolate=True to go beyond)")
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.log((kc - 0.0217) / 0.0883) / 0.149
    return float(out) if out.ndim == 0 else out


def compliance_params(rate_hz: float, force_lo: float, force_hi: float, k_g: float = 1.0, force_cutoff_hz: float = 2.5,
                      highpass_hz: float = 10.0, force_threshold: float = CONTACT_ON_N, vibration_threshold: float = 0.02,
                      smooth_floor: float = 0.1, r2_min: float = 0.8, min_per_bin: int = 10, settle_s: float = 0.2) -> np.ndarray:
    """The kernel's parameter vector (units: Hz, N, N per m/s^2, m/s^2, s)."""
    import scipy.signal

    if not force_hi > force_lo:
        raise ValueError(f"force range must be increasing, got [{force_lo:g}, {force_hi:g}] N")
    for name, hz in (("force cutoff", force_cutoff_hz), ("high-pass cutoff", highpass_hz)):
        if not 0 < hz < rate_hz / 2:
            raise ValueError(f"{name} {hz:g} Hz must be between 0 and Nyquist ({rate_hz / 2:g} Hz)")
    fb, fa = scipy.signal.butter(1, force_cutoff_hz, fs=rate_hz)
    hb, ha = scipy.signal.butter(1, highpass_hz, btype="highpass", fs=rate_hz)
    return PARAMS.pack({"fb0": fb[0], "fb1": fb[1], "fa1": fa[1], "hb0": hb[0], "ha1": ha[1],  # high-pass: b = (hb0, -hb0)
                        "fthr": force_threshold, "athr": vibration_threshold, "flo": force_lo, "fhi": force_hi, "kg": k_g,
                        "floor": smooth_floor, "r2": r2_min, "minbin": min_per_bin, "settle": round(settle_s * rate_hz)})


@njit(cache=True)
def compliance_step(p, s, force, accel, in_contact) -> bool:
    """Advance one tick (force N, accel row of 1..3 axes m/s^2, contact 0/1); True if the tick was binned."""
    fb0, fb1, fa1 = p[P_FB0], p[P_FB1], p[P_FA1]
    if s[S_STARTED] == 0.0:  # start the high-passes at rest on the first sample (no gravity step)
        s[S_STARTED] = 1.0
        for k in range(accel.shape[0]):
            s[S_HP + HP_FIELDS * k + H_X] = accel[k]
    f_lp = fb0 * force + fb1 * s[S_FX] - fa1 * s[S_FY]
    s[S_FX] = force
    s[S_FY] = f_lp
    hb0, ha1 = p[P_HB0], p[P_HA1]
    a2 = 0.0
    for k in range(accel.shape[0]):
        o = S_HP + HP_FIELDS * k
        y = hb0 * (accel[k] - s[o + H_X]) - ha1 * s[o + H_Y]
        s[o + H_X] = accel[k]
        s[o + H_Y] = y
        a2 += y * y
    ms = fb0 * a2 + fb1 * s[S_MX] - fa1 * s[S_MY]
    s[S_MX] = a2
    s[S_MY] = ms
    rms = math.sqrt(ms) if ms > 0.0 else 0.0
    s[S_RMS] = rms
    s[S_FLP] = f_lp
    if in_contact < 0.5 or force <= p[P_FTHR]:
        s[S_SESSION] = 0.0
        return False
    s[S_SESSION] += 1.0
    if s[S_SESSION] <= p[P_SETTLE] or f_lp <= p[P_FTHR] or rms <= p[P_ATHR]:
        return False
    lo, hi = p[P_FLO], p[P_FHI]
    if f_lp < lo or f_lp > hi:
        return False
    j = int((f_lp - lo) / (hi - lo) * N_BINS)
    if j >= N_BINS:
        j = N_BINS - 1
    o = S_BINS + BIN_FIELDS * j
    s[o + B_COUNT] += 1.0
    s[o + B_SUM_F] += f_lp
    s[o + B_SUM_A] += rms
    s[o + B_SUM_A2] += rms * rms
    return True


@njit(cache=True, inline="always")
def _bin_point(s, j, min_n):
    """Bin j's WLS point: (weight 1/sigma_j, mean force N, mean RMS vibration m/s^2); weight 0 for a bin left out."""
    o = S_BINS + BIN_FIELDS * j
    n = s[o + B_COUNT]
    if n < min_n:
        return 0.0, 0.0, 0.0
    mean_a = s[o + B_SUM_A] / n
    var = (s[o + B_SUM_A2] - n * mean_a * mean_a) / (n - 1.0)
    if var <= 0.0:
        return 0.0, 0.0, 0.0
    return 1.0 / math.sqrt(var), s[o + B_SUM_F] / n, mean_a


@njit(cache=True)
def compliance_fit(p, s, out) -> None:
    """WLS fit over the bins: out = (k_c, sigma m/s^2, valid 0/1, reason code, bins used); k_c, sigma NaN if no fit."""
    min_n = max(p[P_MINBIN], 2.0)
    sw = swf = swa = 0.0
    used = 0
    max_mean = 0.0
    for j in range(N_BINS):
        w, mean_f, mean_a = _bin_point(s, j, min_n)
        if w == 0.0:
            continue
        sw += w
        swf += w * mean_f
        swa += w * mean_a
        used += 1
        if mean_a > max_mean:
            max_mean = mean_a
    out[F_KC] = math.nan
    out[F_SIGMA] = math.nan
    out[F_VALID] = 0.0
    out[F_BINS] = used
    if used < MIN_BINS:
        out[F_REASON] = REASON_TOO_FEW
        return
    fbar = swf / sw
    abar = swa / sw
    sff = sfa = saa = 0.0
    for j in range(N_BINS):
        w, mean_f, mean_a = _bin_point(s, j, min_n)
        if w == 0.0:
            continue
        df = mean_f - fbar
        da = mean_a - abar
        sff += w * df * df
        sfa += w * df * da
        saa += w * da * da
    slope = sfa / sff if sff > 0.0 else 0.0
    ssr = saa - slope * sfa
    if ssr < 0.0:
        ssr = 0.0
    out[F_KC] = p[P_KG] * slope
    out[F_SIGMA] = math.sqrt(ssr / sw * used / (used - 2.0))
    r2 = 1.0 - ssr / saa if saa > 0.0 else 0.0
    if max_mean < p[P_FLOOR]:
        out[F_REASON] = REASON_SMOOTH
    elif slope <= 0.0:
        out[F_REASON] = REASON_NO_GROWTH
    elif r2 < p[P_R2]:
        out[F_REASON] = REASON_POOR_FIT
    else:
        out[F_REASON] = REASON_OK
        out[F_VALID] = 1.0


@njit(cache=True)
def compliance_run(p, s, force, accel, in_contact, out) -> None:
    """Feed a whole recording (force (n,), accel (n, axes), contact (n,)) through the kernel, then fit into ``out`` (5,)."""
    for t in range(force.shape[0]):
        compliance_step(p, s, force[t], accel[t], in_contact[t])
    compliance_fit(p, s, out)


def new_state() -> np.ndarray:
    """Zeroed kernel state (filters at rest, empty bins)."""
    return np.zeros(STATE_LEN)


@njit(cache=True)
def compliance_trace(p, s, force, accel, in_contact, f_lp, binned) -> None:
    """Like :func:`compliance_run` without the fit, recording each tick's low-passed force (N) and whether it was binned."""
    for t in range(force.shape[0]):
        binned[t] = compliance_step(p, s, force[t], accel[t], in_contact[t])
        f_lp[t] = s[S_FLP]
