"""flowtex.dsp.poly against independent references: numpy roots, scipy.signal.freqz / dimpulse, Yule-Walker."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from hypothesis import example, given, settings
from hypothesis import strategies as st

from flowtex.dsp.poly import MAX_RADIUS, impulse_response, is_stable, power_spectrum, root_power_spectrum, roots_inside, stabilize, step_down
from tests.dsp.numpy_rounding import NUMPY_ROUNDS_AS_NPMATH


def _poly(roots):
    return np.real(np.poly(roots))


A = _poly([0.95 * np.exp(0.4j), 0.95 * np.exp(-0.4j), 0.7 * np.exp(2.0j), 0.7 * np.exp(-2.0j), -0.5])
C = _poly([0.9 * np.exp(1.1j), 0.9 * np.exp(-1.1j)])


def test_power_spectrum_is_freqz():
    w, h = scipy.signal.freqz(C, A, worN=512)
    np.testing.assert_allclose(power_spectrum(A, C, w), np.abs(h) ** 2, rtol=1e-10)


def test_root_power_spectrum_equals_coefficient_one():
    w = np.linspace(0.0, np.pi, 300)
    np.testing.assert_allclose(root_power_spectrum(np.roots(A), np.roots(C), w), power_spectrum(A, C, w), rtol=1e-9)


def test_impulse_response_is_dimpulse():
    _, (h,) = scipy.signal.dimpulse((np.r_[C, np.zeros(A.size - C.size)], A, 1.0), n=64)
    np.testing.assert_allclose(impulse_response(C, A, 64), h.ravel(), rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("radius, inside", [(0.96, True), (0.95 - 1e-9, False), (1.0, True)])
def test_stability_test_matches_roots(radius, inside):
    assert roots_inside(A, radius) is inside
    assert roots_inside(A, radius) == bool(np.all(np.abs(np.roots(A)) < radius))


def test_stabilize_reflects_then_clips_and_keeps_the_shape():
    outside = _poly([1.25 * np.exp(0.8j), 1.25 * np.exp(-0.8j), 0.5])
    s = stabilize(outside)
    assert is_stable(s) and not is_stable(outside)
    np.testing.assert_allclose(np.sort(np.abs(np.roots(s))), [0.5, 0.8, 0.8], rtol=1e-9)  # 1 / 1.25
    w = np.linspace(0.0, np.pi, 200)
    ratio = power_spectrum(np.r_[1.0], outside, w) / power_spectrum(np.r_[1.0], s, w)
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)  # reflection: |P| changes by a constant factor only
    on_circle = _poly([np.exp(0.3j), np.exp(-0.3j)])
    np.testing.assert_allclose(np.abs(np.roots(stabilize(on_circle))), MAX_RADIUS, rtol=1e-9)
    assert np.array_equal(stabilize(A), A)  # already inside: unchanged


@pytest.mark.parametrize("order", [1, 2, 3])
def test_step_down_is_the_yule_walker_predictor(order):
    # the order-m predictor sharing A's first m reflection coefficients has the AR model's first m autocorrelation lags
    h = impulse_response(np.r_[1.0], A, 4000)
    r = np.array([h[: h.size - k] @ h[k:] for k in range(order + 1)])
    yw = np.r_[1.0, scipy.linalg.solve_toeplitz(r[:-1], -r[1:])]
    np.testing.assert_allclose(step_down(A, order), yw, rtol=1e-8, atol=1e-10)
    with pytest.raises(ValueError, match="not minimum phase"):
        step_down(_poly([1.1, 0.2]), 0)


def test_stabilize_with_a_root_at_the_origin_warns_nothing():
    # found by benchmarks/bench_model_resample.py --hatt: 1 / conj(0) was computed (and warned about) though unused
    import warnings

    from flowtex.dsp.poly import stabilize

    poly = np.poly([0.0, 2.0, 0.5])  # roots 0, 2 (reflected to 0.5) and 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = stabilize(poly)
    np.testing.assert_allclose(np.sort(np.abs(np.roots(out))), [0.0, 0.5, 0.5], atol=1e-12)


def _longdouble_value(p: np.ndarray, w: np.ndarray) -> np.ndarray:
    """P(e^-jw) by Horner in extended precision (np.longdouble; 64-bit mantissa on x86), real and imaginary part."""
    cw, sw = np.cos(w.astype(np.longdouble)), np.sin(w.astype(np.longdouble))
    re, im = np.full(w.shape, np.longdouble(p[-1])), np.zeros(w.shape, np.longdouble)
    for c in p[-2::-1]:
        re, im = np.longdouble(c) + re * cw + im * sw, im * cw - re * sw
    return re * re + im * im


@st.composite
def _hard_models(draw):
    """(A, C, w): monic polynomials with root pairs up to MAX_RADIUS (HaTT's zeros sit at 0.9999) and frequencies
    that include each pair's angle, where |P| is smallest."""
    def poly(n_pairs, n_real):
        radius = [1.0 - 10.0 ** -draw(st.floats(0.0, 5.0)) for _ in range(n_pairs)]
        angle = [draw(st.floats(0.0, np.pi)) for _ in range(n_pairs)]
        real = [draw(st.floats(-MAX_RADIUS, MAX_RADIUS)) for _ in range(n_real)]
        roots = [r * np.exp(s * 1j * a) for r, a in zip(radius, angle, strict=True) for s in (1, -1)] + real
        return _poly(roots) if roots else np.r_[1.0], angle

    a, a_angles = poly(draw(st.integers(0, 8)), draw(st.integers(0, 2)))
    c, c_angles = poly(draw(st.integers(0, 8)), draw(st.integers(0, 2)))
    w = np.unique(np.r_[np.linspace(0.0, np.pi, 101), a_angles, c_angles])
    return a, c, w


@settings(max_examples=150, deadline=None)
@given(_hard_models())
@example((_poly([(1 - 1e-5) * np.exp(0.003j), (1 - 1e-5) * np.exp(-0.003j)] * 2), np.r_[1.0], np.linspace(0.0, np.pi, 101)))
def test_power_spectrum_within_horners_bound_of_an_extended_precision_value(model):
    a, c, w = model
    got = power_spectrum(a, c, w)
    ref_a, ref_c = _longdouble_value(a, w), _longdouble_value(c, w)
    eps, eps_ld = np.finfo(np.float64).eps, np.finfo(np.longdouble).eps

    def rel(p, p2, e):
        # Horner's bound (Higham 2002, eq. 5.3) gamma_2n sum |p_k| at |z| = 1, twice that in complex arithmetic, and
        # n eps sum |p_k| more for z^-1 rounded to the nearest (|P'| <= n sum |p_k|): 5 n e sum |p_k|, relative to |P|
        return 5 * p.size * e * np.sum(np.abs(p)) / np.sqrt(p2.astype(np.float64))

    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):  # where |A| ~ 0 (no digits there, below)
        ref = (ref_c / ref_a).astype(np.float64)
        # |P|^2 doubles the relative error of |P|; a few roundings more for the squares, their sum and the quotient
        bound = 2 * (rel(a, ref_a, eps) + rel(c, ref_c, eps) + rel(a, ref_a, eps_ld) + rel(c, ref_c, eps_ld)) + 8 * eps
        error = np.abs(got / ref - 1.0)
        z = np.exp(-1j * w)
        old = np.abs(np.polynomial.polynomial.polyval(z, c)) ** 2 / np.abs(np.polynomial.polynomial.polyval(z, a)) ** 2
    # where the bound reaches 1/2 the value has no significant digit left (two pole pairs at w = 0 within 1e-5 of the
    # circle: |A(1)| ~ 1e-20 rounds to 0 and both paths give inf); every other frequency is checked
    digits = bound < 0.5
    assert np.all(error[digits] <= bound[digits])
    # and it is numpy's polyval formulation (the code it replaced) bit for bit, inf where A rounds to 0 included, where
    # numpy rounds as npmath does (tests/dsp/numpy_rounding.py); elsewhere both lie within the bound of the reference
    if NUMPY_ROUNDS_AS_NPMATH:
        np.testing.assert_array_equal(got, old)
    else:
        assert np.all(np.abs(old / ref - 1.0)[digits] <= bound[digits])


def test_power_spectrum_stack_rows_are_each_models_own_bit_for_bit():
    w = np.linspace(0.0, np.pi, 77)
    ar = np.array([A, _poly([0.99 * np.exp(0.1j), 0.99 * np.exp(-0.1j), 0.2, -0.3, 0.1])])
    ma = np.array([C, _poly([0.9999 * np.exp(2.5j), 0.9999 * np.exp(-2.5j)])])
    rows = power_spectrum(ar, ma, w)
    z = np.exp(-1j * w)
    stacked = (np.abs(np.polynomial.polynomial.polyval(z, ma.T)) ** 2
               / np.abs(np.polynomial.polynomial.polyval(z, ar.T)) ** 2)
    np.testing.assert_array_equal(rows, stacked)  # numpy's polyval over the stack, as before
    assert rows.shape == (2, w.size)
    for k in range(2):
        np.testing.assert_array_equal(rows[k], power_spectrum(ar[k], ma[k], w))
        np.testing.assert_array_equal(power_spectrum(ar, ma[k:k + 1], w)[k], rows[k])  # one row serves every row
    with pytest.raises(ValueError, match="power_spectrum"):
        power_spectrum(ar, np.ones((3, 2)), w)


def test_step_down_is_the_numpy_recursion_bit_for_bit():
    """The compiled recursion does numpy's operations in numpy's order (the reduced models of flowtex.dsp.order)."""
    rng = np.random.default_rng(5)
    for _ in range(50):
        n = int(rng.integers(1, 30))
        a = _poly(rng.uniform(0.0, 0.999, n) * np.exp(1j * rng.uniform(-np.pi, np.pi, n)))  # complex roots, real part
        a = stabilize(a)
        order = int(rng.integers(0, n))
        ref = a.copy()
        for m in range(a.size - 1, order, -1):
            k = ref[m]
            ref = (ref[:m] - k * ref[m:0:-1]) / (1.0 - k * k)
        np.testing.assert_array_equal(step_down(a, order), ref)
