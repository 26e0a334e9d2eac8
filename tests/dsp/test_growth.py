"""``plugin check``'s divergence test (flowtex.dsp.growth.diverging): exponential growth is named, stable outputs are not.

The references are independent of the probe: scipy.signal's Butterworth designs (stable, their start-up rising fast for
high orders and low cutoffs), polynomials t**k and random walks (growing, but not exponentially), and first-order
recursions y = r y + x whose growth r**t is known.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from flowtex.dsp.growth import diverging
from flowtex.kernelprobe import TICKS

NOISE = np.random.default_rng(7).uniform(-1.0, 1.0, (TICKS, 1))  # what the probe feeds a kernel


def _recursion(r: float) -> np.ndarray:
    return signal.lfilter([1.0], [1.0, -r], NOISE, axis=0)


@pytest.mark.parametrize("r", [1.024, 1.05, 1.5, -2.14])  # -2.14: forward Euler's pole 1 - 2 pi 500/1000
def test_a_pole_outside_the_unit_circle_is_named(r):
    assert diverging(_recursion(r)) is not None


@pytest.mark.parametrize("r", [0.5, 0.999, 1.0, -1.0, 1.015])  # stable, marginal (a random walk), and too slow to see
def test_a_pole_on_or_inside_the_unit_circle_is_not(r):
    assert diverging(_recursion(r)) is None


def test_stable_filters_starting_up_and_polynomial_growth_are_not_divergence():
    for order in range(1, 33):
        for cutoff_hz in (0.01, 0.1, 1.0, 10.0):
            y = signal.sosfilt(signal.butter(order, cutoff_hz, fs=1000.0, output="sos"), NOISE, axis=0)
            assert diverging(y) is None, (order, cutoff_hz)
    t = np.arange(TICKS, dtype=np.float64)[:, None]
    for k in range(1, 80):
        assert diverging(t ** k) is None, k
    assert diverging(np.vstack([np.zeros((450, 1)), 1e9 * NOISE[:150]])) is None  # a late start is not growth
