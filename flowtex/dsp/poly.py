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

MAX_RADIUS = 1.0 - 1e-5
"""Largest root radius kept (AR poles and MA zeros). HaTT's MA zeros sit at |z| ~ 0.9999, 10x further in; at 1 - 1e-5
the line spectral frequencies of an isolated root pair near z = -1 are still ~1e-5 rad apart, which
:func:`flowtex.dsp.lsf_roots.poly_to_lsf` resolves (the caller checks and pulls further in only if it does not)."""


def step_down(a: np.ndarray, order: int) -> np.ndarray:
    """Monic minimum-phase ``a`` (length p+1) reduced to ``order`` by the Levinson step-down recursion.

    A_{m-1}(z) = (A_m(z) - k_m z^-m A_m(1/z)) / (1 - k_m^2), k_m the last coefficient of A_m (Levinson 1947,
    Durbin 1960; Kay 1988 ch. 6): the order-``order`` predictor sharing A's first reflection coefficients.
    Raises ValueError if a reflection coefficient has |k| >= 1 (``a`` not minimum phase).
    """
    a = np.asarray(a, dtype=np.float64).copy()
    for m in range(a.shape[0] - 1, order, -1):
        k = a[m]
        if not abs(k) < 1.0:
            raise ValueError(f"polynomial is not minimum phase (reflection coefficient {k:.6g} at order {m})")
        a = (a[:m] - k * a[m:0:-1]) / (1.0 - k * k)
    return a


def roots_inside(poly: np.ndarray, radius: float = 1.0) -> bool:
    """True if every root of the monic ``poly`` has magnitude < ``radius`` (Schur-Cohn step-down, O(p^2), no eigenvalues).

    The roots of P(z) scaled as p_k radius^-k are the roots of P divided by
    ``radius``; the step-down recursion (:func:`step_down`) of that polynomial has all
    |reflection coefficients| < 1 exactly when they are inside the unit circle.
    """
    poly = np.asarray(poly, dtype=np.float64)
    a = poly / poly[0] / (radius ** np.arange(poly.shape[0]))
    try:
        step_down(a, 0)
    except ValueError:
        return False
    return True


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


def power_spectrum(ar: np.ndarray, ma: np.ndarray, w: np.ndarray) -> np.ndarray:
    """|C(e^jw) / A(e^jw)|^2 at ``w`` (rad/sample), from the coefficients (Horner).

    ``ar`` and ``ma`` may also be stacks (m, p + 1) and (m, q + 1): then one row per model, shape (m, len(w)),
    each row what the model alone gives. The physical PSD is :func:`flowtex.dsp.arma.arma_psd` (variance, gain
    and rate applied).
    """
    z = np.exp(-1j * np.asarray(w, dtype=np.float64))
    num = np.polynomial.polynomial.polyval(z, np.asarray(ma, dtype=np.float64).T)
    den = np.polynomial.polynomial.polyval(z, np.asarray(ar, dtype=np.float64).T)
    return np.abs(num) ** 2 / np.abs(den) ** 2


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
