"""Coulomb/viscous and Dahl friction against analytic values and a plain-Python transcription of 002 eqs. (1)-(2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtex.dsp.friction import (
    DAHL_ISTATE,
    DAHL_STATE,
    DS_NORMAL,
    coulomb_block,
    coulomb_threshold,
    dahl_block,
)
from flowtex.dsp.motion import initial_normal_state


def coulomb(mu, mode, vel, fn):
    vel = np.ascontiguousarray(np.atleast_2d(vel), dtype=np.float64)
    fn = np.ascontiguousarray(np.broadcast_to(np.asarray(fn, dtype=np.float64), (vel.shape[0],)).reshape(-1, 1))
    out = np.empty_like(vel)
    coulomb_block(np.array([mu, coulomb_threshold(mu, mode)]), vel, fn, out)
    return out


DIRECTION = np.array([3.0, -4.0, 0.0]) / 5.0


@pytest.mark.parametrize("speed", [0.0, 1e-3, 10.0, 74.0, 74.999999, 75.0, 75.000001, 80.0, 300.0, 1e4])
def test_hatt_rule_exact(speed):
    mu, fn = 0.3, 2.0
    f = coulomb(mu, "hatt", speed * DIRECTION, fn)[0]
    vth = mu / 0.004  # 75 mm/s
    expected = -mu * fn * 0.004 * speed * DIRECTION if speed < vth else -mu * fn * DIRECTION
    np.testing.assert_allclose(f, expected, rtol=1e-13, atol=1e-15)


def test_hatt_rule_jumps_from_mu2_fn_to_mu_fn_at_threshold():
    mu, fn = 0.3, 2.0
    below = np.linalg.norm(coulomb(mu, "hatt", np.nextafter(75.0, 0.0) * DIRECTION, fn)[0])
    at = np.linalg.norm(coulomb(mu, "hatt", 75.0 * DIRECTION, fn)[0])
    assert below == pytest.approx(mu * mu * fn, rel=1e-12)
    assert at == pytest.approx(mu * fn, rel=1e-12)


@pytest.mark.parametrize("speed", [0.0, 50.0, 249.0, 249.9999999, 250.0, 250.0000001, 251.0, 1000.0])
def test_continuous_rule_and_continuity_at_250(speed):
    mu, fn = 0.45, 1.5
    f = coulomb(mu, "continuous", speed * DIRECTION, fn)[0]
    expected = -mu * fn * 0.004 * speed * DIRECTION if speed < 250.0 else -mu * fn * DIRECTION
    np.testing.assert_allclose(f, expected, rtol=1e-12, atol=1e-15)
    # continuity: within 1e-6 mm/s of 250 the magnitude is within mu F_n 0.004 * 1e-6 of mu F_n
    if abs(speed - 250.0) < 1e-6:
        assert abs(np.linalg.norm(f) - mu * fn) < mu * fn * 0.004 * 1e-6 + 1e-15


def test_force_opposes_velocity_in_every_direction():
    rng = np.random.default_rng(0)
    vel = rng.normal(0, 200, (200, 3))
    for mode in ("continuous", "hatt"):
        f = coulomb(0.6, mode, vel, 0.8)
        cos = np.sum(f * vel, axis=1) / (np.linalg.norm(f, axis=1) * np.linalg.norm(vel, axis=1))
        np.testing.assert_allclose(cos, -1.0, atol=1e-12)
        assert np.all(np.linalg.norm(f, axis=1) <= 0.6 * 0.8 * (1 + 1e-12))


def test_coulomb_bad_inputs_give_zero_force():
    vel = np.array([[np.nan, 1.0, 0.0], [10.0, 0.0, 0.0], [10.0, 0.0, 0.0], [np.inf, 0.0, 0.0]])
    f = coulomb(0.5, "continuous", vel, np.array([1.0, np.nan, -2.0, 1.0]))
    np.testing.assert_array_equal(f, 0.0)


# ---------------------------------------------------------------- Dahl -----

def dahl(pos, fn, mu, zmax, normal=(0.0, 0.0, 1.0), normals=None, chunks=None):
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    n = pos.shape[0]
    fn = np.ascontiguousarray(np.broadcast_to(np.asarray(fn, dtype=np.float64), (n,)).reshape(n, 1))
    nrm = np.ascontiguousarray(np.broadcast_to(normal, (n, 3)) if normals is None else normals, dtype=np.float64)
    p = np.array([mu, zmax])
    s = initial_normal_state(DAHL_STATE, DS_NORMAL, normal)
    si = np.zeros(DAHL_ISTATE, np.int64)
    out = np.empty((n, 3))
    bounds = chunks or [0, n]
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        o = np.empty((hi - lo, 3))
        dahl_block(p, s, si, pos[lo:hi], fn[lo:hi], nrm[lo:hi], o)
        out[lo:hi] = o
    return out


def published_dahl_1d(x, fn, mu, zmax):
    """002 eqs. (1)-(2) transcribed literally (force sign: opposing the stretch)."""
    w = x[0]
    forces = [0.0]
    for i in range(1, len(x)):
        if abs(x[i] - w) > zmax:
            w = x[i] - math.copysign(1.0, x[i] - x[i - 1]) * zmax
        z = x[i] - w
        forces.append(-mu * fn[i] * z / zmax)
    return np.array(forces)


def on_x(x):
    return np.stack([x, np.zeros_like(x), np.zeros_like(x)], 1)


def test_dahl_matches_the_published_equations_on_a_1d_path():
    rng = np.random.default_rng(7)
    x = np.cumsum(rng.normal(0, 0.15, 3000)) + 4.0  # many reversals, stick and slip
    mu = 0.35
    zmax = 4.0 * mu
    fn = np.full(x.size, 1.7)
    f = dahl(on_x(x), fn, mu, zmax)
    np.testing.assert_allclose(f[:, 0], published_dahl_1d(x, fn, mu, zmax), rtol=1e-12, atol=1e-13)
    assert np.all(f[:, 1:] == 0.0)
    # chunked calls give identical numbers
    np.testing.assert_array_equal(dahl(on_x(x), fn, mu, zmax, chunks=[0, 1, 17, 1024, 1025, 3000]), f)


def test_dahl_ramp_and_reversal_analytic():
    mu, fn = 0.5, 2.0
    zmax = 4.0 * mu  # 2 mm
    up = 0.1 * np.arange(31)  # 0 .. 3 mm
    down = 3.0 - 0.1 * np.arange(1, 61)  # back to -3 mm
    x = np.concatenate([up, down])
    f = dahl(on_x(x), fn, mu, zmax)[:, 0]
    k = mu * fn / zmax
    np.testing.assert_allclose(f[:31], -k * np.minimum(up, zmax), rtol=1e-12, atol=1e-12)
    # at x = 3 the adhesion point is at 1; going back the spring unloads linearly until x = -1
    expected_down = np.where(down >= -1.0, -k * (down - 1.0), mu * fn)
    np.testing.assert_allclose(f[31:], expected_down, rtol=1e-10, atol=1e-10)


def work_and_energy(pos, f, fn, mu, zmax):
    """Work by the friction force on the tool, W = sum F_i . (x_i - x_{i-1}), and the final stored energy."""
    w = np.sum(f[1:] * np.diff(pos, axis=0))
    z = -f[-1] * zmax / (mu * fn[-1]) if fn[-1] > 0 else np.zeros(3)
    return w, mu * fn[-1] * np.dot(z, z) / (2 * zmax)


def closed_paths():
    rng = np.random.default_rng(11)
    t = np.linspace(0, 1, 2001)
    yield "circle", np.stack([3 * np.cos(2 * np.pi * 3 * t), 3 * np.sin(2 * np.pi * 3 * t), 0 * t], 1)
    yield "back-and-forth", np.stack([2.5 * np.sin(2 * np.pi * 5 * t), 0 * t, 0 * t], 1)
    yield "small-circle", np.stack([0.3 * np.cos(2 * np.pi * 4 * t), 0.3 * np.sin(2 * np.pi * 4 * t), 0 * t], 1)
    for k in range(5):
        pts = rng.normal(0, 2, (8, 2))
        pts = np.vstack([pts, pts[:1]])
        seg = np.concatenate([np.linspace(a, b, 60, endpoint=False) for a, b in zip(pts[:-1], pts[1:], strict=True)] + [pts[-1:]])
        seg += rng.normal(0, 0.01, seg.shape) * (np.arange(len(seg)) % 50 != 0)[:, None]
        seg[-1] = seg[0]
        yield f"random-{k}", np.column_stack([seg, np.zeros(len(seg))])


@pytest.mark.parametrize("name,path", list(closed_paths()))
def test_dahl_is_passive_on_closed_paths_at_constant_normal_force(name, path):
    mu, fn = 0.4, 1.2
    zmax = 4 * mu
    fns = np.full(len(path), fn)
    f = dahl(path, fns, mu, zmax)
    work, energy = work_and_energy(path, f, fns, mu, zmax)
    assert work <= 0.0
    assert -work >= energy - 1e-12  # dissipated at least what is still stored


def test_dahl_in_a_tilted_plane_is_passive_and_ignores_normal_motion():
    normal = np.array([1.0, 2.0, 2.0]) / 3.0
    e1 = np.array([2.0, -1.0, 0.0]) / math.sqrt(5)
    e2 = np.cross(normal, e1)
    t = np.linspace(0, 1, 1500)
    path = np.outer(2 * np.cos(2 * np.pi * 2 * t), e1) + np.outer(2 * np.sin(2 * np.pi * 2 * t), e2)
    f = dahl(path, 1.0, 0.5, 2.0, normal=tuple(normal))
    assert np.max(np.abs(f @ normal)) < 1e-12
    w, _ = work_and_energy(path, f, np.ones(len(t)), 0.5, 2.0)
    assert w < 0.0
    f_normal = dahl(np.outer(np.sin(np.linspace(0, 20, 500)), normal), 1.0, 0.5, 2.0, normal=tuple(normal))
    assert np.max(np.abs(f_normal)) < 1e-12


def test_rising_normal_force_never_increases_stored_energy():
    mu, zmax = 0.5, 2.0
    # stretch the spring by 1 mm at 0.5 N, hold still while F_n rises to 3 N, then return
    x = np.concatenate([np.linspace(0, 1, 11), np.ones(20), np.linspace(1, 0, 11)])
    fn = np.concatenate([np.full(11, 0.5), np.linspace(0.5, 3.0, 20), np.full(11, 3.0)])
    f = dahl(on_x(x), fn, mu, zmax)
    z = -f[:, 0] * zmax / (mu * fn)
    energy = mu * fn * z * z / (2 * zmax)
    assert np.all(np.diff(energy[10:31]) <= 1e-15)  # stuck ticks: no energy gained
    np.testing.assert_allclose(energy[10:31], energy[10], rtol=1e-12)  # and none lost either (the rescale keeps it)
    work = np.sum(f[1:, 0] * np.diff(x))
    assert work <= 0.0
    # the published model, transcribed literally, gains energy on the same path
    w_pub = np.sum(published_dahl_1d(x, fn, mu, zmax)[1:] * np.diff(x))
    assert w_pub > 0.0


def test_random_paths_with_random_normal_force_are_passive():
    rng = np.random.default_rng(5)
    mu, zmax = 0.6, 2.4
    for _ in range(20):
        n = 800
        xy = np.cumsum(rng.normal(0, 0.2, (n, 2)), axis=0)
        path = np.column_stack([xy, rng.normal(0, 0.1, n)])
        fn = np.abs(np.cumsum(rng.normal(0, 0.1, n))) * (rng.random(n) > 0.05)  # includes lift-offs (F_n = 0)
        f = dahl(path, fn, mu, zmax)
        work = np.sum(f[1:] * np.diff(path, axis=0))
        assert work <= 1e-12


def test_dahl_nan_inputs_give_zero_and_are_skipped():
    rng = np.random.default_rng(2)
    x = np.cumsum(rng.normal(0, 0.2, 300))
    pos = on_x(x)
    fn = np.full(300, 1.0)
    bad_pos = pos.copy()
    bad_pos[50] = np.nan
    bad_fn = fn.copy()
    bad_fn[120] = np.nan
    f = dahl(bad_pos, bad_fn, 0.4, 1.6)
    assert np.all(np.isfinite(f))
    assert np.all(f[[50, 120]] == 0.0)
    keep = np.ones(300, bool)
    keep[[50, 120]] = False
    np.testing.assert_allclose(f[keep], dahl(pos[keep], fn[keep], 0.4, 1.6), rtol=1e-12, atol=1e-14)


def test_negative_normal_force_counts_as_zero():
    x = np.linspace(0, 3, 31)
    f = dahl(on_x(x), -1.0, 0.4, 1.6)
    np.testing.assert_array_equal(f, 0.0)


def test_zero_order_hold_pairing_leak_is_bounded_by_half_k_step_squared():
    # docs/friction.md: sum F_i . (x_{i+1} - x_i) <= k/2 sum |P dx|^2 - E_end (sampled-spring leak)
    rng = np.random.default_rng(9)
    mu, fn, zmax = 0.5, 1.0, 2.0
    k = mu * fn / zmax
    for _ in range(10):
        path = np.column_stack([np.cumsum(rng.normal(0, 0.3, (500, 2)), axis=0), np.zeros(500)])
        f = dahl(path, fn, mu, zmax)
        steps = np.diff(path, axis=0)
        w_hold = np.sum(f[:-1] * steps)
        _, energy = work_and_energy(path, f, np.full(500, fn), mu, zmax)
        assert w_hold <= k / 2 * np.sum(steps**2) - energy + 1e-12
    # and it is a real leak: a stuck back-and-forth stroke gains energy under this pairing
    x = 0.5 * np.sin(np.linspace(0, 8 * np.pi, 401))
    f = dahl(on_x(x), fn, mu, zmax)
    assert np.sum(f[:-1, 0] * np.diff(x)) > 0.0


def test_overflowing_inputs_never_poison_the_state():
    x = np.linspace(0, 3, 40)
    pos = on_x(x)
    bad = pos.copy()
    bad[10] = [1e300, -1e300, 0.0]
    f = dahl(bad, 1.0, 0.4, 1.6)
    assert np.all(np.isfinite(f)) and np.all(f[10] == 0.0)
    keep = np.arange(40) != 10
    np.testing.assert_allclose(f[keep], dahl(pos[keep], 1.0, 0.4, 1.6), rtol=1e-12, atol=1e-14)
    vel = np.array([[1e300, 1e300, 0.0], [10.0, 0.0, 0.0]])
    out = coulomb(0.5, "hatt", vel, np.array([1e300, 1.0]))
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out[1], [-0.5 * 0.004 * 10.0, 0.0, 0.0], rtol=1e-12)
