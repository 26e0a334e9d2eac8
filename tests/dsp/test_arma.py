"""Normalized lattice-ladder ARMA synthesis: exact transfer function, statistics, switching, invalid models.

References: scipy.signal.lfilter / freqz on the same excitation (regenerated
from flowtex.dsp.rng with the same seed), analytic variance sums, and a
direct-form time-varying filter written here.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from flowtex.dsp.arma import (
    _offsets,
    arma_impulse_response,
    arma_lattice_block,
    arma_output_variance,
    arma_psd,
    arma_psd_rows,
    lattice_ladder_coefficients,
    new_state,
)
from flowtex.dsp.lsf import lsf_to_poly_new
from flowtex.dsp.rng import next_normal, seed_rng
from flowtex.dsp.spectral import gfc, welch_psd
from tests.power_reference import lyapunov_power

RATE = 1000.0


def poly_from_roots(roots) -> np.ndarray:
    return np.real(np.poly(np.asarray(roots))) if len(roots) else np.ones(1)


def conj_pairs(radii, angles, real=()) -> list[complex]:
    out: list[complex] = []
    for r, th in zip(radii, angles, strict=True):
        out += [r * np.exp(1j * th), r * np.exp(-1j * th)]
    return out + list(real)


def model_19_17(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """An AR(19)/MA(17) pair of the size of real HaTT surfaces, built from chosen roots."""
    rng = np.random.default_rng(seed)
    a = poly_from_roots(conj_pairs(rng.uniform(0.7, 0.97, 9), np.sort(rng.uniform(0.05, 3.1, 9)), [rng.uniform(-0.8, 0.8)]))
    c = poly_from_roots(conj_pairs(rng.uniform(0.5, 0.95, 8), np.sort(rng.uniform(0.05, 3.1, 8)), [rng.uniform(-0.8, 0.8)]))
    return a, c


def run(ar, ma, gain, variance, seed: int = 1, chunks=None):
    """Run the kernel on per-tick model arrays; returns y (n,)."""
    ar = np.ascontiguousarray(ar, dtype=np.float64)
    ma = np.ascontiguousarray(ma, dtype=np.float64)
    n = ar.shape[0]
    gain = np.ascontiguousarray(np.broadcast_to(np.asarray(gain, dtype=np.float64).reshape(-1, 1), (n, 1)))
    variance = np.ascontiguousarray(np.broadcast_to(np.asarray(variance, dtype=np.float64).reshape(-1, 1), (n, 1)))
    s, si = new_state(ar.shape[1] - 1, ma.shape[1] - 1)
    seed_rng(si, s, np.random.SeedSequence(seed))
    y = np.zeros((n, 1))
    bounds = [0, n] if chunks is None else [0, *chunks, n]
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        arma_lattice_block(s, si, ar[lo:hi], ma[lo:hi], gain[lo:hi], variance[lo:hi], y[lo:hi])
    return y[:, 0], s, si


def fixed(a, c, n):
    return np.tile(a, (n, 1)), np.tile(c, (n, 1))


def normals(seed: int, n: int) -> np.ndarray:
    """The excitation the kernel draws: one flowtex.dsp.rng normal per tick."""
    si = np.zeros(5, np.int64)
    sf = np.zeros(1)
    seed_rng(si, sf, np.random.SeedSequence(seed))
    return np.array([next_normal(si, sf) for _ in range(n)])


@pytest.mark.parametrize("p,q", [(0, 0), (1, 0), (0, 3), (2, 2), (5, 3), (3, 6), (19, 17)])
def test_block_equals_lfilter_on_the_same_excitation(p: int, q: int) -> None:
    rng = np.random.default_rng(p * 100 + q)
    a = poly_from_roots(conj_pairs(rng.uniform(0.5, 0.98, p // 2), rng.uniform(0.1, 3.0, p // 2), rng.uniform(-0.9, 0.9, p % 2)))
    c = poly_from_roots(conj_pairs(rng.uniform(0.3, 0.95, q // 2), rng.uniform(0.1, 3.0, q // 2), rng.uniform(-0.9, 0.9, q % 2)))
    g, var, n = 1.7, 0.3, 3000
    y, _, _ = run(*fixed(a, c, n), g, var)
    ref = scipy.signal.lfilter(g * c, a, np.sqrt(var) * normals(1, n))
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-10 * np.abs(ref).max())


@pytest.mark.parametrize("p,q", [(2, 1), (6, 4), (19, 17), (3, 8)])
def test_impulse_response_of_the_lattice_ladder(p: int, q: int) -> None:
    """The lattice-ladder realises exactly g C(z)/A(z): impulse response vs scipy.signal.lfilter."""
    rng = np.random.default_rng(p + 7 * q)
    a = poly_from_roots(conj_pairs(rng.uniform(0.8, 0.995, p // 2), rng.uniform(0.1, 3.0, p // 2), rng.uniform(-0.9, 0.9, p % 2)))
    c = poly_from_roots(conj_pairs(rng.uniform(0.3, 0.99, q // 2), rng.uniform(0.1, 3.0, q // 2), rng.uniform(-0.9, 0.9, q % 2)))
    g, n = 0.8, 2000
    ar, ma = fixed(a, c, n)
    # variance 1 on the first tick only, scaled so that the first excitation is exactly 1: an impulse
    e0 = normals(5, 1)[0]
    variance = np.zeros(n)
    variance[0] = 1.0 / e0**2
    y, _, _ = run(ar, ma, g, variance, seed=5)
    y = y * np.sign(e0)  # the excitation was sqrt(variance) * e0 = sign(e0)
    ref = scipy.signal.lfilter(g * c, a, np.r_[1.0, np.zeros(n - 1)])
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-10 * max(1.0, np.abs(ref).max()))
    np.testing.assert_allclose(arma_impulse_response(a, c, g, n), ref, rtol=0, atol=1e-14 * np.abs(ref).max())


def test_output_variance_and_psd_helpers_match_independent_references() -> None:
    a, c = model_19_17(3)
    g, var = 0.6, 2.5
    h = scipy.signal.lfilter(c, a, np.r_[1.0, np.zeros(20000)])
    np.testing.assert_allclose(arma_output_variance(a, c, g, var), var * g * g * np.sum(h * h), rtol=1e-9)
    freqs = np.linspace(0, 500, 257)
    _, resp = scipy.signal.freqz(g * c, a, worN=freqs, fs=RATE)
    expect = var * np.abs(resp) ** 2 / RATE
    expect[1:-1] *= 2.0
    np.testing.assert_allclose(arma_psd(a, c, g, var, freqs, RATE), expect, rtol=1e-10)
    # the one-sided PSD integrates to the variance
    fine = np.linspace(0, 500, 200001)
    total = np.trapezoid(arma_psd(a, c, g, var, fine, RATE), fine)
    np.testing.assert_allclose(total, arma_output_variance(a, c, g, var), rtol=1e-3)
    with pytest.raises(ValueError):
        arma_output_variance(np.real(np.poly([1.01])), c, g, var)


def test_psd_rows_equal_each_models_own_psd_bit_for_bit() -> None:
    """arma_psd_rows (flowtex.fit.quality's path evaluations) gives each model's arma_psd exactly: the same operations."""
    models = [model_19_17(k) for k in range(5)]
    ar, ma = np.array([m[0] for m in models]), np.array([m[1] for m in models])
    gain, var = np.array([0.6, 1.0, 0.0, 2.0, 0.3]), np.array([2.5, 1.0, 1.0, 0.0, 7.0])
    freqs = np.r_[0.0, np.linspace(1.0, 499.0, 300), 500.0]
    rows = arma_psd_rows(ar, ma, gain, var, freqs, RATE)
    for k in range(5):
        np.testing.assert_array_equal(rows[k], arma_psd(ar[k], ma[k], gain[k], var[k], freqs, RATE))
    with pytest.raises(ValueError, match="ar"):
        arma_psd_rows(ar[:, :0], ma, gain, var, freqs, RATE)


def test_stationary_variance_and_psd() -> None:
    """Fixed model, 3 seeds x 60 s at 1 kHz: variance within 3 %, Welch PSD GFC >= 0.99."""
    a = poly_from_roots(conj_pairs([0.9, 0.85, 0.8], [0.4, 1.3, 2.4], [0.5]))
    c = poly_from_roots(conj_pairs([0.7], [2.0], [-0.4]))
    g, var, n = 1.3, 0.02, 60000
    h = scipy.signal.lfilter(c, a, np.r_[1.0, np.zeros(5000)])
    theory = var * g * g * np.sum(h * h)
    variances = []
    for seed in (11, 12, 13):
        y, _, _ = run(*fixed(a, c, n), g, var, seed=seed)
        variances.append(np.var(y))
        freqs, psd = welch_psd(y, RATE, nperseg=1024)
        model = arma_psd(a, c, g, var, freqs, RATE)
        assert gfc(np.sqrt(psd), np.sqrt(model)) >= 0.99
    assert abs(np.mean(variances) / theory - 1.0) < 0.03


def test_gfc() -> None:
    x = np.array([1.0, 2.0, 3.0])
    assert gfc(x, 5 * x) == pytest.approx(1.0)
    assert gfc(x, -x) == pytest.approx(1.0)
    assert gfc(np.array([1.0, 0.0]), np.array([0.0, 1.0])) == 0.0
    assert gfc(np.array([1.0, 1.0]), np.array([1.0, 0.0])) == pytest.approx(1 / np.sqrt(2))
    with pytest.raises(ValueError):
        gfc(x, x[:2])


# --------------------------------------------------------------------------- switching


def direct_form(ar_rows: np.ndarray, ma_rows: np.ndarray, gain: float, x: np.ndarray) -> np.ndarray:
    """Time-varying direct form: y_n = -sum a_i(n) y_{n-i} + g sum c_j(n) x_{n-j} (HaTT's synthesis)."""
    p = ar_rows.shape[1] - 1
    q = ma_rows.shape[1] - 1
    y = np.zeros(x.size)
    for n in range(x.size):
        acc = 0.0
        for j in range(q + 1):
            if n - j >= 0:
                acc += gain * ma_rows[n, j] * x[n - j]
        for i in range(1, p + 1):
            if n - i >= 0:
                acc -= ar_rows[n, i] * y[n - i]
        y[n] = acc
        if not np.isfinite(acc) or abs(acc) > 1e300:
            return y[: n + 1]
    return y


def switching_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Two stable ARMA(4,2) models (poles at radius <= 0.95) that make a direct form burst when alternated."""
    a1 = poly_from_roots(conj_pairs([0.95, 0.9], [0.3, 1.2]))
    a2 = poly_from_roots(conj_pairs([0.95, 0.9], [2.8, 2.0]))
    c1 = poly_from_roots(conj_pairs([0.6], [2.0]))
    c2 = poly_from_roots(conj_pairs([0.6], [0.9]))
    return a1, c1, a2, c2


def test_direct_form_bursts_but_lattice_stays_bounded_under_per_tick_switching() -> None:
    a1, c1, a2, c2 = switching_pair()
    assert np.abs(np.roots(a1)).max() < 1 and np.abs(np.roots(a2)).max() < 1
    g, var = 1.0, 1.0
    loudest = np.sqrt(max(arma_output_variance(a1, c1, g, var), arma_output_variance(a2, c2, g, var)))
    # direct form, 2000 ticks of alternation: grows by many orders of magnitude
    n_df = 2000
    ar = np.empty((n_df, 5))
    ma = np.empty((n_df, 3))
    ar[0::2], ar[1::2], ma[0::2], ma[1::2] = a1, a2, c1, c2
    y_df = direct_form(ar, ma, g, np.sqrt(var) * normals(2, n_df))
    assert np.nanmax(np.abs(y_df)) > 1e12 * loudest
    # lattice, 10^6 ticks of the same alternation
    n = 1_000_000
    ar = np.empty((n, 5))
    ma = np.empty((n, 3))
    ar[0::2], ar[1::2], ma[0::2], ma[1::2] = a1, a2, c1, c2
    y, _, _ = run(ar, ma, g, var, seed=2)
    assert np.all(np.isfinite(y))
    assert np.abs(y).max() <= 10 * loudest


def test_random_switching_among_high_order_models_stays_bounded() -> None:
    """10^6 ticks, a random one of four AR(19)/MA(17) models every tick (gains and variances differ too)."""
    models = [model_19_17(s) for s in range(4)]
    gains = np.array([1.0, 0.5, 2.0, 1.5])
    variances = np.array([1.0, 3.0, 0.2, 0.7])
    loudest = np.sqrt(max(arma_output_variance(a, c, g, v) for (a, c), g, v in zip(models, gains, variances, strict=True)))
    n = 1_000_000
    pick = np.random.default_rng(9).integers(0, 4, n)
    ar = np.stack([m[0] for m in models])[pick]
    ma = np.stack([m[1] for m in models])[pick]
    y, _, _ = run(ar, ma, gains[pick], variances[pick], seed=3)
    assert np.all(np.isfinite(y))
    assert np.abs(y).max() <= 10 * loudest


def test_new_model_is_used_on_the_tick_it_arrives() -> None:
    """No smoothing: a gain step at tick T scales y from tick T on exactly (the lattice state does not depend on g)."""
    a, c = model_19_17(1)
    n, T = 400, 200
    gain = np.full(n, 1.0)
    gain[T:] = 3.0
    y1, _, _ = run(*fixed(a, c, n), 1.0, 1.0, seed=4)
    y2, _, _ = run(*fixed(a, c, n), gain, 1.0, seed=4)
    np.testing.assert_array_equal(y2[:T], y1[:T])
    np.testing.assert_allclose(y2[T:], 3.0 * y1[T:], rtol=1e-12, atol=1e-12 * np.abs(y1).max())
    # an AR change at tick T changes y at tick T already
    a2, c2 = model_19_17(2)
    ar, ma = fixed(a, c, n)
    ar[T:] = a2
    ma[T:] = c2
    y3, _, _ = run(ar, ma, 1.0, 1.0, seed=4)
    np.testing.assert_array_equal(y3[:T], y1[:T])
    assert y3[T] != y1[T]


# --------------------------------------------------------------------------- state hygiene, invalid models


def test_zero_variance_leaves_no_subnormal_state() -> None:
    a, c = model_19_17(5)
    n = 200_000
    variance = np.zeros(n)
    variance[:100] = 1.0
    y, s, _ = run(*fixed(a, c, n), 1.0, variance, seed=6)
    L, *_, o_g = _offsets(19, 17)[:6]
    state = s[o_g:o_g + L]
    tiny = np.finfo(np.float64).tiny
    assert not np.any((state != 0) & (np.abs(state) < tiny))
    assert np.all(state == 0.0)
    assert y[-1] == 0.0
    # while the model is loud, the same state is non-zero (the test looks at the right numbers)
    _, s_loud, _ = run(*fixed(a, c, 300), 1.0, 1.0, seed=6)
    assert np.any(s_loud[o_g:o_g + L] != 0)


def test_no_output_before_a_valid_model() -> None:
    a, c = model_19_17(0)
    n = 50
    ar, ma = fixed(a, c, n)
    ar[:20, 3] = np.nan
    y, _, _ = run(ar, ma, 1.0, 1.0, seed=1)
    assert np.all(y[:20] == 0.0)
    assert np.all(y[20:] != 0.0)


def unstable_but_valid_looking_lsf_model() -> np.ndarray:
    """A valid LSF vector (4 LSFs within 1e-4 of pi) whose float64 polynomial has a root outside the circle."""
    lsf = np.r_[0.5, 1.0, np.pi - 3e-5 * np.arange(4, 0, -1)]
    a = lsf_to_poly_new(lsf)
    assert np.abs(np.roots(a)).max() > 1.0
    return a


@pytest.mark.parametrize("kind", ["nan_ar", "nan_ma", "unstable", "lsf_cluster", "nan_gain", "inf_gain", "neg_var", "nan_var", "zero_a0"])
def test_invalid_model_holds_the_last_valid_one(kind: str) -> None:
    rng = np.random.default_rng(0)
    a = poly_from_roots(conj_pairs(rng.uniform(0.7, 0.95, 3), [0.5, 1.5, 2.5]))
    c = poly_from_roots(conj_pairs([0.8, 0.5], [1.0, 2.2]))
    n, lo, hi = 600, 200, 350
    g, var = 1.2, 0.5
    ar, ma = fixed(a, c, n)
    gain = np.full(n, g)
    variance = np.full(n, var)
    if kind == "nan_ar":
        ar[lo:hi, 2] = np.nan
    elif kind == "nan_ma":
        ma[lo:hi, 1] = np.nan
    elif kind == "unstable":
        ar[lo:hi] = poly_from_roots(conj_pairs([1.02, 0.5, 0.5], [0.5, 1.5, 2.5]))
    elif kind == "lsf_cluster":
        ar[lo:hi] = unstable_but_valid_looking_lsf_model()
    elif kind == "nan_gain":
        gain[lo:hi] = np.nan
    elif kind == "inf_gain":
        gain[lo:hi] = np.inf
    elif kind == "neg_var":
        variance[lo:hi] = -1.0
    elif kind == "nan_var":
        variance[lo:hi] = np.nan
    elif kind == "zero_a0":
        ar[lo:hi, 0] = 0.0
    # a valid but different model just before the invalid stretch, so "held" is observable
    a_prev = poly_from_roots(conj_pairs([0.9, 0.6, 0.6], [0.8, 1.9, 2.9]))
    ar[lo - 50:lo] = a_prev
    gain[lo - 50:lo] = 0.7
    variance[lo - 50:lo] = 0.9
    y, _, _ = run(ar, ma, gain, variance, seed=8)
    # reference: the invalid ticks replaced by the last valid model (the one of tick lo-1)
    ar_ref, ma_ref = ar.copy(), ma.copy()
    ar_ref[lo:hi], ma_ref[lo:hi] = ar[lo - 1], ma[lo - 1]
    gain_ref, var_ref = gain.copy(), variance.copy()
    gain_ref[lo:hi], var_ref[lo:hi] = gain[lo - 1], variance[lo - 1]
    y_ref, _, _ = run(ar_ref, ma_ref, gain_ref, var_ref, seed=8)
    assert np.all(np.isfinite(y))
    np.testing.assert_array_equal(y, y_ref)


def test_chunked_equals_one_pass_and_seeds() -> None:
    models = [model_19_17(s) for s in range(3)]
    n = 5000
    pick = np.random.default_rng(1).integers(0, 3, n) * (np.arange(n) // 7 % 2)
    ar = np.stack([m[0] for m in models])[pick]
    ma = np.stack([m[1] for m in models])[pick]
    y1, s1, si1 = run(ar, ma, 1.0, 1.0, seed=21)
    y2, s2, si2 = run(ar, ma, 1.0, 1.0, seed=21, chunks=[1, 2, 3, 100, 1123, 1124, 4000])
    np.testing.assert_array_equal(y1, y2)
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_array_equal(si1, si2)
    y3, _, _ = run(ar, ma, 1.0, 1.0, seed=22)
    assert not np.allclose(y1, y3)


def test_coefficients_reject_non_minimum_phase_and_accept_pole_near_circle() -> None:
    k, c, v, wa, wr = np.zeros(4), np.zeros(4), np.zeros(5), np.zeros(5), np.zeros(5)
    ma = np.array([1.0, 0.5])
    assert not lattice_ladder_coefficients(poly_from_roots([1.0001, 0.3]), ma, 1.0, k, c, v, wa, wr)
    assert not lattice_ladder_coefficients(poly_from_roots([-1.0, 0.3]), ma, 1.0, k, c, v, wa, wr)
    a = poly_from_roots(conj_pairs([0.9995, 0.5], [1.0, 2.0]))
    assert lattice_ladder_coefficients(a, ma, 1.0, k, c, v, wa, wr)
    assert np.all(np.abs(k) < 1)
    # sum v^2 is the output variance of the model at unit excitation (normalized lattice property)
    np.testing.assert_allclose(np.sum(v**2), lyapunov_power(a, ma, 1.0, 1.0), rtol=1e-8)


@pytest.mark.parametrize("a0", [2.5, -0.75])
def test_non_monic_ar_matches_lfilter(a0: float) -> None:
    """A(z) with a0 != 1 (the general path, divided by a0) realises g C(z) / A(z) like the monic fast path."""
    a, c = model_19_17(11)
    g, var, n = 1.3, 0.5, 3000
    y, _, _ = run(*fixed(a0 * a, c, n), g, var)
    ref = scipy.signal.lfilter(g * c, a0 * a, np.sqrt(var) * normals(1, n))
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-10 * np.abs(ref).max())
