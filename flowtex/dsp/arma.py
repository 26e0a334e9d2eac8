"""ARMA synthesis that stays bounded under per-tick model changes: a normalized lattice-ladder.

The model (HaTT's, per tick): y_n = -sum_i a_i y_{n-i} + g (e_n + sum_j c_j e_{n-j}),
e_n ~ N(0, var), i.e. y = g C(z) / A(z) e with A = 1 + a1 z^-1 + ... + ap z^-p
and C = 1 + c1 z^-1 + ... + cq z^-q (units of y: m/s^2 for HaTT models).

Why not the direct form: each model is stable, but switching between two of
them every tick is a time-varying system whose state matrix product can have
spectral radius > 1; a direct-form filter then grows without bound (1e235 on
a real surface). The Gray-Markel *normalized* lattice realises 1/A(z) as a
cascade of plane rotations::

    [f_{m-1}]   [ c_m  -k_m ] [ f_m              ]        c_m = sqrt(1 - k_m^2)
    [g_m    ] = [ k_m   c_m ] [ g_{m-1}[n - 1]   ]

(k_m: reflection coefficients of A, from the step-down recursion). Each tick
maps (input, old state) to (new state, leaked g_L) by an orthogonal matrix
*whatever the k's are*, so the state energy can never grow by more than the
input energy, for any sequence of valid models (|k_m| < 1). The MA part is a
ladder: y = sum_m v_m g_m, with v solving g C(z) = sum_m v_m (prod_{i>m} c_i)
B_m(z), B_m(z) = z^-m A_m(z^-1) (backward predictor polynomials). For a
fixed model the transfer function is exactly g C(z) / A(z).

Rules implemented by :func:`arma_lattice_block` (all documented in the node):

* the new model is used on the tick it arrives (no smoothing, no lag); the
  filter state is kept across model changes;
* reflection and ladder coefficients are recomputed only when the incoming
  ar/ma/gain differ (by ``!=``) from the previous tick's;
* an invalid model -- any NaN/inf, a0 == 0, |k_m| > K_MAX = 1 - 1e-12 (not
  minimum phase, also numerically), non-finite ladder weights, non-finite gain, negative or
  non-finite variance -- is not used: the last valid model (all four parts)
  is held. Before any valid model arrives the output is 0;
* state values below 1e-200 in magnitude are flushed to 0 every tick, so a
  zero-variance (silent) model never leaves subnormal numbers behind (they
  make every later multiply ~100x slower on x86);
* the excitation is one standard normal per tick from :mod:`flowtex.dsp.rng`
  (drawn whatever the variance, so the noise sequence does not depend on
  the model), scaled by sqrt(var).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .fastmath import FASTMATH
from .layout import Field, Layout
from .rng import STATE_FLOATS, STATE_INTS, next_normal

_FAST = FASTMATH
"""numba fast-math flags: FMA contraction only, unless FLOWTEX_CONTRACT=0 (flowtex.dsp.fastmath)."""

FLUSH_BELOW = 1e-200
"""State values smaller than this in magnitude are set to 0 (subnormal guard)."""

K_MAX = 1.0 - 1e-12
"""Largest accepted |reflection coefficient|. A pole within ~1e-12 of the unit circle (a resonance with
Q ~ 1e12) cannot be told apart from an unstable one after float64 rounding (a root exactly at z = -1
comes out of the step-down as |k| = 1 - 2e-16), so such models are refused like |k| >= 1."""

STATE = Layout("float", [
    Field("rng", STATE_FLOATS, "cached normal of the random generator (flowtex.dsp.rng)"),
    Field("k", "L", "active set: reflection coefficients k_1..k_L"),
    Field("c", "L", "active set: sqrt(1 - k_m^2)"),
    Field("v", "L + 1", "active set: ladder weights v_0..v_L"),
    Field("var", 1, "active excitation variance"),
    Field("g", "L", "lattice state g_0..g_{L-1} (previous tick)"),
    Field("la", "p + 1", "last seen ar"),
    Field("lm", "q + 1", "last seen ma"),
    Field("lg", 1, "last seen gain"),
    Field("tk", "L", "second coefficient set: k"),
    Field("tc", "L", "second coefficient set: c"),
    Field("tv", "L + 1", "second coefficient set: v"),
    Field("wa", "L + 1", "work: step-down polynomial"),
    Field("wr", "L + 1", "work: ladder remainder"),
], sizes=("p", "q"), derived={"L": "max(p, q)"})
"""The synthesizer's float state for AR order p and MA order q. Two coefficient sets (k, c, v) live at
``k`` and ``tk``: one is active (int field ``which``), the other is the trial set a new model is computed
into, so making a new model active is a flip of ``which``, not a copy."""

ISTATE = Layout("int", [
    Field("rng", STATE_INTS, "random generator words (flowtex.dsp.rng)"),
    Field("active", 1, "1 once a valid model is active"),
    Field("trial_ok", 1, "1 if the last seen ar/ma/gain were valid (trial coefficients usable)"),
    Field("trial_active", 1, "1 once those trial coefficients have been made active"),
    Field("which", 1, "which coefficient set is active (0: the one at k, 1: the one at tk)"),
])
"""The synthesizer's int state (fixed length)."""

ISTATE_INTS = ISTATE.size()
SI_ACTIVE = ISTATE.const("active")
SI_TRIAL_OK = ISTATE.const("trial_ok")
SI_TRIAL_ACTIVE = ISTATE.const("trial_active")
SI_WHICH = ISTATE.const("which")

def lattice_order(p: int, q: int) -> int:
    """Number of lattice sections L = max(p, q) (sections above p have k = 0)."""
    return max(p, q)


def state_size(p: int, q: int) -> int:
    """Length of the float state array for AR order p and MA order q (see :func:`_offsets`)."""
    return STATE.size(p=p, q=q)


_offsets = STATE.kernel_offsets()
"""(L, o_rng, o_k, o_c, ...) for orders (p, q): the offsets of :data:`STATE`, generated from it."""


@njit(cache=True, fastmath=_FAST)
def lattice_ladder_coefficients(ar, ma, gain, k, c, v, wa, wr) -> bool:
    """Reflection coefficients ``k``, ``c = sqrt(1 - k^2)`` and ladder weights ``v`` of g C(z) / A(z).

    ``ar`` (p+1), ``ma`` (q+1); ``k``, ``c`` have length >= L = max(p, q),
    ``v``, ``wa``, ``wr`` length >= L+1 (``wa``, ``wr`` are scratch). Section
    m (1-based) uses ``k[m-1]``. Returns False (outputs then meaningless) if
    the model is not usable: non-finite input, a0 == 0, |k_m| >= 1 or
    non-finite weights. No allocation.

    Cost: the step-down is a chain of L dependent stages, each waiting for one
    reciprocal 1 / (1 - k_m^2) (every coefficient of the stage is then
    multiplied by it, not divided). The ladder weights v_m = lambda_m / prod_{i>m} c_i
    use the running reciprocal of that product, 1 / c_m = c_m / (1 - k_m^2),
    so they need no division at all; and a monic A (a0 == 1, always the case
    for texture_lookup's output) is used as is instead of being divided by a0.
    """
    p = ar.shape[0] - 1
    q = ma.shape[0] - 1
    L = max(p, q)
    a0 = ar[0]
    if not (math.isfinite(a0) and a0 != 0.0 and math.isfinite(gain)):
        return False
    if a0 == 1.0:
        for i in range(L + 1):
            wa[i] = ar[i] if i <= p else 0.0
            wr[i] = gain * ma[i] if i <= q else 0.0
    else:
        for i in range(L + 1):
            wa[i] = ar[i] / a0 if i <= p else 0.0
            wr[i] = gain * ma[i] / a0 if i <= q else 0.0
    for i in range(L + 1):
        if not (math.isfinite(wa[i]) and math.isfinite(wr[i])):
            return False
    rprod = 1.0  # 1 / prod_{i > m} c_i
    km = wa[L]
    for m in range(L, 0, -1):
        lam = wr[m]
        v[m] = lam * rprod
        if not (abs(km) <= K_MAX):
            return False
        den = 1.0 - km * km
        inv = 1.0 / den
        cm = math.sqrt(den)
        k[m - 1] = km
        c[m - 1] = cm
        # The next reflection coefficient (A_{m-1}[m-1], the same expression the pair loop stores) goes
        # straight into a register: the stage-to-stage dependency chain then skips a store and a reload.
        if m >= 3:
            kn = (wa[m - 1] - km * wa[1]) * inv
        elif m == 2:
            kn = wa[1] * (1.0 - km) * inv
        else:
            kn = 0.0
        wr[0] -= lam * km
        wr[m] = 0.0
        for i in range(1, (m + 1) // 2):
            j = m - i
            ai = wa[i]
            aj = wa[j]
            wr[i] -= lam * aj
            wr[j] -= lam * ai
            wa[i] = (ai - km * aj) * inv
            wa[j] = (aj - km * ai) * inv
        if m % 2 == 0:
            h = m // 2
            wr[h] -= lam * wa[h]
            wa[h] = wa[h] * (1.0 - km) * inv
        wa[m] = 0.0
        rprod *= cm * inv
        km = kn
    v[0] = wr[0] * rprod
    for m in range(L + 1):
        if not math.isfinite(v[m]):
            return False
    return True


@njit(cache=True)
def filter_power(ar: np.ndarray, ma: np.ndarray, gain: float, work: np.ndarray) -> float:
    """g^2 sum_n h_n^2 of g C(z) / A(z) (its output power for unit-variance white input); -1.0 if not usable.

    The one computation of an ARMA model's output power (:func:`arma_output_variance` and the texture lookup's
    power blending call it). The normalized lattice-ladder realisation's backward states are
    orthonormal for white unit-variance input, so the output power is exactly
    the sum of the squared ladder weights v_m. ``work`` (>= 5 L + 3 floats,
    L = max(p, q)) is scratch; nothing is allocated.
    """
    L = max(ar.shape[0], ma.shape[0]) - 1
    k = work[:L]
    c = work[L:2 * L]
    v = work[2 * L:3 * L + 1]
    wa = work[3 * L + 1:4 * L + 2]
    wr = work[4 * L + 2:5 * L + 3]
    if not lattice_ladder_coefficients(ar, ma, gain, k, c, v, wa, wr):
        return -1.0
    total = 0.0
    for m in range(L + 1):
        total += v[m] * v[m]
    return total


@njit(cache=True)
def arma_lattice_block(s, si, ar, ma, gain, variance, y) -> None:
    """Normalized lattice-ladder ARMA synthesis over a block of ticks.

    ``ar`` (n, p+1), ``ma`` (n, q+1), ``gain`` (n, 1), ``variance`` (n, 1):
    the model of each tick; ``y`` (n, 1) output. ``s`` (float64,
    :func:`state_size`) and ``si`` (int64, :data:`ISTATE_INTS`, RNG seeded)
    hold all state, so any split into blocks gives the same numbers.
    """
    n = y.shape[0]
    p = ar.shape[1] - 1
    q = ma.shape[1] - 1
    L, _, o_k, o_c, o_v, o_var, o_g, o_la, o_lm, o_lg, o_tk, o_tc, o_tv, o_wa, o_wr = _offsets(p, q)
    rng_f = s[0:1]
    for t in range(n):
        e = next_normal(si, rng_f)
        # --- model update (only when ar/ma/gain changed) ---
        g = gain[t, 0]
        changed = g != s[o_lg]
        if not changed:
            for i in range(p + 1):
                if ar[t, i] != s[o_la + i]:
                    changed = True
                    break
        if not changed:
            for i in range(q + 1):
                if ma[t, i] != s[o_lm + i]:
                    changed = True
                    break
        if changed:
            for i in range(p + 1):
                s[o_la + i] = ar[t, i]
            for i in range(q + 1):
                s[o_lm + i] = ma[t, i]
            s[o_lg] = g
            o_t = o_tk if si[SI_WHICH] == 0 else o_k  # the coefficient set that is not active
            ok = lattice_ladder_coefficients(
                ar[t], ma[t], g,
                s[o_t:o_t + L], s[o_t + L:o_t + 2 * L], s[o_t + 2 * L:o_t + 3 * L + 1], s[o_wa:o_wa + L + 1], s[o_wr:o_wr + L + 1],
            )
            si[SI_TRIAL_OK] = 1 if ok else 0
            si[SI_TRIAL_ACTIVE] = 0
        var = variance[t, 0]
        if si[SI_TRIAL_OK] == 1 and math.isfinite(var) and var >= 0.0:
            if si[SI_TRIAL_ACTIVE] == 0:  # trial coefficients not active yet: make them the active set (no copy)
                si[SI_WHICH] = 1 - si[SI_WHICH]
                si[SI_TRIAL_ACTIVE] = 1
            s[o_var] = var
            si[SI_ACTIVE] = 1
        if si[SI_ACTIVE] == 0:
            y[t, 0] = 0.0
            continue
        # --- one tick of the normalized lattice-ladder ---
        o_a = o_k if si[SI_WHICH] == 0 else o_tk
        y[t, 0] = lattice_step(s, o_a, o_a + L, o_a + 2 * L, o_g, L, math.sqrt(s[o_var]) * e)


@njit(cache=True, inline="always")
def lattice_step(s, o_k, o_c, o_v, o_g, L, x) -> float:
    """One tick of the normalized lattice-ladder with input ``x``; returns the output.

    Coefficients k, c (L each), v (L+1) and the state g_0..g_{L-1} live in
    ``s`` at the given offsets. Updates the state, flushing values below
    :data:`FLUSH_BELOW` to zero.
    """
    if L == 0:
        return s[o_v] * x
    # top section peeled off: its output g_L is not stored (no section above reads it), so the loop has no branch
    km = s[o_k + L - 1]
    cm = s[o_c + L - 1]
    gp = s[o_g + L - 1]
    acc = s[o_v + L] * (km * x + cm * gp)
    f = cm * x - km * gp
    for m in range(L - 1, 0, -1):
        km = s[o_k + m - 1]
        cm = s[o_c + m - 1]
        gp = s[o_g + m - 1]  # g_{m-1}[n-1]
        gm = km * f + cm * gp  # g_m[n]
        f = cm * f - km * gp  # f_{m-1}[n]
        acc += s[o_v + m] * gm
        s[o_g + m] = gm if abs(gm) >= FLUSH_BELOW else 0.0
    acc += s[o_v] * f
    s[o_g] = f if abs(f) >= FLUSH_BELOW else 0.0
    return acc


def new_state(p: int, q: int) -> tuple[np.ndarray, np.ndarray]:
    """Zeroed (float state, int state) arrays for orders p, q; seed the RNG with flowtex.dsp.rng.seed_rng."""
    s = np.zeros(state_size(p, q))
    si = ISTATE.zeros()
    # last seen ar/ma/gain start as NaN so that the first model always counts as "changed"
    slots = STATE.bind(p=p, q=q)
    s[slots["la"].start:slots["lg"].stop] = np.nan
    return s, si


# ----------------------------------------------------------------------------- Python helpers


def _check_model(ar: np.ndarray, ma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ar = np.asarray(ar, dtype=np.float64).ravel()
    ma = np.asarray(ma, dtype=np.float64).ravel()
    if ar.size == 0 or ma.size == 0 or ar[0] == 0.0:
        raise ValueError("ar and ma need at least one coefficient and ar[0] must be non-zero")
    return ar, ma


def arma_impulse_response(ar: np.ndarray, ma: np.ndarray, gain: float, n: int) -> np.ndarray:
    """First ``n`` samples of the impulse response of g C(z) / A(z) (scipy.signal.lfilter)."""
    from .poly import impulse_response

    ar, ma = _check_model(ar, ma)
    return impulse_response(gain * ma, ar, n)


def arma_output_variance(ar: np.ndarray, ma: np.ndarray, gain: float, variance: float) -> float:
    """Stationary output variance var * g^2 * sum_n h_n^2 of the model (h: impulse response of C/A).

    Exact (no truncation): :func:`filter_power`, the normalized lattice's sum of squared ladder weights. Units:
    those of y squared (m^2/s^4). Raises ValueError for a model that is not stable (a reflection coefficient
    beyond :data:`K_MAX`) or not finite.
    """
    ar, ma = _check_model(ar, ma)
    unit = filter_power(ar, ma, float(gain), np.empty(5 * (max(ar.size, ma.size) - 1) + 3))
    if not unit >= 0.0:
        raise ValueError("the model is not stable (a pole on or outside the unit circle) or not finite")
    return float(variance * unit)


def arma_psd(ar: np.ndarray, ma: np.ndarray, gain: float, variance: float, freqs_hz: np.ndarray, rate_hz: float,
             onesided: bool = True) -> np.ndarray:
    """Model power spectral density at ``freqs_hz``: var g^2 |C/A|^2 / fs, in (m/s^2)^2/Hz.

    ``onesided`` (default, matching scipy.signal.welch for real signals)
    doubles every frequency strictly between 0 and fs/2, so the PSD
    integrates over [0, fs/2] to the output variance.
    """
    ar, ma = _check_model(ar, ma)
    freqs_hz = np.asarray(freqs_hz, dtype=np.float64)
    from .poly import power_spectrum

    psd = variance * gain**2 * power_spectrum(ar, ma, 2.0 * np.pi * freqs_hz / rate_hz) / rate_hz
    if onesided:
        inner = (freqs_hz > 0) & (freqs_hz < rate_hz / 2)
        psd = np.where(inner, 2.0 * psd, psd)
    return psd


def arma_psd_rows(ar: np.ndarray, ma: np.ndarray, gain: np.ndarray, variance: np.ndarray, freqs_hz: np.ndarray,
                  rate_hz: float) -> np.ndarray:
    """One-sided PSDs of many models of one order pair, one row per model: row k is :func:`arma_psd` of model k.

    ``ar`` (m, p + 1), ``ma`` (m, q + 1), ``gain`` and ``variance`` (m,). The same operations as :func:`arma_psd`,
    element by element (:func:`flowtex.dsp.poly.power_spectrum` over the stack), so each row equals its
    :func:`arma_psd` bit for bit; one call for every model instead of one per model, which is what evaluating a
    set along a path costs (flowtex.fit.quality). Units: those of :func:`arma_psd`.
    """
    ar = np.asarray(ar, dtype=np.float64)
    ma = np.asarray(ma, dtype=np.float64)
    gain = np.asarray(gain, dtype=np.float64).reshape(-1)
    variance = np.asarray(variance, dtype=np.float64).reshape(-1)
    m = gain.shape[0]
    if ar.ndim != 2 or ma.ndim != 2 or ar.shape[0] != m or ma.shape[0] != m or variance.shape[0] != m:
        raise ValueError(f"arma_psd_rows: ar (m, p+1), ma (m, q+1), gain (m,), variance (m,); got {ar.shape}, "
                         f"{ma.shape}, {gain.shape}, {variance.shape}")
    if ar.shape[1] == 0 or ma.shape[1] == 0 or np.any(ar[:, 0] == 0.0):
        raise ValueError("ar and ma need at least one coefficient and ar[:, 0] must be non-zero")
    freqs_hz = np.asarray(freqs_hz, dtype=np.float64)
    from .poly import power_spectrum

    inner = (freqs_hz > 0) & (freqs_hz < rate_hz / 2)
    psd = (variance * gain ** 2)[:, None] * power_spectrum(ar, ma, 2.0 * np.pi * freqs_hz / rate_hz) / rate_hz
    return np.where(inner, 2.0 * psd, psd)

