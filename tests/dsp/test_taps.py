"""Tap playback kernel: every branch of ALGORITHMS §6 checked against hand-computed transients."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.dsp.taps import initial_tap_state, tap_block, tap_params

SPEEDS = np.array([20.0, 50.0, 100.0])
T = np.array([[1.0, -2.0, 3.0, -4.0, 5.0],
              [10.0, 20.0, -30.0, 40.0, 0.5],
              [-7.0, 0.0, 7.0, 1.0, -1.0]])
MASS = 0.05


def play(contact, speed, mass=MASS, speeds=SPEEDS, transients=T, chunks=None):
    contact = np.ascontiguousarray(np.asarray(contact, dtype=np.float64).reshape(-1, 1))
    n = contact.shape[0]
    speed = np.ascontiguousarray(np.broadcast_to(np.asarray(speed, dtype=np.float64), (n,)).reshape(n, 1))
    p = tap_params(mass, speeds, transients)
    s, si = initial_tap_state(transients.shape[1])
    out = np.empty((n, 1))
    bounds = chunks or [0, n]
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        o = np.empty((hi - lo, 1))
        tap_block(p, s, si, contact[lo:hi], speed[lo:hi], o)
        out[lo:hi] = o
    return out[:, 0]


def single_tap(v):
    contact = [0, 0, 1, 1, 1, 1, 1, 1, 1, 1]
    return play(contact, v)


@pytest.mark.parametrize("v,expected", [
    (10.0, 0.5 * T[0]),                 # below the slowest: scaled by v / v_min
    (20.0, T[0]),                       # exactly the slowest
    (35.0, 0.5 * T[0] + 0.5 * T[1]),    # halfway between 20 and 50
    (50.0, T[1]),
    (80.0, 0.4 * T[1] + 0.6 * T[2]),    # (80-50)/(100-50) = 0.6
    (100.0, T[2]),
    (250.0, T[2]),                      # above the fastest: played as is
])
def test_each_branch(v, expected):
    out = single_tap(v)
    np.testing.assert_array_equal(out[:2], 0.0)
    np.testing.assert_allclose(out[2:7], MASS * expected, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(out[7:], 0.0)  # playback ends after L samples


@pytest.mark.parametrize("v", [0.0, -5.0, np.nan])
def test_no_incoming_speed_is_silent(v):
    np.testing.assert_array_equal(single_tap(v), 0.0)


def test_new_contact_restarts_and_speed_is_read_at_onset_only():
    contact = [1, 1, 1, 0, 1, 1, 1, 1, 1, 1, 1, 1]
    speed = [50, 999, 999, 999, 10, 999, 999, 999, 999, 999, 999, 999]
    out = play(contact, speed)
    expected = np.zeros(12)
    expected[0:3] = MASS * T[1][:3]            # first tap, cut short by the new contact
    expected[3] = MASS * T[1][3]               # still playing through the release tick
    expected[4:9] = MASS * 0.5 * T[0]          # second tap from its own start
    np.testing.assert_allclose(out, expected, rtol=1e-13, atol=1e-15)


def test_nan_contact_keeps_previous_state_and_chunks_match():
    contact = [0, 1, np.nan, 1, 0, np.nan, 1, 1, 1, 1, 1, 0]
    out = play(contact, 100.0)
    expected = np.zeros(12)
    expected[1:6] = MASS * T[2]
    expected[6:11] = MASS * T[2]
    np.testing.assert_allclose(out, expected, rtol=1e-13)
    np.testing.assert_array_equal(play(contact, 100.0, chunks=[0, 1, 2, 5, 6, 12]), out)


def test_single_speed_library():
    speeds = np.array([40.0])
    tr = T[:1]
    contact = [1, 1, 1, 1, 1]
    np.testing.assert_allclose(play(contact, 10.0, speeds=speeds, transients=tr), MASS * 0.25 * T[0])
    np.testing.assert_allclose(play(contact, 400.0, speeds=speeds, transients=tr), MASS * T[0])
