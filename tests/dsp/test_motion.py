"""Speed estimator and contact kernels against scipy references and hand-worked values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import butter, lfilter

from flowtex.dsp.motion import (
    CONTACT_ISTATE,
    CONTACT_STATE,
    CS_NORMAL,
    SPEED_ISTATE,
    SPEED_STATE,
    SS_NORMAL,
    butter2_biquad,
    contact_block,
    first_order_biquad,
    initial_normal_state,
    speed_block,
    speed_params,
)

FS = 1000.0


def run_speed(pos, normal=(0.0, 0.0, 1.0), method="lowpass", cutoff=20.0, threshold=0.0, normals=None):
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    n = pos.shape[0]
    biquad = first_order_biquad(cutoff, FS) if method == "lowpass" else butter2_biquad(125.0, FS)
    p = speed_params(biquad, FS, threshold)
    s = initial_normal_state(SPEED_STATE, SS_NORMAL, normal)
    si = np.zeros(SPEED_ISTATE, np.int64)
    nrm = np.ascontiguousarray(np.broadcast_to(normal, (n, 3)) if normals is None else normals, dtype=np.float64)
    speed = np.empty((n, 1))
    vel = np.empty((n, 3))
    speed_block(p, s, si, pos, nrm, speed, vel)
    return speed[:, 0], vel


def backward_difference(pos):
    v = np.zeros_like(pos)
    v[1:] = np.diff(pos, axis=0) * FS
    return v


def smooth_path(n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    return np.stack([40 * np.sin(2 * np.pi * 1.3 * t) + rng.normal(0, 0.01, n),
                     25 * np.cos(2 * np.pi * 0.7 * t) + rng.normal(0, 0.01, n),
                     rng.normal(0, 0.01, n)], 1) + np.array([10.0, -5.0, 3.0])


def test_lowpass_matches_lfilter_of_backward_difference():
    pos = smooth_path(1500)
    speed, vel = run_speed(pos, cutoff=20.0)
    alpha = 1 - math.exp(-2 * math.pi * 20.0 / FS)
    ref = lfilter([alpha], [1.0, -(1.0 - alpha)], backward_difference(pos), axis=0)
    ref[:, 2] = 0.0  # tangential projection for the normal [0, 0, 1]
    np.testing.assert_allclose(vel, ref, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(speed, np.linalg.norm(ref, axis=1), rtol=1e-10, atol=1e-9)


def test_hatt_matches_scipy_butterworth_at_125_rad_s():
    pos = smooth_path(1500, seed=1)
    speed, vel = run_speed(pos, method="hatt")
    b, a = butter(2, 125.0 / (2 * np.pi), fs=FS)
    ref = lfilter(b, a, backward_difference(pos), axis=0)
    ref[:, 2] = 0.0
    np.testing.assert_allclose(vel, ref, rtol=1e-9, atol=1e-8)
    np.testing.assert_allclose(speed, np.linalg.norm(ref, axis=1), rtol=1e-9, atol=1e-8)


def test_hatt_filter_corner_is_125_rad_s():
    b0, b1, b2, a1, a2 = butter2_biquad(125.0, FS)
    z = np.exp(1j * 125.0 / FS)
    h = (b0 + b1 / z + b2 / z**2) / (1 + a1 / z + a2 / z**2)
    assert abs(h) == pytest.approx(1 / math.sqrt(2), rel=1e-12)
    assert (b0 + b1 + b2) / (1 + a1 + a2) == pytest.approx(1.0, rel=1e-12)


def test_motion_along_the_normal_gives_zero_speed():
    normal = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    t = np.arange(600) / FS
    along = np.outer(30 * np.sin(2 * np.pi * 2 * t), normal)
    speed, vel = run_speed(along, normal=(2.0, 2.0, 2.0))  # the normal need not be unit length
    assert np.max(speed) < 1e-9
    assert np.max(np.abs(vel)) < 1e-9
    # perpendicular motion at 50 mm/s reaches full speed, with velocity in the tangent plane
    tangent = np.array([1.0, -1.0, 0.0]) / math.sqrt(2)
    speed, vel = run_speed(np.outer(50 * t, tangent) + along, normal=normal)
    assert speed[-1] == pytest.approx(50.0, rel=1e-6)
    np.testing.assert_allclose(vel[-1], 50 * tangent, rtol=1e-6, atol=1e-9)


def test_normal_input_is_used_per_tick_and_bad_normals_keep_the_last():
    t = np.arange(400) / FS
    pos = np.stack([60 * t, 0 * t, 0 * t], 1)
    normals = np.tile([0.0, 0.0, 1.0], (400, 1))
    normals[200:] = [1.0, 0.0, 0.0]  # now the motion is along the normal
    normals[250:260] = np.nan
    normals[300:310] = 0.0
    speed, _ = run_speed(pos, normals=normals, cutoff=200.0)
    assert speed[199] == pytest.approx(60.0, rel=1e-6)
    assert np.max(speed[200:]) < 1e-9


def test_stationary_jitter_gives_exactly_zero_and_motion_passes():
    rng = np.random.default_rng(3)
    n = 2000
    jitter = rng.uniform(-0.02, 0.02, (n, 3)) + np.array([5.0, 7.0, 1.0])
    speed, vel = run_speed(jitter, threshold=0.06)
    assert np.all(speed == 0.0) and np.all(vel == 0.0)
    # the same jitter without the gate gives a clearly non-zero speed
    speed_raw, _ = run_speed(jitter, threshold=0.0)
    assert np.mean(speed_raw) > 1.0
    # steady sliding at 50 mm/s: filtered displacement ~ 50/(2 pi 10) = 0.8 mm > 0.06 mm
    t = np.arange(n) / FS
    slide = jitter + np.stack([50 * t, 0 * t, 0 * t], 1)
    speed, _ = run_speed(slide, threshold=0.06)
    assert np.all(speed[500:] > 40.0)
    assert np.mean(speed[1000:]) == pytest.approx(50.0, rel=0.02)


def test_nan_positions_hold_outputs_and_do_not_poison_state():
    n = 400
    t = np.arange(n) / FS
    pos = np.stack([30 * t, -20 * t, 0 * t], 1)
    clean_speed, clean_vel = run_speed(pos)
    bad = pos.copy()
    bad[100:110, 0] = np.nan
    bad[150, 1] = np.inf
    bad[0:3] = np.nan  # before the first valid sample
    speed, vel = run_speed(bad)
    assert np.all(np.isfinite(speed)) and np.all(np.isfinite(vel))
    assert np.all(speed[:3] == 0.0)
    np.testing.assert_array_equal(speed[100:110], speed[99])
    # constant velocity: the gap-averaged derivative equals the true one, so the
    # filter resumes exactly where it stopped, delayed by the gap
    np.testing.assert_allclose(speed[110:150], clean_speed[110 - 3 - 10:150 - 3 - 10], rtol=1e-9)
    assert speed[-1] == pytest.approx(math.hypot(30, 20), rel=1e-6)


def test_block_split_gives_identical_numbers():
    pos = smooth_path(700, seed=5)
    pos[300:305] = np.nan
    whole, vwhole = run_speed(pos, threshold=0.06)
    biquad = first_order_biquad(20.0, FS)
    p = speed_params(biquad, FS, 0.06)
    s = initial_normal_state(SPEED_STATE, SS_NORMAL, (0, 0, 1))
    si = np.zeros(SPEED_ISTATE, np.int64)
    nrm = np.tile([0.0, 0.0, 1.0], (700, 1))
    out = np.empty((700, 1))
    vout = np.empty((700, 3))
    for lo, hi in [(0, 1), (1, 301), (301, 302), (302, 700)]:
        o = np.empty((hi - lo, 1))
        v = np.empty((hi - lo, 3))
        speed_block(p, s, si, np.ascontiguousarray(pos[lo:hi]), np.ascontiguousarray(nrm[lo:hi]), o, v)
        out[lo:hi] = o
        vout[lo:hi] = v
    np.testing.assert_array_equal(out[:, 0], whole)
    np.testing.assert_array_equal(vout, vwhole)


def run_contact(force, pos, normal=(0.0, 0.0, 1.0), on=0.1, off=0.05):
    force = np.ascontiguousarray(np.asarray(force, dtype=np.float64).reshape(-1, 1))
    n = force.shape[0]
    p = np.array([FS, on, off])
    s = initial_normal_state(CONTACT_STATE, CS_NORMAL, normal)
    si = np.zeros(CONTACT_ISTATE, np.int64)
    nrm = np.ascontiguousarray(np.broadcast_to(normal, (n, 3)), dtype=np.float64)
    outs = [np.empty((n, 1)) for _ in range(3)]
    contact_block(p, s, si, force, np.ascontiguousarray(pos, dtype=np.float64), nrm, *outs)
    return [o[:, 0] for o in outs]


def test_contact_hysteresis_onset_and_incoming_speed():
    force = [0.0, 0.06, 0.12, 0.08, 0.051, 0.049, 0.07, 0.1, 0.2, 0.0, np.nan, 0.3]
    n = len(force)
    z = -20.0 * np.arange(n) / FS  # approaching along -normal at 20 mm/s
    pos = np.stack([np.full(n, 3.0), np.zeros(n), z], 1)
    pos[9:] = pos[8]  # stop moving
    pos[11] = pos[8] + [0.0, 0.0, -0.005]  # 5 mm/s approach on the last tick
    in_c, incoming, onset = run_contact(force, pos)
    np.testing.assert_array_equal(in_c, [0, 0, 1, 1, 1, 0, 0, 1, 1, 0, 0, 1])
    np.testing.assert_array_equal(onset, [0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1])
    np.testing.assert_allclose(incoming, [0, 0, 20, 20, 20, 0, 0, 20, 20, 0, 0, 5], rtol=1e-9)


def test_incoming_speed_along_a_tilted_normal_and_receding_tool():
    normal = np.array([0.0, 1.0, 1.0]) / math.sqrt(2)
    n = 5
    vel = np.array([7.0, -10.0, -10.0])  # mm/s: approach speed 20/sqrt(2), tangential part ignored
    pos = np.outer(np.arange(n) / FS, vel)
    _, incoming, onset = run_contact([0, 0, 0, 1, 1], pos, normal=normal)
    assert onset[3] == 1.0
    assert incoming[3] == pytest.approx(20 / math.sqrt(2), rel=1e-9)
    _, incoming, _ = run_contact([0, 0, 0, 1, 1], -pos, normal=normal)
    assert incoming[3] == 0.0  # moving away: no incoming speed


def test_overflowing_jumps_are_skipped_like_nan():
    t = np.arange(300) / FS
    pos = np.stack([30 * t, 0 * t, 0 * t], 1)
    bad = pos.copy()
    bad[100] = [1e300, -1e300, 0.0]
    speed, vel = run_speed(bad)
    assert np.all(np.isfinite(speed)) and np.all(np.isfinite(vel))
    assert speed[-1] == pytest.approx(30.0, rel=1e-6)
    force = np.ones(300)
    force[:50] = 0.0
    _, incoming, _ = run_contact(force, bad)
    assert np.all(np.isfinite(incoming))
