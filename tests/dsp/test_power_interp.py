"""Power-preserving interpolation in the lookup kernel, against independent float64 references.

References: scipy's discrete Lyapunov solution (tests/power_reference.py) and the
impulse response's energy for every output power, numpy LSF products (lsf_to_poly_reference) for the
polynomials, barycentric weights from the file's triangle (tests/hatt_reference.py).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal
from hypothesis import example, given, settings
from hypothesis import strategies as st

from flowtex.datasets.model_sets import cork_like_model_set, hard_model_set, lsf_to_poly_reference, poly_from_roots
from flowtex.dsp.arma import arma_output_variance
from flowtex.dsp.interp import filter_power, initial_state, model_output_powers, pack_texture_table, texture_lookup_block
from flowtex.fit.quality import models_at
from tests.hatt_reference import clamp, locate
from tests.power_reference import lattice_error_bound, lyapunov_error_bound, lyapunov_power


def _power(a, c, g, v):
    return lyapunov_power(a, c, g, v) if v > 0 else 0.0


@pytest.mark.parametrize("p, q, radius", [(2, 0, 0.9), (6, 4, 0.97), (12, 10, 0.998), (19, 17, 0.995), (4, 9, 0.99)])
def test_filter_power_is_the_impulse_response_energy(p, q, radius):
    rng = np.random.default_rng(p * 100 + q)
    a = poly_from_roots(np.full(p // 2, radius), rng.uniform(0.1, 3.0, p // 2), [0.5] if p % 2 else [])
    c = poly_from_roots(np.full(q // 2, 0.9), rng.uniform(0.1, 3.0, q // 2), [-0.3] if q % 2 else [])
    L = max(p, q)
    got = filter_power(a, c, 1.7, np.empty(5 * L + 3))
    # reference: the energy of scipy's impulse response, 200 000 samples (the tail beyond: < 0.998^4e5 = e^-800);
    # an exact identity, so 1e-9 covers the step-down's rounding (it grows as 1 / (1 - |k|^2) near the circle).
    # (p, q) = (6, 4) has two resonances 0.007 rad apart (2.2e8 gain): the Lyapunov solution is 7e-7 off there.
    h = scipy.signal.lfilter(1.7 * c, a, np.r_[1.0, np.zeros(200_000)])
    assert got == pytest.approx(np.sum(h * h), rel=1e-9)


@settings(max_examples=60, deadline=None)
@given(p=st.integers(0, 12), q=st.integers(0, 10), radius=st.floats(0.2, 0.99), zero_radius=st.floats(0.1, 1.6),
       gain=st.floats(0.01, 100.0), seed=st.integers(0, 2**32 - 1))
@example(p=12, q=0, radius=0.875, zero_radius=1.0, gain=1.0, seed=671)  # clustered resonances (below)
def test_the_one_output_power_is_the_spectrum_mean_and_the_lyapunov_solution(p, q, radius, zero_radius, gain, seed):
    # arma_output_variance (the lattice's filter_power) against two references that share nothing with it. Parseval on
    # scipy.signal.freqz's 2^16-point grid: mean |g C/A|^2 is the energy of the impulse response folded every 2^16
    # samples, off by < radius^65536 < 1e-280 relatively. The step-down's float64 rounding: 1e-9, or its measured
    # bound where resonances cluster (tests/power_reference.py; hypothesis found 12 poles at radius 0.875 with
    # angles 0.015-0.08 rad apart, where the lattice is 1.4e-9 off a 50-digit impulse-response energy and the
    # Parseval sum 5e-11). The Lyapunov solver: 1e-6, or its own bound (it was 5.6e-4 off there).
    rng = np.random.default_rng(seed)
    a = poly_from_roots(np.full(p // 2, radius), rng.uniform(0.05, 3.1, p // 2), [rng.uniform(-radius, radius)] if p % 2 else [])
    c = poly_from_roots(np.full(q // 2, zero_radius), rng.uniform(0.05, 3.1, q // 2), [rng.uniform(-1.5, 1.5)] if q % 2 else [])
    got = arma_output_variance(a, c, gain, 0.7)
    _, h = scipy.signal.freqz(gain * c, a, worN=2**16, whole=True)
    assert got == pytest.approx(0.7 * np.mean(np.abs(h) ** 2), rel=max(1e-9, lattice_error_bound(a)))
    assert got == pytest.approx(lyapunov_power(a, c, gain, 0.7), rel=max(1e-6, lyapunov_error_bound(a)))


def test_unstable_filter_has_no_power():
    assert filter_power(np.array([1.0, -2.0, 1.0]), np.array([1.0]), 1.0, np.empty(13)) == -1.0


@pytest.fixture(scope="module", params=["hard", "cork"])
def surface(request):
    return hard_model_set() if request.param == "hard" else cork_like_model_set()


def test_model_powers_match_lyapunov(surface):
    ms = surface
    want = [_power(lsf_to_poly_reference(ms.ar_lsf[m]), lsf_to_poly_reference(ms.ma_lsf[m]), ms.gain[m], ms.variance[m])
            for m in range(ms.num_models)]
    np.testing.assert_allclose(model_output_powers(ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain), want, rtol=1e-9)


def _queries(ms, n=60, seed=3):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.0, ms.max_speed, n), rng.uniform(0.0, ms.max_force, n)


@pytest.mark.parametrize("rule", ["power", "log_power"])
def test_rendered_power_is_the_blend_of_the_vertex_powers(surface, rule):
    ms = surface
    vertex_power = np.array([_power(lsf_to_poly_reference(ms.ar_lsf[m]), lsf_to_poly_reference(ms.ma_lsf[m]), ms.gain[m],
                                    ms.variance[m]) for m in range(ms.num_models)])
    speed, force = _queries(ms)
    got = models_at(ms, speed, force, outside="fade", interpolation=rule)
    hatt = models_at(ms, speed, force, outside="fade", interpolation="variance")
    for i in range(len(speed)):
        t, w, _ = locate(ms, clamp(speed[i], ms.max_speed), clamp(force[i], ms.max_force))
        P = vertex_power[t]
        if rule == "power":
            want = float(w @ P)
        else:                     # geometric over the non-silent vertices, times their weight (silent corners fade)
            on = P > 0
            want = float(w[on].sum() * np.exp(w[on] @ np.log(P[on]) / w[on].sum())) if on.any() else 0.0
        a, c, g, v = got[i]
        assert np.array_equal(a, hatt[i][0]) and np.array_equal(c, hatt[i][1]) and g == hatt[i][2]   # shape: LSFs as HaTT
        assert _power(lsf_to_poly_reference(w @ ms.ar_lsf[t]), lsf_to_poly_reference(w @ ms.ma_lsf[t]), g, v) == \
            pytest.approx(want, rel=1e-8, abs=1e-300)                                               # its power: the blend


def test_at_a_vertex_every_interpolation_gives_that_model(surface):
    ms = surface
    inside = [m for m in range(ms.num_models) if 0.05 <= ms.speeds[m] < ms.max_speed and 0.05 <= ms.forces[m] < ms.max_force]
    for rule in ("power", "log_power"):
        got = models_at(ms, ms.speeds[inside], ms.forces[inside], interpolation=rule)
        np.testing.assert_allclose([r[3] for r in got], ms.variance[inside], rtol=1e-9)


def test_power_interpolation_keeps_loudness_where_variance_interpolation_loses_it():
    # two models with resonances far apart: halfway, the LSF blend's filter gain differs from both, so blending the
    # excitation variance misses the vertices' power; blending the power does not
    ms = hard_model_set(8, 6)
    s = np.array([100.0])
    f = np.array([1.0])
    (a1, c1, g1, v1), = models_at(ms, s, f, interpolation="variance")
    (a2, c2, g2, v2), = models_at(ms, s, f, interpolation="power")
    assert np.array_equal(a1, a2) and v1 != v2


def test_lookup_kernel_allocates_nothing_per_tick(nrt_allocations):
    ms = cork_like_model_set()
    n = 3000
    rng = np.random.default_rng(0)
    speed = rng.uniform(0, 400, (n, 1))
    force = rng.uniform(0, 4.5, (n, 1))
    out = [np.empty((n, 20)), np.empty((n, 18)), np.empty((n, 1)), np.empty((n, 1))]
    for rule in ("power", "log_power"):
        tab = pack_texture_table(ms.speeds, ms.forces, ms.triangles, ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain,
                                 ms.max_speed, ms.max_force, interpolation=rule, outside="trend")
        s, si = initial_state(19, 17)
        texture_lookup_block(tab, s, si, speed[:10], force[:10], *[o[:10] for o in out])  # compiled before counting
        short, long = (nrt_allocations(texture_lookup_block, tab, s, si, speed[:m], force[:m], *[o[:m] for o in out])
                       for m in (10, n))
        assert short == long and short > 0, (rule, short, long)  # 10 and 3000 ticks: the same (boxing) allocations
