"""Robust statistics for fitting: IRLS line fits (Huber / Tukey bisquare) and outlier clamping.

All functions are pure numpy/scipy and unit-agnostic (the caller's units).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import robust_kernels

MAD_TO_SIGMA = 1.4826
"""MAD of a Gaussian sample times this is its standard deviation."""
HUBER_K = 1.345
"""Huber's tuning constant (95 % efficiency at the Gaussian)."""
BISQUARE_C = 4.685
"""Tukey's bisquare tuning constant (95 % efficiency at the Gaussian)."""
BATCHES = 20
"""Consecutive blocks of :func:`batch_means_se` in :func:`irls_line`'s intervals (1 s each in 20 s of recording)."""


@dataclass(frozen=True)
class RobustLine:
    """y = slope x + intercept fitted by IRLS; ``ci`` = 95 % intervals; ``weights`` the final IRLS weights."""

    slope: float
    intercept: float
    slope_ci: tuple[float, float]
    intercept_ci: tuple[float, float]
    scale: float
    weights: np.ndarray
    iterations: int


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
    g = np.array([Xb.T @ pb for Xb, pb in zip(np.array_split(X, blocks), np.array_split(psi, blocks), strict=True)])
    S = blocks / (blocks - 1) * (g.T @ g)
    Hi = np.linalg.inv(H)
    return scale * np.sqrt(np.maximum(np.diag(Hi @ S @ Hi), 0.0))


def robust_scale(r: np.ndarray, work: np.ndarray | None = None) -> float:
    """MAD-based standard deviation of residuals ``r`` (about their median); ``work``: optional scratch (2, len(r))
    reused between calls (:func:`flowtex.dsp.robust_kernels.mad`)."""
    return float(MAD_TO_SIGMA * robust_kernels.mad(np.asarray(r, float), work))


_KINDS = {"huber": robust_kernels.HUBER, "bisquare": robust_kernels.BISQUARE}


@dataclass(frozen=True)
class RobustFit:
    """Coefficients ``beta`` of y = X beta fitted by IRLS, their standard errors ``se`` and the t quantile ``tq`` of
    their 95 % intervals, the residual ``scale``, the final IRLS ``weights`` and the iteration count."""

    beta: np.ndarray
    se: np.ndarray
    tq: float
    scale: float
    weights: np.ndarray
    iterations: int


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
    work, Xw, yw, r = np.empty((2, n)), np.empty((n, k)), np.empty(n), np.empty(n)  # for every iteration
    for stage in ("huber", kind) if kind != "huber" else ("huber",):
        for _ in range(max_iter):
            it += 1
            np.subtract(y, np.matmul(X, beta, out=r), out=r)  # y - X beta
            s = robust_scale(r, work) or float(np.std(r)) or 1.0
            if stage not in _KINDS:
                raise ValueError(f"unknown weight function {stage!r}; use huber or bisquare")
            robust_kernels.weighted_rows(X, y, r, s, _KINDS[stage], HUBER_K, BISQUARE_C, w, Xw, yw)
            new = np.linalg.lstsq(Xw, yw, rcond=None)[0]
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


def line_from_fit(fit: RobustFit, intercept: bool) -> RobustLine:
    """The :class:`RobustLine` of a fit whose design columns are (x, 1) (or x alone without ``intercept``)."""
    slope = float(fit.beta[0])
    icpt = float(fit.beta[1]) if intercept else 0.0
    se, tq = fit.se, fit.tq
    ici = (icpt - tq * float(se[1]), icpt + tq * float(se[1])) if intercept else (0.0, 0.0)
    return RobustLine(slope, icpt, (slope - tq * float(se[0]), slope + tq * float(se[0])), ici, fit.scale, fit.weights,
                      fit.iterations)


def irls_line(x: np.ndarray, y: np.ndarray, intercept: bool = False, kind: str = "bisquare", max_iter: int = 100,
              tol: float = 1e-10, blocks: int = BATCHES) -> RobustLine:
    """Robust line y = slope x (+ intercept) by iteratively reweighted least squares (:func:`irls`), one residual
    scale for every sample. Samples must be in time order."""
    x = np.asarray(x, float)
    X = np.column_stack([x, np.ones_like(x)]) if intercept else x[:, None]
    return line_from_fit(irls(X, y, kind, max_iter, tol, blocks), intercept)


def clamp_outliers(x: np.ndarray, k: float = 8.0, block: int = 250) -> tuple[np.ndarray, np.ndarray]:
    """Clip samples further than ``k`` local scales from the local median; returns (copy, indices).

    The scale of each block of ``block`` samples (a vibration's power changes
    with speed and force, so one global scale would clip the loud stretches)
    is the larger of its MAD-based standard deviation and its RMS about the
    median. A Gaussian sample exceeds 8 sigma with probability 1e-15, so clean
    recordings are left untouched while isolated sensor spikes are cut back to
    the +-k band of their block (their power no longer dominates the spectrum):
    a spike of 20 x RMS raises its block's RMS by sqrt(1 + 400 / 250) = 1.6 and
    still stands 12 scales out. Why not the MAD alone: real vibration is
    heavy-tailed (kurtosis 4-12), its MAD underestimates its RMS, and
    its bursts went past 8 MAD-sigma: on generated heavy-tailed recordings
    (flowtex.datasets.resonant) the MAD alone clipped some 90 genuine samples in
    20 s and the fitted surface lost 0.5-1 dB; the larger scale clips none of
    them and still every one of 20 spikes of 20 x RMS.
    """
    x = np.asarray(x, float)
    out = x.copy()
    bad_all = []
    for a in range(0, x.shape[0], block):
        seg = x[a:a + block]
        if a + block < x.shape[0] < a + 2 * block:  # fold a short tail into the last block
            seg = x[a:]
        med = float(np.median(seg))
        s = max(robust_scale(seg), float(np.sqrt(np.mean((seg - med) ** 2))))
        if s > 0.0:
            bad = np.flatnonzero(np.abs(seg - med) > k * s)
            out[a + bad] = med + np.sign(seg[bad] - med) * k * s
            bad_all.append(a + bad)
        if seg.shape[0] > block:
            break
    return out, (np.concatenate(bad_all) if bad_all else np.zeros(0, np.int64))
