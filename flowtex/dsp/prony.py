"""IIR filters from impulse responses: least-squares Prony, guarded Steiglitz-McBride, order selection (Guruswamy thesis ch. 4).

A filter is ``H(z) = (b0 + b1 z^-1 + ... + bq z^-q) / (1 + a1 z^-1 + ... + ap z^-p)``;
``b`` has q + 1 and ``a`` p + 1 coefficients with ``a[0] == 1``. The units of ``b``
are those of the impulse response (``a`` is dimensionless).

* :func:`prony` -- Prony's method in the least-squares form (Parks & Burrus):
  the denominator solves the linear prediction equations
  ``h[n] + sum_k a_k h[n-k] = 0`` for n > q, the numerator then makes the first
  q + 1 samples exact. Exact (to rounding) on a noise-free response of a filter of
  the same or lower orders.
* :func:`steiglitz_mcbride` -- iterative prefiltered least squares, much less
  biased by noise than Prony but not guaranteed to converge or to stay stable.
  Guarded here: an unstable iterate has its poles reflected into the unit circle,
  the numerator is refitted, and the best stable iterate by fit error is kept; if
  none beats the (stabilised) Prony start, that start is returned.
* :func:`fit_iir` -- either method over a set of orders, keeping the least fit error.

Fit error is the SAD of Guruswamy thesis Table 1: the mean absolute difference between the
target and the filter's impulse response, in the target's units.
scipy is imported inside functions (graph loading should not pay for it).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from . import poly as _poly
from .poly import impulse_response  # noqa: F401  (re-exported)

Solver = Callable[[np.ndarray, np.ndarray], np.ndarray]
STABLE_RADIUS = 0.9995
"""Poles are kept at or inside this radius (a ring-down of ~2000 samples per e-fold at most)."""


def lstsq_numpy(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Minimum-norm least-squares solution of ``A x ~= y`` (numpy's SVD-based LAPACK gelsd)."""
    return np.linalg.lstsq(A, y, rcond=None)[0]


def sad(h: np.ndarray, b: np.ndarray, a: np.ndarray) -> float:
    """Mean absolute difference between ``h`` and the impulse response of b / a (Guruswamy thesis Table 1's SAD, units of h)."""
    h = np.asarray(h, dtype=np.float64)
    return float(np.mean(np.abs(h - impulse_response(b, a, h.size)))) if h.size else 0.0


def prony_equations(h: np.ndarray, p: int, q: int) -> tuple[np.ndarray, np.ndarray]:
    """The linear prediction equations of Prony's denominator: rows n = q+1 .. N-1 of ``A a' = -h[n]``.

    ``A[n - q - 1, k - 1] = h[n - k]`` (zero for n - k < 0); the unknowns are a_1 .. a_p.
    """
    h = np.asarray(h, dtype=np.float64)
    n = h.size
    rows = np.arange(q + 1, n)
    lags = rows[:, None] - np.arange(1, p + 1)[None, :]
    A = np.where(lags >= 0, h[np.clip(lags, 0, None)], 0.0)
    return A, -h[rows]


def _check(h: np.ndarray, p: int, q: int) -> np.ndarray:
    h = np.asarray(h, dtype=np.float64).ravel()
    if p < 0 or q < 0:
        raise ValueError(f"orders must be >= 0, got p={p}, q={q}")
    if h.size < p + q + 2:
        raise ValueError(f"need at least p + q + 2 = {p + q + 2} samples for orders ({p}, {q}), got {h.size}")
    if not np.all(np.isfinite(h)):
        raise ValueError("the impulse response contains NaN or infinite samples")
    return h


def prony(h: np.ndarray, p: int, q: int, solver: Solver = lstsq_numpy) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares Prony fit of orders (p, q) to the impulse response ``h``; may be unstable (see :func:`stabilize`)."""
    h = _check(h, p, q)
    a = np.ones(p + 1)
    if p:
        A, y = prony_equations(h, p, q)
        a[1:] = solver(A, y)
    b = np.convolve(a, h)[: q + 1]
    return b, a


def stabilize(a: np.ndarray, radius: float = STABLE_RADIUS) -> np.ndarray:
    """Denominator stabilised by :func:`flowtex.dsp.poly.stabilize` at Prony's radius (the numerator should be refitted)."""
    return _poly.stabilize(a, radius)


def is_stable(a: np.ndarray, radius: float = STABLE_RADIUS) -> bool:
    """True if every root of the denominator ``a`` lies within ``radius`` (:func:`flowtex.dsp.poly.is_stable`)."""
    return _poly.is_stable(np.asarray(a, dtype=np.float64), radius)


def refit_numerator(h: np.ndarray, a: np.ndarray, q: int, solver: Solver = lstsq_numpy) -> np.ndarray:
    """Least-squares numerator for a fixed denominator: h ~= sum_k b_k g[n-k], g the impulse response of 1/a."""
    n = h.size
    g = impulse_response(np.array([1.0]), a, n)
    G = np.zeros((n, q + 1))
    for k in range(q + 1):
        G[k:, k] = g[: n - k]
    return solver(G, h)


def steiglitz_mcbride(h: np.ndarray, p: int, q: int, iterations: int = 6, solver: Solver = lstsq_numpy,
                      radius: float = STABLE_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """Guarded Steiglitz-McBride fit of orders (p, q); the result is always stable (all poles within ``radius`` < 1).

    Starts from Prony (stabilised, numerator refitted). Each iteration prefilters
    the target and the unit impulse by the previous 1/a and solves
    ``h_f[n] + sum a_k h_f[n-k] - sum b_k d_f[n-k] = 0`` in least squares. Unstable
    iterates are stabilised and their numerator refitted; the iterate with the
    least SAD is returned (the start if none is better).
    """
    import scipy.signal

    h = _check(h, p, q)
    n = h.size
    b, a = prony(h, p, q, solver)
    if not is_stable(a, radius):
        a = stabilize(a, radius)
        b = refit_numerator(h, a, q, solver)
    best = (sad(h, b, a), b, a)
    if p == 0:
        return b, a
    delta = np.zeros(n)
    delta[0] = 1.0
    for _ in range(iterations):
        hf = scipy.signal.lfilter([1.0], a, h)
        df = scipy.signal.lfilter([1.0], a, delta)
        cols = []
        for k in range(1, p + 1):
            cols.append(np.concatenate([np.zeros(k), -hf[: n - k]]))
        for k in range(q + 1):
            cols.append(np.concatenate([np.zeros(k), df[: n - k]]))
        theta = solver(np.column_stack(cols), hf)
        a_new = np.concatenate([[1.0], theta[:p]])
        b_new = theta[p:]
        if not np.all(np.isfinite(theta)):
            break
        if not is_stable(a_new, radius):
            a_new = stabilize(a_new, radius)
            b_new = refit_numerator(h, a_new, q, solver)
        err = sad(h, b_new, a_new)
        if err < best[0]:
            best = (err, b_new, a_new)
        if np.max(np.abs(a_new - a)) < 1e-12:
            break
        a = a_new
    return best[1], best[2]


@dataclass(frozen=True)
class IIRFit:
    """A fitted filter, its orders and its fit error (mean |h - impulse response|, units of h)."""

    b: np.ndarray
    a: np.ndarray
    p: int
    q: int
    sad: float


def bic(h: np.ndarray, b: np.ndarray, a: np.ndarray) -> float:
    """Bayesian information criterion of b / a as a model of ``h``: n ln(RSS / n) + (p + q + 1) ln n (Schwarz 1978).

    RSS is the sum of squared differences between ``h`` and the impulse
    response; p + q + 1 counts the free coefficients (a[0] = 1 is fixed). Lower
    is better: an extra coefficient must cut the RSS by a factor n^(1/n) to pay
    for itself, so the simplest order that explains the waveform wins.
    """
    h = np.asarray(h, dtype=np.float64)
    n = h.size
    rss = float(np.sum((h - impulse_response(b, a, n)) ** 2))
    scale = float(np.sum(h * h)) or 1.0
    return n * np.log(max(rss, 1e-30 * scale) / n) + (len(b) + len(a) - 1) * np.log(n)


def fit_iir(h: np.ndarray, orders: Iterable[int | tuple[int, int]] = range(2, 9), method: str = "smb",
            tie_tolerance: float = 0.02, solver: Solver = lstsq_numpy, radius: float = STABLE_RADIUS,
            criterion: str = "sad") -> IIRFit:
    """Best stable IIR filter for the impulse response ``h`` over ``orders`` (N = M = order, or (p, q) pairs).

    ``criterion="bic"`` picks the order with the least :func:`bic` instead of
    the least SAD (``tie_tolerance`` is then unused): the simplest order that
    explains the waveform.

    ``method`` is ``"smb"`` (guarded Steiglitz-McBride) or ``"prony"`` (Prony, then
    stabilised with the numerator refitted if unstable). The order with the least
    SAD wins; an order whose SAD is within ``tie_tolerance`` (relative) of a lower
    order's is not preferred -- a gain below 2 % is noise being fitted (and SADs within
    1e-12 of the mean |h| are rounding, so equal).
    Orders needing more samples than ``h`` has are skipped. Every pole ends within
    ``radius`` (unstable or slower poles are reflected / pulled in, numerator refitted).
    """
    h = np.asarray(h, dtype=np.float64).ravel()
    rounding = 1e-12 * float(np.mean(np.abs(h))) if h.size else 0.0  # SADs this close are equal (exact fits)
    best: IIRFit | None = None
    best_score = np.inf
    for order in orders:
        p, q = (order, order) if isinstance(order, (int, np.integer)) else order
        if h.size < p + q + 2:
            continue
        if method == "smb":
            b, a = steiglitz_mcbride(h, p, q, solver=solver, radius=radius)
        elif method == "prony":
            b, a = prony(h, p, q, solver)
            if not is_stable(a, radius):
                a = stabilize(a, radius)
                b = refit_numerator(h, a, q, solver)
        else:
            raise ValueError(f"unknown method {method!r}; use 'smb' or 'prony'")
        fit = IIRFit(np.asarray(b, float), np.asarray(a, float), p, q, sad(h, b, a))
        if criterion == "bic":
            score = bic(h, fit.b, fit.a)
            if best is None or score < best_score:
                best, best_score = fit, score
        elif criterion != "sad":
            raise ValueError(f"unknown criterion {criterion!r}; use 'sad' or 'bic'")
        elif best is None or fit.sad < best.sad * (1.0 - tie_tolerance) - rounding:
            best = fit
    if best is None:
        raise ValueError(f"the impulse response has {h.size} samples, too few for any of the requested orders")
    return best


def ring_length(b: np.ndarray, a: np.ndarray, decay: float = 1e-6, max_samples: int = 20000) -> int:
    """Samples until the impulse response of b / a stays below ``decay`` times its peak (at most ``max_samples``).

    Measured on the response itself, not on the slowest pole: a slow pole with a
    tiny residue should not keep a ring-down alive for seconds.
    """
    h = np.abs(impulse_response(b, a, max_samples))
    peak = float(h.max()) if h.size else 0.0
    if peak == 0.0:
        return 1
    above = np.nonzero(h > decay * peak)[0]
    return int(above[-1]) + 1
