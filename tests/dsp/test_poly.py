"""flowtex.dsp.poly against independent references: numpy roots, scipy.signal.freqz / dimpulse, Yule-Walker."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from flowtex.dsp.poly import MAX_RADIUS, impulse_response, is_stable, power_spectrum, root_power_spectrum, roots_inside, stabilize, step_down


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
