"""The compiled IRLS pieces (flowtex.dsp.robust_kernels) give the old numpy code's values bit for bit.

The oracle is the old code itself (tests/dsp/robust_old.py); every comparison is exact equality (nan equal to nan),
no tolerance: the fits are a contract pinned elsewhere with derived tolerances, and a speed-up must not move them.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from flowtex.dsp import hetero, robust, robust_kernels
from tests.dsp import robust_old

SPECIAL = st.sampled_from([0.0, -0.0, 1.0, -1.0, 5e-324, 1e308, -1e308, np.inf, -np.inf, np.nan])
VALUES = st.one_of(st.floats(allow_nan=True, allow_infinity=True), SPECIAL, st.integers(-3, 3).map(float))


def _same(a, b) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=True))


@settings(max_examples=400, deadline=None)
@given(arrays(np.float64, st.integers(1, 60), elements=VALUES))
def test_median_and_mad_are_numpys(x):
    """Any values (ties, zeros of both signs, subnormals, infinities, nans), odd and even counts. numpy's median of an
    even count averages the two middle values, which overflows to inf for two near 1e308: the kernels must agree."""
    with np.errstate(invalid="ignore", over="ignore"):
        assert _same(robust_kernels.median(x), np.median(x))
        assert _same(robust_kernels.mad(x), np.median(np.abs(x - np.median(x))))


def _median_cases():
    rng = np.random.default_rng(5)
    n = 20001
    cases = [rng.standard_t(2, n), np.sort(rng.normal(size=n)), np.sort(rng.normal(size=n))[::-1], np.ones(n),
             np.concatenate([np.arange(n // 2), np.arange(n // 2, 0, -1)]).astype(float), rng.integers(0, 3, n) * 1.0]
    return cases + [c[:-1] for c in cases]


def test_median_of_large_and_adversarial_orders():
    """Large arrays, sorted, reversed, constant and organ-pipe orders, odd and even counts."""
    for x in _median_cases():
        assert _same(robust_kernels.median(x), np.median(x))
        assert _same(robust_kernels.mad(x), np.median(np.abs(x - np.median(x))))


def test_a_selection_that_gives_up_hands_back_to_numpy(monkeypatch):
    """The depth bound (what keeps an adversarial order linear): the kernels say they gave up, the values stay."""
    x = _median_cases()[0]
    assert not robust_kernels._median_kernel(x, 0)[1]
    assert not robust_kernels._mad_kernel(x, np.empty((2, x.shape[0])), 0)[1]
    monkeypatch.setattr(robust_kernels, "DEPTH_SLACK", -10 ** 6)
    for x in _median_cases():
        assert _same(robust_kernels.median(x), np.median(x))
        assert _same(robust_kernels.mad(x), np.median(np.abs(x - np.median(x))))


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, st.integers(1, 40), elements=VALUES), st.floats(1e-300, 1e300),
       st.sampled_from(["huber", "bisquare"]), st.integers(1, 2))
def test_weighted_rows_are_the_numpy_formulas(r, s, kind, k):
    rng = np.random.default_rng(r.shape[0])
    X = rng.normal(size=(r.shape[0], k))
    y = rng.normal(size=r.shape[0])
    w, Xw, yw = np.empty_like(y), np.empty_like(X), np.empty_like(y)
    robust_kernels.weighted_rows(X, y, r, s, robust._KINDS[kind], robust.HUBER_K, robust.BISQUARE_C, w, Xw, yw)
    with np.errstate(all="ignore"):
        w0 = robust_old._weights(r / s, kind)
        sw = np.sqrt(w0)
        assert _same(w, w0) and _same(Xw, X * sw[:, None]) and _same(yw, y * sw)


def _problem(seed: int, n: int, intercept: bool, tails: float, outliers: float, hetero_power: float):
    """A friction-like line: force noise that grows with the normal force, heavy tails, stiction spikes."""
    rng = np.random.default_rng(seed)
    x = np.abs(rng.normal(2.0, 1.0, n)) + 0.05
    e = rng.standard_t(tails, n) if np.isfinite(tails) else rng.normal(size=n)
    y = 0.4 * x + (0.1 if intercept else 0.0) + 0.02 * x ** hetero_power * e
    spikes = rng.random(n) < outliers
    y[spikes] += rng.normal(0.0, 2.0, int(spikes.sum()))
    return x, y


PROBLEMS = dict(seed=st.integers(0, 2 ** 32 - 1), n=st.sampled_from([25, 200, 1001, 4000]), intercept=st.booleans(),
                tails=st.sampled_from([2.5, 5.0, np.inf]), outliers=st.sampled_from([0.0, 0.01, 0.1]),
                hetero_power=st.sampled_from([0.0, 1.0]))


def _same_fit(a, b) -> bool:
    return (_same(a.beta, b.beta) and _same(a.se, b.se) and a.tq == b.tq and _same(a.scale, b.scale)
            and _same(a.weights, b.weights) and a.iterations == b.iterations)


@settings(max_examples=40, deadline=None)
@given(**PROBLEMS, kind=st.sampled_from(["huber", "bisquare"]))
def test_irls_is_the_old_irls(seed, n, intercept, tails, outliers, hetero_power, kind):
    x, y = _problem(seed, n, intercept, tails, outliers, hetero_power)
    X = np.column_stack([x, np.ones_like(x)]) if intercept else x[:, None]
    assert _same_fit(robust.irls(X, y, kind), robust_old.irls(X, y, kind))


@settings(max_examples=20, deadline=None)
@given(**PROBLEMS)
def test_hetero_line_is_the_old_one(seed, n, intercept, tails, outliers, hetero_power):
    x, y = _problem(seed, n, intercept, tails, outliers, hetero_power)
    new, old = hetero.irls_line_hetero(x, y, intercept), robust_old.irls_line_hetero(x, y, intercept)
    assert new.line.slope == old.line.slope and new.line.intercept == old.line.intercept
    assert new.line.slope_ci == old.line.slope_ci and new.line.intercept_ci == old.line.intercept_ci
    assert new.line.scale == old.line.scale and new.line.iterations == old.line.iterations
    assert _same(new.line.weights, old.line.weights) and _same(new.standardised, old.standardised)
    assert new.scale_function == old.scale_function


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(3, 3000), degree=st.integers(0, 2),
       exact=st.floats(0.0, 0.9))
def test_median_regression_is_the_old_one(seed, n, degree, exact):
    """Including rows fitted exactly (residuals 0: the weights' floor, and so the median, bites)."""
    rng = np.random.default_rng(seed)
    A = np.vander(rng.uniform(-1, 1, n), degree + 1, increasing=True)
    b = A @ rng.normal(size=degree + 1) + rng.standard_t(3, n) * (rng.random(n) >= exact)
    with np.errstate(over="ignore"):  # a residual of exactly 0 under a median of 0: weight inf, as always
        assert _same(hetero.median_regression(A, b), robust_old.median_regression(A, b))


def test_unknown_weight_function_is_refused_as_before():
    x, y = _problem(1, 200, False, np.inf, 0.0, 0.0)
    for fit in (robust.irls, robust_old.irls):
        try:
            fit(x[:, None], y, "cauchy")
        except ValueError as e:
            assert "unknown weight function 'cauchy'" in str(e)
        else:
            raise AssertionError("an unknown weight function was accepted")
