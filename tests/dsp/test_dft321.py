"""Offline DFT321: Parseval, one moving axis, collinear axes (analytic), a full-spectrum reference, bad input.

Tolerances: float64 FFT round-off on a few thousand samples is ~1e-13
relative; 1e-10 leaves room and still fails on any real mistake.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.dsp.dft321 import dft321


def noise3(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n, 3)) * np.array([1.0, 0.3, 2.0])
    x[:, 1] += np.sin(2 * np.pi * 0.05 * np.arange(n))  # different spectra per axis
    return x


@pytest.mark.parametrize("n", [1, 2, 7, 8, 1001, 1024])
def test_total_power_is_the_sum_of_the_axes_powers(n: int) -> None:
    x = noise3(n, seed=n)
    y = dft321(x)
    assert y.shape == (n,)
    assert y.dtype == np.float64
    np.testing.assert_allclose(np.sum(y * y), np.sum(x * x), rtol=1e-10)


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("n", [999, 1000])
def test_one_moving_axis_is_given_back_exactly(axis: int, n: int) -> None:
    # The phase of A_x + 0 + 0 is A_x's own phase, so no sign ambiguity: y == x[:, axis].
    x = np.zeros((n, 3))
    x[:, axis] = noise3(n, seed=3)[:, 0] + 0.5  # with a DC offset: DC bin keeps its sign
    np.testing.assert_allclose(dft321(x), x[:, axis], rtol=0, atol=1e-12 * np.max(np.abs(x)))
    np.testing.assert_allclose(dft321(-x), -x[:, axis], rtol=0, atol=1e-12 * np.max(np.abs(x)))


@pytest.mark.parametrize("gains", [(1.0, 2.0, -0.5), (-1.0, -2.0, 0.5)])
def test_collinear_axes_give_the_scaled_signal_with_the_sign_of_their_sum(gains) -> None:
    # Axes g_i * s: A_s = sqrt(sum g_i^2) |S| with the phase of (sum g_i) S.
    s = noise3(500, seed=5)[:, 2]
    g = np.array(gains)
    expected = np.sign(g.sum()) * np.sqrt(np.sum(g * g)) * s
    np.testing.assert_allclose(dft321(s[:, None] * g[None, :]), expected, rtol=0, atol=1e-12 * np.max(np.abs(expected)))


def test_matches_a_two_sided_reference() -> None:
    # Independent path: full complex FFT over all n bins, per-bin formula, complex inverse.
    x = noise3(257, seed=9)
    a = np.fft.fft(x, axis=0)
    s = a.sum(axis=1)
    ref = np.fft.ifft(np.sqrt(np.sum(np.abs(a) ** 2, axis=1)) * np.exp(1j * np.angle(s)))
    assert np.max(np.abs(ref.imag)) < 1e-12
    np.testing.assert_allclose(dft321(x), ref.real, rtol=0, atol=1e-12)


def test_cancelling_axes_keep_their_power() -> None:
    # x + (-x) + 0: the sum is zero at every bin, the phase is taken as 0; power is still the sum.
    s = noise3(64, seed=2)[:, 0]
    x = np.stack([s, -s, np.zeros_like(s)], axis=1)
    y = dft321(x)
    np.testing.assert_allclose(np.sum(y * y), 2 * np.sum(s * s), rtol=1e-10)
    np.testing.assert_allclose(np.abs(np.fft.rfft(y)), np.sqrt(2) * np.abs(np.fft.rfft(s)), atol=1e-10)


def test_zero_and_empty_input() -> None:
    assert np.all(dft321(np.zeros((10, 3))) == 0.0)
    assert dft321(np.zeros((0, 3))).shape == (0,)


@pytest.mark.parametrize("bad", [np.zeros((10, 2)), np.zeros(10), np.zeros((3, 10, 1))])
def test_wrong_shape_is_rejected(bad) -> None:
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        dft321(bad)


def test_non_finite_input_is_rejected() -> None:
    x = np.zeros((10, 3))
    x[4, 1] = np.nan
    with pytest.raises(ValueError, match="sample 4"):
        dft321(x)
