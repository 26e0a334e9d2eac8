"""flowtex.dsp.hetero: the median regression, the scale function, the rule's false-rejection share, and the robust
line against statsmodels' RLM given the true weights.

Ground truth: noise of known standard deviation s(x) (a power law, or a sensor floor joining noise proportional
to x), Gaussian or Student t.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from flowtex.dsp.hetero import false_rejection_rate, fit_scale_function, irls_line_hetero, median_regression, rejected_stretches
from flowtex.dsp.robust import BISQUARE_C, MAD_TO_SIGMA

N = 20000  # 20 s at 1 kHz, as the recordings


def _forces(rng: np.random.Generator) -> np.ndarray:
    return 0.3 * (4.3 / 0.3) ** rng.uniform(0.0, 1.0, N)  # normal force log-uniform over 0.3-4.3 N


def test_median_regression_is_the_least_absolute_deviations_fit():
    """Against the exact optimum of the least-absolute-deviations linear programme (its dual, Koenker 2005 sec. 6.2,
    solved by scipy's HiGHS): the sum of absolute residuals within 1e-9 (relative) of the optimum, the
    coefficients within 1e-3, a tenth of the slope's standard error (~0.01; the objective is flat near its
    optimum: measured 2e-4 apart at equal sums); statsmodels' QuantReg (independent code, stopping at its own
    1e-6 tolerance) agrees within 2e-3."""
    sm = pytest.importorskip("statsmodels.api")
    from scipy.optimize import linprog

    rng = np.random.default_rng(1)
    x = rng.uniform(-1.0, 1.0, N)
    A = np.vander(x, 3, increasing=True)
    b = 1.0 + 2.0 * x - 0.5 * x * x + rng.standard_t(3, N)
    ours = median_regression(A, b)
    dual = linprog(-b, A_eq=A.T, b_eq=np.zeros(3), bounds=(-1.0, 1.0), method="highs")
    exact = -dual.eqlin.marginals
    best = np.sum(np.abs(b - A @ exact))
    assert np.sum(np.abs(b - A @ ours)) == pytest.approx(best, rel=1e-9)
    assert ours == pytest.approx(exact, abs=1e-3)
    assert ours == pytest.approx(sm.QuantReg(b, A).fit(q=0.5).params, abs=2e-3)


@pytest.mark.parametrize("exponent", [0.0, 0.8, 1.0])
def test_scale_function_recovers_a_power_law(exponent):
    """r = 0.05 (x / 1.1)^p Z, Z Gaussian: the fitted exponent is p within 4 standard errors of the LAD slope.

    Asymptotic variance of the LAD slope (Koenker 2005, eq. 4.1): 1 / (4 f^2 n var(log x)), f the density of
    log|Z| at its median log(0.6745): f = 2 phi(0.6745) 0.6745 = 0.429.
    """
    rng = np.random.default_rng(7)
    x = _forces(rng)
    r = 0.05 * (x / 1.1) ** exponent * rng.standard_normal(N)
    fn = fit_scale_function(x, r, degree=1)
    q = stats.norm.ppf(0.75)
    f = 2.0 * stats.norm.pdf(q) * q
    se = 1.0 / (2.0 * f * np.sqrt(N * np.var(np.log(x))))
    assert fn.exponent(1.1) == pytest.approx(exponent, abs=4 * se)
    # the level: s(1.1) = 0.05 (the MAD scale is the standard deviation for Gaussian noise); the LAD intercept's
    # relative SE is 1 / (2 f sqrt(n)) = 0.8 % at the centre of log x; 4 of them
    assert float(fn(np.array([1.1]))[0]) == pytest.approx(0.05, rel=4 / (2 * f * np.sqrt(N)) + 4 * se * abs(np.log(1.1 / fn.x_ref)))


def test_scale_function_is_constant_for_a_constant_x():
    r = np.random.default_rng(0).standard_normal(1000)
    fn = fit_scale_function(np.full(1000, 2.0), r)
    assert fn.exponent(2.0) == 0.0
    assert float(fn(np.array([2.0]))[0]) == pytest.approx(MAD_TO_SIGMA * np.median(np.abs(r)))


@pytest.mark.parametrize("dof", [np.inf, 5.0, 3.0])
def test_false_rejection_rate_is_the_rules_share_on_clean_noise(dof):
    """Simulated: the share of 2 million draws past 4.685 MAD-sigmas of their own MAD, within 4 binomial sd."""
    rng = np.random.default_rng(3)
    e = rng.standard_normal(2_000_000) if not np.isfinite(dof) else rng.standard_t(dof, 2_000_000)
    share = np.mean(np.abs(e) > BISQUARE_C * MAD_TO_SIGMA * np.median(np.abs(e)))
    p = false_rejection_rate(dof)
    assert share == pytest.approx(p, abs=4 * np.sqrt(p * (1 - p) / e.size) + 1e-6)
    if not np.isfinite(dof):
        assert p == pytest.approx(2 * stats.norm.sf(4.685), rel=1e-4)   # 2.8e-6; MAD_TO_SIGMA is 1 / 0.6745 rounded


def test_rejected_stretches():
    assert rejected_stretches(np.zeros(5, bool)) == (0, 0)
    assert rejected_stretches(np.array([1, 1, 0, 1, 0, 0, 1, 1, 1], bool)) == (3, 3)
    assert rejected_stretches(np.ones(4, bool)) == (1, 4)


@given(st.lists(st.booleans(), max_size=200))
def test_rejected_stretches_are_the_runs_of_true(mask):
    runs = [len(list(g)) for k, g in itertools.groupby(mask) if k]
    assert rejected_stretches(np.array(mask, bool)) == (len(runs), max(runs, default=0))


@given(st.floats(1e-3, 1e3), st.floats(1e-3, 1e3))
@settings(max_examples=20, deadline=None)
def test_scale_function_is_equivariant(cx, cr):
    """Forces in other units (x cx) and residuals in other units (x cr): the scale follows the residuals' units and
    keeps its shape (the exponent)."""
    rng = np.random.default_rng(5)
    x = _forces(rng)[:2000]
    r = 0.05 * x ** 0.7 * rng.standard_normal(2000)
    a, b = fit_scale_function(x, r), fit_scale_function(cx * x, cr * r)
    assert b.exponent(cx * 1.0) == pytest.approx(a.exponent(1.0), abs=1e-6)
    assert b(cx * x[:50]) == pytest.approx(cr * a(x[:50]), rel=1e-6)


def test_line_matches_statsmodels_rlm_given_the_true_weights():
    """Floor + proportional noise, Student t5, 3 % outliers: the slope with the estimated scale function is within a
    fifth of a standard error of statsmodels' RLM (Tukey biweight) on rows divided by the true noise sd, and the
    interval's standard error within 25 % of RLM's (20 batches: the batch-means SE scatters by ~1/sqrt(19) = 23 %,
    but the wider of it and the asymptotic one is taken)."""
    sm = pytest.importorskip("statsmodels.api")
    rng = np.random.default_rng(11)
    x = _forces(rng)
    sd = np.sqrt(0.01 ** 2 + (0.04 * x) ** 2)
    y = 0.4 * x + sd * rng.standard_t(5, N) / np.sqrt(5 / 3)
    bad = rng.choice(N, size=600, replace=False)
    y[bad] += 2.0 * 0.4 * x[bad]
    ours = irls_line_hetero(x, y)
    ref = sm.RLM(y / sd, x / sd, M=sm.robust.norms.TukeyBiweight()).fit()
    se = (ours.line.slope_ci[1] - ours.line.slope_ci[0]) / (2 * stats.t.ppf(0.975, 19))
    assert ours.line.slope == pytest.approx(ref.params[0], abs=0.2 * ref.bse[0])
    assert se == pytest.approx(ref.bse[0], rel=0.25)
    assert np.all(ours.line.weights[bad] == 0.0)   # 2 x the friction force stands > 8 noise sd out everywhere
