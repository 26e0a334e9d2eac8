"""Robust line fits whose noise grows with the regressor: a robust scale that is a function of x.

Real tangential-force noise grows with the normal force. A robust fit with
one scale for every sample (:func:`flowtex.dsp.robust.irls_line`) then
measures its residuals against a scale that is too large at light contact
and too small at heavy contact, and rejects the heavy samples as outliers.

The model here is the heteroscedastic linear model of Carroll & Ruppert
(1988, "Transformation and Weighting in Regression", ch. 2-3):
y_i = X_i beta + s g(x_i) e_i, with e_i symmetric and g a smooth positive
variance function, estimated by generalised least squares with estimated
weights, in its robust form (Carroll & Ruppert 1982, "Robust estimation in
heteroscedastic linear models", Ann. Statist. 10:429-441): alternate

1. a robust fit of beta with the residuals standardised by g (the M-estimator
   of :func:`flowtex.dsp.robust.irls` on the rows X_i / g_i, y_i / g_i), and
2. an estimate of g from that fit's residuals r_i,

for ``cycles`` cycles (Carroll & Ruppert recommend two or three). Step 2 is a
median regression of log |r_i| on a polynomial in log x_i (degree 1 by
default: a power law, g ~ x^theta, Carroll & Ruppert's power-of-the-mean model
in x; a quadratic bends to slow drift in 20 s of recording, docs/fitting.md).
Since log is monotone, exp of the fitted conditional
median of log |r| is the conditional median of |r|: g is the MAD of the
residuals as a function of x, the local form of the MAD scale the
homoscedastic fit uses, and, as a median, it is barely moved by the outliers
the fit then rejects and untroubled by the residuals near 0 whose logarithms
spoil a least-squares fit of log |r| (Davidian & Carroll 1987, "Variance
function estimation", JASA 82:1079-1091, sec. 3). Estimating the weights
does not change the asymptotic distribution of beta when the errors are
symmetric (Carroll & Ruppert 1988, sec. 2.3), so the intervals of
:func:`flowtex.dsp.robust.irls` on the standardised rows hold.

Rejection: a sample whose standardised residual is beyond the bisquare
constant (4.685 scales) gets weight 0; with Gaussian noise that happens to
2 (1 - Phi(4.685)) = 2.8e-6 of clean samples, with heavier tails to more
(:func:`false_rejection_rate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .robust import BISQUARE_C, MAD_TO_SIGMA, RobustLine, irls, line_from_fit
from .robust_kernels import median

SCALE_DEGREE = 1
"""Degree of the polynomial in log x whose exp is the scale function (1: a power law in x)."""
CYCLES = 3
"""Cycles of (robust fit, scale function) (Carroll & Ruppert 1988, sec. 2.2: two or three suffice)."""


@dataclass(frozen=True)
class ScaleFunction:
    """A robust residual scale that depends on x: s(x) = exp(poly(log(x / x_ref))), in the residuals' units.

    ``coef`` are the polynomial's coefficients in ``log(x / x_ref) / span``, lowest power first; x is floored at
    ``x_floor`` (> 0) before the logarithm.
    """

    coef: tuple[float, ...]
    x_ref: float
    span: float
    x_floor: float

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """The scale at each x (same units as the residuals)."""
        z = np.log(np.maximum(np.asarray(x, float), self.x_floor) / self.x_ref) / self.span
        return np.exp(np.polynomial.polynomial.polyval(z, np.asarray(self.coef)))

    def exponent(self, x: float) -> float:
        """d log s / d log x at ``x``: 1 where the scale is proportional to x, 0 where it is constant."""
        z = np.log(max(float(x), self.x_floor) / self.x_ref) / self.span
        deriv = np.polynomial.polynomial.polyder(np.asarray(self.coef))
        return float(np.polynomial.polynomial.polyval(z, deriv)) / self.span if deriv.size else 0.0


def _floored(r: np.ndarray) -> np.ndarray:
    """|residuals| ``r`` floored at 1e-9 of their median (at least 1e-300): the weights 1 / r stay finite.

    The median (a partial sort, most of an iteration's time) is taken only when the floor can bite: the floor is at
    most 1e-9 of the largest |r|, so when the smallest |r| is above that, no value changes and none is needed.
    """
    if float(np.min(r)) >= 1e-9 * max(float(np.max(r)), 1e-300):
        return r
    return np.maximum(r, 1e-9 * max(median(r), 1e-300))


def median_regression(A: np.ndarray, b: np.ndarray, max_iter: int = 500, tol: float = 1e-12) -> np.ndarray:
    """Coefficients c minimising sum |b - A c| (least absolute deviations: the conditional median of b).

    Iteratively reweighted least squares with weights 1 / |r_i| (Schlossmacher 1973, "An iterative technique for
    absolute deviations curve fitting", JASA 68:857), the residuals floored at 1e-9 of their median, until the sum
    of absolute residuals falls by less than ``tol`` (relative) in an iteration. For a few columns and many rows
    this reaches the optimum of the linear programme (tests/dsp/test_hetero.py checks it against one) in time
    linear in the rows, where the programme's time grows much faster (docs/fitting.md).
    """
    A = np.asarray(A, float)
    b = np.asarray(b, float)
    c = np.linalg.lstsq(A, b, rcond=None)[0]
    total = np.inf
    r, w, wb, wA = np.empty(b.shape), np.empty(b.shape), np.empty(b.shape), np.empty(A.shape)  # for every iteration
    for _ in range(max_iter):
        np.abs(np.subtract(b, np.matmul(A, c, out=r), out=r), out=r)  # |b - A c|
        new = float(np.sum(r))
        if total - new <= tol * new:
            break
        total = new
        np.divide(1.0, _floored(r), out=w)
        try:
            c = np.linalg.solve(A.T @ np.multiply(w[:, None], A, out=wA), A.T @ np.multiply(w, b, out=wb))
        except np.linalg.LinAlgError:
            break
    return c


def fit_scale_function(x: np.ndarray, r: np.ndarray, degree: int = SCALE_DEGREE) -> ScaleFunction:
    """The MAD of residuals ``r`` as a function of ``x`` (> 0): median regression of log |r| on a polynomial in
    log x (module docstring), times MAD_TO_SIGMA so that it is the standard deviation for Gaussian noise.

    x is floored at 1 % of its median (a sample at x ~ 0 would otherwise set the shape). A constant x, or fewer
    samples than 10 per coefficient, gives a constant scale (the MAD of r).
    """
    x = np.asarray(x, float)
    r = np.abs(np.asarray(r, float))
    x_ref = float(np.median(x))
    if not x_ref > 0.0:
        raise ValueError("the scale function needs a positive median x")
    floor = 0.01 * x_ref
    lx = np.log(np.maximum(x, floor) / x_ref)
    span = float(np.max(np.abs(lx)))
    tiny = 1e-12 * (float(np.max(r)) or 1.0)
    logr = np.log(np.maximum(r, tiny))
    if span < 1e-6 or x.size < 10 * (degree + 1):
        return ScaleFunction((float(np.log(MAD_TO_SIGMA * max(float(np.median(r)), tiny))),), x_ref, 1.0, floor)
    A = np.vander(lx / span, degree + 1, increasing=True)
    coef = median_regression(A, logr)
    coef[0] += np.log(MAD_TO_SIGMA)
    return ScaleFunction(tuple(float(c) for c in coef), x_ref, span, floor)


@dataclass(frozen=True)
class HeteroLine:
    """A robust line with a scale that depends on x: ``line`` (its ``scale`` is the scale at the median x, its
    ``weights`` the final IRLS weights), the ``scale_function`` of the last cycle (its shape weighted the final
    fit; :meth:`scale_at` is the final scale), and the ``standardised`` residuals r_i / scale_at(x_i)."""

    line: RobustLine
    scale_function: ScaleFunction
    standardised: np.ndarray

    def scale_at(self, x: np.ndarray) -> np.ndarray:
        """The residual scale at each x (the residuals' units): the fit's scale times the scale function's shape."""
        f = self.scale_function
        return self.line.scale * f(np.asarray(x, float)) / float(f(np.array([f.x_ref]))[0])


def irls_line_hetero(x: np.ndarray, y: np.ndarray, intercept: bool = False, kind: str = "bisquare",
                     degree: int = SCALE_DEGREE, cycles: int = CYCLES) -> HeteroLine:
    """Robust line y = slope x (+ intercept) whose residual scale is a function of x (> 0) (module docstring).

    Starts from the one-scale fit (:func:`flowtex.dsp.robust.irls`), then ``cycles`` times: fit the scale function
    to the residuals, refit on the rows standardised by it. Samples must be in time order (the intervals' batch
    means).
    """
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    X = np.column_stack([x, np.ones_like(x)]) if intercept else x[:, None]
    fit = irls(X, y, kind)
    g = np.ones_like(x)
    scale_fn = ScaleFunction((0.0,), float(np.median(x)), 1.0, 1.0)
    for _ in range(cycles):
        scale_fn = fit_scale_function(x, y - X @ fit.beta, degree)
        g = scale_fn(x) / scale_fn(np.array([scale_fn.x_ref]))[0]       # relative shape, 1 at x_ref
        fit = irls(X / g[:, None], y / g, kind)
    line = line_from_fit(fit, intercept)
    return HeteroLine(line, scale_fn, (y - X @ fit.beta) / (fit.scale * g))


def false_rejection_rate(tail_dof: float = float("inf")) -> float:
    """Share of clean samples the bisquare rule rejects when the standardised noise is Student t with ``tail_dof``
    degrees of freedom (inf: Gaussian): P(|e| > 4.685 x MAD_TO_SIGMA x median |e|), since the fit's scale is the
    MAD-based one."""
    from scipy import stats

    dist = stats.norm if not np.isfinite(tail_dof) else stats.t(tail_dof)
    mad = float(dist.ppf(0.75))
    return float(2.0 * dist.sf(BISQUARE_C * MAD_TO_SIGMA * mad))


def rejected_stretches(rejected: np.ndarray) -> tuple[int, int]:
    """(number of runs of consecutive True samples, length of the longest run) of a boolean mask in time order.

    A stiction spike is one short run; slow drift past the rule is a long one.
    """
    r = np.asarray(rejected, bool).astype(np.int8)
    if not r.any():
        return 0, 0
    edges = np.diff(np.concatenate([[0], r, [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int(starts.size), int(np.max(ends - starts))
