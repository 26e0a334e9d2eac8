"""Polynomial tools of ARMA models, in one place: stability, stabilisation, step-down, spectra, impulse responses.

Polynomials are in z^-1, P(z) = p0 + p1 z^-1 + ... + pn z^-n (HaTT's and
scipy.signal's convention), usually monic (p0 = 1). Every estimator
(:mod:`flowtex.dsp.arma_estimate`), the model resampler
(:mod:`flowtex.dsp.arma_resample`), Prony fits (:mod:`flowtex.dsp.prony`),
model-order reduction (:mod:`flowtex.dsp.order`) and the synthesis checks
(:mod:`flowtex.dsp.arma`) take these functions from here.

**Radius policy** (one rule for every model polynomial that is stored or
rendered): a root is kept at radius <= :data:`MAX_RADIUS` = 1 - 1e-5; a root
outside the unit circle is first reflected to 1 / conj(z) (same angle, and
|P(e^jw)| changes only by a constant factor), then any root beyond
MAX_RADIUS is pulled in to it (:func:`stabilize`). Callers that need a
tighter bound pass it explicitly and say why: Prony's pattern filters keep
poles within 0.9995 (a ring-down of at most ~2000 samples per e-fold,
:data:`flowtex.dsp.prony.STABLE_RADIUS`); :func:`flowtex.fit.arma.min_phase_for_lsf`
doubles the margin until the LSFs are valid; the resampler's start (roots
mapped by z -> z^ratio) is pulled to 0.999 (a start, the fit moves it) and the
anti-imaging FIR's zeros to 0.9999 (valid LSFs for a filter designed with
zeros on the circle).

Sources: the step-down (backward Levinson) recursion and the Schur-Cohn
stability test it gives: Levinson, N. (1947), "The Wiener RMS error criterion
in filter design and prediction", J. Math. Phys. 25; Durbin, J. (1960), "The
fitting of time-series models", Rev. Int. Stat. Inst. 28; Kay, S. M. (1988),
*Modern Spectral Estimation*, ch. 6 (step-down, reflection coefficients
|k| < 1 iff minimum phase).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .npmath import cabs, cmul

MAX_RADIUS = 1.0 - 1e-5
"""Largest root radius kept (AR poles and MA zeros). HaTT's MA zeros sit at |z| ~ 0.9999, 10x further in; at 1 - 1e-5
the line spectral frequencies of an isolated root pair near z = -1 are still ~1e-5 rad apart, which
:func:`flowtex.dsp.lsf_roots.poly_to_lsf` resolves (the caller checks and pulls further in only if it does not)."""


@njit(cache=True)
def _step_down_kernel(a: np.ndarray, order: int) -> tuple[np.ndarray, int]:
    """:func:`step_down`'s recursion, compiled (the same operations in the same order): (``a`` reduced to ``order``,
    -1), or (``a`` reduced as far as it went, the order m whose reflection coefficient a[m] has |k| >= 1)."""
    a = a.copy()
    for m in range(a.shape[0] - 1, order, -1):
        k = a[m]
        if not abs(k) < 1.0:
            return a, m
        d = 1.0 - k * k
        b = np.empty(m)
        for i in range(m):
            b[i] = (a[i] - k * a[m - i]) / d
        a = b
    return a, -1


def step_down(a: np.ndarray, order: int) -> np.ndarray:
    """Monic minimum-phase ``a`` (length p+1) reduced to ``order`` by the Levinson step-down recursion.

    A_{m-1}(z) = (A_m(z) - k_m z^-m A_m(1/z)) / (1 - k_m^2), k_m the last coefficient of A_m (Levinson 1947,
    Durbin 1960; Kay 1988 ch. 6): the order-``order`` predictor sharing A's first reflection coefficients.
    Raises ValueError if a reflection coefficient has |k| >= 1 (``a`` not minimum phase).
    """
    out, m = _step_down_kernel(np.asarray(a, dtype=np.float64), int(order))
    if m >= 0:
        raise ValueError(f"polynomial is not minimum phase (reflection coefficient {out[m]:.6g} at order {m})")
    return out


def roots_inside(poly: np.ndarray, radius: float = 1.0) -> bool:
    """True if every root of the monic ``poly`` has magnitude < ``radius`` (Schur-Cohn step-down, O(p^2), no eigenvalues).

    The roots of P(z) scaled as p_k radius^-k are the roots of P divided by
    ``radius``; the step-down recursion (:func:`step_down`) of that polynomial has all
    |reflection coefficients| < 1 exactly when they are inside the unit circle.
    """
    poly = np.asarray(poly, dtype=np.float64)
    return _step_down_kernel(poly / poly[0] / (radius ** np.arange(poly.shape[0])), 0)[1] < 0


def is_stable(a: np.ndarray, radius: float = MAX_RADIUS) -> bool:
    """True if every root of ``a`` lies within ``radius`` (a hair of rounding, 1e-12, allowed: roots placed exactly there)."""
    a = np.asarray(a, dtype=np.float64)
    return a.shape[0] <= 1 or roots_inside(a, radius + 1e-12)


def stabilize(poly: np.ndarray, radius: float = MAX_RADIUS) -> np.ndarray:
    """``poly`` with its roots outside the unit circle reflected in and roots beyond ``radius`` pulled to it (the radius policy).

    The leading coefficient is kept. A polynomial already inside ``radius`` is
    returned unchanged (same values). Reflection keeps each root's angle (the
    resonance frequency) and |P(e^jw)| up to a constant factor.
    """
    poly = np.asarray(poly, dtype=np.float64)
    if poly.shape[0] <= 1 or roots_inside(poly, radius):
        return poly.copy()
    roots = np.roots(poly)
    r = np.abs(roots)
    roots = np.where(r > 1.0, 1.0 / np.conj(np.where(r > 1.0, roots, 1.0)), roots)  # no 1/0 for a root at the origin
    r = np.abs(roots)
    roots = np.where(r > radius, roots * (radius / np.maximum(r, 1e-300)), roots)
    return np.real(np.poly(roots)) * poly[0]


@njit(cache=True, error_model="numpy")
def _power_spectrum_kernel(ar: np.ndarray, ma: np.ndarray, zr: np.ndarray, zi: np.ndarray, out: np.ndarray) -> None:
    """Row r of ``out`` = |C_r(z) / A_r(z)|^2 at z^-1 = ``zr`` + j ``zi`` (e^-jw).

    Horner's rule as numpy's ``polyval`` runs it, c0 <- c_k + c0 z^-1, each complex product and |.| rounded as numpy
    rounds them (:mod:`flowtex.dsp.npmath`), so every value is numpy's bit for bit; one pass per coefficient over all
    frequencies (the recursions of different frequencies are independent, so they pipeline) and no temporaries.
    A stack with one row (``ar`` or ``ma``) serves every row of the other. A value of A that rounds to 0 gives
    inf, as numpy's division does (numpy's error model: no exception).
    """
    m = out.shape[0]
    nw = zr.shape[0]
    p1 = ar.shape[1]
    q1 = ma.shape[1]
    re = np.empty(nw)
    im = np.empty(nw)
    num = np.empty(nw)
    for r in range(m):
        for poly, row, n1, into_num in ((ma, r if ma.shape[0] > 1 else 0, q1, True),
                                        (ar, r if ar.shape[0] > 1 else 0, p1, False)):
            for j in range(nw):
                re[j] = poly[row, n1 - 1]
                im[j] = 0.0
            for i in range(n1 - 2, -1, -1):
                c = poly[row, i]
                for j in range(nw):
                    pr, pi = cmul(re[j], im[j], zr[j], zi[j])
                    re[j] = c + pr
                    im[j] = 0.0 + pi
            if into_num:
                for j in range(nw):
                    h = cabs(re[j], im[j])
                    num[j] = h * h
            else:
                for j in range(nw):
                    h = cabs(re[j], im[j])
                    out[r, j] = num[j] / (h * h)


def power_spectrum(ar: np.ndarray, ma: np.ndarray, w: np.ndarray) -> np.ndarray:
    """|C(e^jw) / A(e^jw)|^2 at ``w`` (rad/sample), from the coefficients (Horner's rule, compiled).

    ``ar`` and ``ma`` may also be stacks (m, p + 1) and (m, q + 1): then one row per model, shape (m, len(w)),
    each row bit for bit what the model alone gives (a stack of one row serves every row of the other). The values
    are those of numpy's ``polyval`` over z = exp(-jw) and ``abs(num) ** 2 / abs(den) ** 2``, bit for bit
    (:mod:`flowtex.dsp.npmath`; benchmarks/bench_fit_math.py measures the kernel against that formulation), so the
    error of each polynomial's value is within Horner's bound, gamma_2n sum |p_k| at |z| = 1 (Higham 2002, eq. 5.3):
    relative to |P| only where |P| is not small against sum |p_k| (tests/dsp/test_poly.py checks it against an
    extended-precision evaluation near the unit circle). The physical PSD is :func:`flowtex.dsp.arma.arma_psd`
    (variance, gain and rate applied).
    """
    w = np.asarray(w, dtype=np.float64)
    ar = np.asarray(ar, dtype=np.float64)
    ma = np.asarray(ma, dtype=np.float64)
    a2 = np.ascontiguousarray(ar.reshape(1, -1) if ar.ndim == 1 else ar)
    c2 = np.ascontiguousarray(ma.reshape(1, -1) if ma.ndim == 1 else ma)
    if a2.ndim != 2 or c2.ndim != 2 or a2.shape[1] == 0 or c2.shape[1] == 0 or (
            a2.shape[0] != c2.shape[0] and 1 not in (a2.shape[0], c2.shape[0])):
        raise ValueError(f"power_spectrum: ar (p + 1,) or (m, p + 1) and ma (q + 1,) or (m, q + 1); got {ar.shape}, {ma.shape}")
    z = np.exp(-1j * w.reshape(-1))  # numpy's exp, as before: the kernel starts from the same z
    out = np.empty((max(a2.shape[0], c2.shape[0]), z.shape[0]))
    _power_spectrum_kernel(a2, c2, np.ascontiguousarray(z.real), np.ascontiguousarray(z.imag), out)
    if ar.ndim == 1 and ma.ndim == 1:
        return out[0].reshape(w.shape)
    return out.reshape(out.shape[:1] + w.shape)


def root_power_spectrum(poles: np.ndarray, zeros: np.ndarray, w: np.ndarray) -> np.ndarray:
    """|C/A(e^jw)|^2 of monic polynomials given by their roots (products of distances: no cancellation among large coefficients)."""
    e = np.exp(1j * np.asarray(w, dtype=np.float64))[:, None]
    num = np.prod(np.abs(1.0 - zeros[None, :] / e) ** 2, axis=1) if zeros.shape[0] else np.ones(e.shape[0])
    den = np.prod(np.abs(1.0 - poles[None, :] / e) ** 2, axis=1) if poles.shape[0] else np.ones(e.shape[0])
    return num / den


def impulse_response(b: np.ndarray, a: np.ndarray, n: int) -> np.ndarray:
    """First ``n`` samples of the impulse response of B(z) / A(z) (scipy.signal.lfilter)."""
    import scipy.signal

    x = np.zeros(n)
    if n:
        x[0] = 1.0
    return scipy.signal.lfilter(np.asarray(b, dtype=np.float64), np.asarray(a, dtype=np.float64), x)
