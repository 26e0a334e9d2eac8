"""The IRLS fits as they were before their compiled kernels (flowtex.dsp.robust_kernels), kept verbatim.

The oracle of tests/dsp/test_robust_speed.py and the baseline of benchmarks/bench_robust.py: the fits of
flowtex.dsp.robust and flowtex.dsp.hetero must give these values bit for bit. Copied from flowtex/dsp/robust.py
(``batch_means_se``, ``robust_scale``, ``_weights``, ``irls``) and flowtex/dsp/hetero.py (``_floored``,
``median_regression``, ``fit_scale_function``, ``irls_line_hetero``) as they stood; the result classes and the
helpers that did not change are imported.
"""

from __future__ import annotations

import numpy as np

from flowtex.dsp.hetero import CYCLES, SCALE_DEGREE, HeteroLine, ScaleFunction
from flowtex.dsp.robust import BATCHES, BISQUARE_C, HUBER_K, MAD_TO_SIGMA, RobustFit, line_from_fit


def batch_means_se(X: np.ndarray, psi: np.ndarray, dpsi: np.ndarray, scale: float, blocks: int) -> np.ndarray | None:
    """Standard errors of an M-estimator's coefficients (design ``X``; ``psi`` and its derivative ``dpsi`` at each
    sample's scaled residual; residual ``scale``) by batch means.

    The samples (in time order) are cut into ``blocks`` consecutive blocks whose summed scores g_b = X_b' psi_b
    are taken as independent: the covariance is scale^2 H^-1 S H^-1 with H = X' diag(dpsi) X and
    S = blocks / (blocks - 1) sum g_b g_b' (the M-estimator's sandwich with the blocks as clusters). Neighbouring
    samples may be correlated, as long as blocks far apart are not. None when fewer than ``blocks`` x (columns + 1)
    samples are given or H is singular.
    """
    n, k = X.shape
    if blocks < 2 or n < blocks * (k + 1):
        return None
    H = X.T @ (dpsi[:, None] * X)
    if np.linalg.matrix_rank(H) < k:
        return None
    g = np.array([X[idx].T @ psi[idx] for idx in np.array_split(np.arange(n), blocks)])
    S = blocks / (blocks - 1) * (g.T @ g)
    Hi = np.linalg.inv(H)
    return scale * np.sqrt(np.maximum(np.diag(Hi @ S @ Hi), 0.0))


def robust_scale(r: np.ndarray) -> float:
    """MAD-based standard deviation of residuals ``r`` (about their median)."""
    r = np.asarray(r, float)
    return float(MAD_TO_SIGMA * np.median(np.abs(r - np.median(r))))


def _weights(u: np.ndarray, kind: str) -> np.ndarray:
    if kind == "huber":
        a = np.abs(u)
        return np.where(a <= HUBER_K, 1.0, HUBER_K / np.maximum(a, 1e-300))
    if kind == "bisquare":
        return np.where(np.abs(u) < BISQUARE_C, (1.0 - (u / BISQUARE_C) ** 2) ** 2, 0.0)
    raise ValueError(f"unknown weight function {kind!r}; use huber or bisquare")


def irls(X: np.ndarray, y: np.ndarray, kind: str = "bisquare", max_iter: int = 100, tol: float = 1e-10,
         blocks: int = BATCHES) -> RobustFit:
    """Robust linear fit y = X beta by iteratively reweighted least squares (the method of :func:`irls_line`).

    Starts from a Huber fit (convex: a unique solution) seeded by least
    squares, then, for ``bisquare``, continues with bisquare weights (which
    reject gross outliers such as stiction spikes completely). The scale is
    the MAD of the residuals, re-estimated every iteration. The standard
    errors are the larger of two: the asymptotic covariance of an
    M-estimator (Huber 1981, eq. 7.6.4), s^2 mean(psi^2) / mean(psi')^2
    (X'X)^-1 (used with a t quantile), which assumes independent samples,
    and batch means (:func:`batch_means_se`: the M-estimator's sandwich with
    ``blocks`` consecutive blocks as independent clusters, a t quantile with
    blocks - 1 degrees of freedom), which holds for noise correlated over
    less than a block. Rows must be in time order.
    """
    from scipy import stats

    X = np.asarray(X, float)
    y = np.asarray(y, float)
    n, k = X.shape
    if n <= k:
        raise ValueError(f"need more than {k} samples for a robust fit, got {n}")
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    it = 0
    w = np.ones(n)
    s = 1.0
    for stage in ("huber", kind) if kind != "huber" else ("huber",):
        for _ in range(max_iter):
            it += 1
            r = y - X @ beta
            s = robust_scale(r) or float(np.std(r)) or 1.0
            w = _weights(r / s, stage)
            sw = np.sqrt(w)
            new = np.linalg.lstsq(X * sw[:, None], y * sw, rcond=None)[0]
            done = np.max(np.abs(new - beta)) <= tol * (1.0 + np.max(np.abs(beta)))
            beta = new
            if done:
                break
    r = y - X @ beta
    u = r / s
    psi = w * u
    if kind == "huber":
        dpsi = (np.abs(u) <= HUBER_K).astype(float)
    else:
        v = u / BISQUARE_C
        dpsi = np.where(np.abs(u) < BISQUARE_C, (1 - v * v) * (1 - 5 * v * v), 0.0)
    mean_dpsi = float(np.mean(dpsi)) or 1e-12
    cov = s * s * float(np.mean(psi ** 2)) / mean_dpsi ** 2 * np.linalg.inv(X.T @ X) * n / max(n - k, 1)
    tq = float(stats.t.ppf(0.975, max(n - k, 1)))
    half = tq * np.sqrt(np.maximum(np.diag(cov), 0.0))
    batch = batch_means_se(X, psi, dpsi, s, blocks)
    if batch is not None:
        half = np.maximum(half, float(stats.t.ppf(0.975, blocks - 1)) * batch)
    return RobustFit(beta, half / tq, tq, s, w, it)


def _floored(r: np.ndarray) -> np.ndarray:
    """|residuals| ``r`` floored at 1e-9 of their median (at least 1e-300): the weights 1 / r stay finite.

    The median (a partial sort, most of an iteration's time) is taken only when the floor can bite: the floor is at
    most 1e-9 of the largest |r|, so when the smallest |r| is above that, no value changes and none is needed.
    """
    if float(np.min(r)) >= 1e-9 * max(float(np.max(r)), 1e-300):
        return r
    return np.maximum(r, 1e-9 * max(float(np.median(r)), 1e-300))


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
    for _ in range(max_iter):
        r = np.abs(b - A @ c)
        new = float(np.sum(r))
        if total - new <= tol * new:
            break
        total = new
        w = 1.0 / _floored(r)
        try:
            c = np.linalg.solve(A.T @ (w[:, None] * A), A.T @ (w * b))
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
