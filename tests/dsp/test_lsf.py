"""Line spectral frequencies: round trips, hard cases of real surfaces, repair, float32 comparison.

References are independent of flowtex.dsp.lsf and lsf_roots: polynomials are built from
chosen roots with numpy.poly, stability is checked with numpy.roots, and the
LSF -> polynomial convention is checked against a plain full-complex-product
construction written here (MATLAB's lsf2poly formulation).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.dsp.lsf import DEFAULT_MIN_GAP, is_valid_lsf, lsf_to_poly, lsf_to_poly_new, repair_lsf
from flowtex.dsp.lsf_roots import poly_to_lsf, roots_to_lsf


def random_stable_poly(rng: np.random.Generator, p: int, rmin: float = 0.2, rmax: float = 0.995) -> np.ndarray:
    """Monic real polynomial of order p with random roots of radius in [rmin, rmax] (numpy.poly)."""
    roots: list[complex] = []
    while len(roots) < p:
        if p - len(roots) >= 2 and rng.random() < 0.75:
            rad = rng.uniform(rmin, rmax)
            th = rng.uniform(0.0, np.pi)
            roots += [rad * np.exp(1j * th), rad * np.exp(-1j * th)]
        else:
            roots.append(rng.uniform(-rmax, rmax))
    return np.real(np.poly(roots)) if p else np.ones(1)


def reference_lsf_to_poly(lsf: np.ndarray) -> np.ndarray:
    """Full complex products, as MATLAB's lsf2poly: even-index LSFs (0-based) with (1+z^-1), odd with (1-z^-1)."""
    p = len(lsf)
    z = np.exp(1j * np.asarray(lsf))
    even = np.real(np.poly(np.r_[z[0::2], np.conj(z[0::2])]))
    odd = np.real(np.poly(np.r_[z[1::2], np.conj(z[1::2])]))
    if p % 2 == 0:
        s = np.convolve(even, [1.0, 1.0])
        d = np.convolve(odd, [1.0, -1.0])
    else:
        s = even
        d = np.convolve(odd, [1.0, 0.0, -1.0])
    return (0.5 * (s + d))[: p + 1]


def max_root(a: np.ndarray) -> float:
    return float(np.max(np.abs(np.roots(a)))) if len(a) > 1 else 0.0


@pytest.mark.parametrize("p", list(range(1, 21)))
def test_round_trip_random_orders(p: int) -> None:
    rng = np.random.default_rng(100 + p)
    for _ in range(5):
        a = random_stable_poly(rng, p)
        lsf = poly_to_lsf(a)
        assert lsf.shape == (p,)
        assert np.all(np.diff(lsf) > 0) and lsf[0] > 0 and lsf[-1] < np.pi
        back = lsf_to_poly_new(lsf)
        assert back[0] == 1.0
        np.testing.assert_allclose(back, a, rtol=0, atol=1e-12 * max(1.0, np.abs(a).max()))


@pytest.mark.parametrize("p", [1, 2, 5, 8, 17, 19, 20])
def test_convention_matches_full_product_reference(p: int) -> None:
    """Our in-place half-storage construction equals the textbook full-product one (HaTT/MATLAB meaning)."""
    rng = np.random.default_rng(p)
    lsf = np.sort(rng.uniform(0.01, np.pi - 0.01, p))
    ref = reference_lsf_to_poly(lsf)
    np.testing.assert_allclose(lsf_to_poly_new(lsf), ref, rtol=0, atol=1e-12 * max(1.0, np.abs(ref).max()))


def test_analytic_cases() -> None:
    # A(z) = 1 has LSFs k pi / (p+1), k = 1..p (roots of 1 +- z^-(p+1)).
    for p in (1, 2, 7, 10):
        lsf = np.arange(1, p + 1) * np.pi / (p + 1)
        np.testing.assert_allclose(lsf_to_poly_new(lsf), np.r_[1.0, np.zeros(p)], atol=1e-14)
        np.testing.assert_allclose(poly_to_lsf(np.r_[1.0, np.zeros(p)]), lsf, atol=1e-14)
    # order 1: S = 1 + 2 a1 z^-1 + z^-2 = 1 - 2 cos(w) z^-1 + z^-2  =>  a1 = -cos(w)
    for w in (0.1, 1.0, 3.0):
        np.testing.assert_allclose(lsf_to_poly_new(np.array([w])), [1.0, -math.cos(w)], atol=1e-16)
    # order 0
    out = np.empty(1)
    lsf_to_poly(np.zeros(0), out)
    assert out[0] == 1.0
    assert poly_to_lsf(np.array([1.0])).shape == (0,)


def test_out_may_be_longer_and_is_written_only_up_to_p() -> None:
    lsf = np.array([0.3, 0.9, 1.7, 2.5])
    out = np.full(8, 7.0)
    lsf_to_poly(lsf, out)
    np.testing.assert_allclose(out[:5], reference_lsf_to_poly(lsf), atol=1e-14)
    assert np.all(out[5:] == 7.0)


def test_poles_near_unit_circle() -> None:
    """Resonances at radius 0.995..0.9995 survive the round trip (pole radii to ~1e-10)."""
    for p, radius in ((2, 0.9995), (10, 0.995), (19, 0.997), (20, 0.998)):
        thetas = np.linspace(0.2, 2.9, p // 2)
        roots = np.r_[radius * np.exp(1j * thetas), radius * np.exp(-1j * thetas)]
        if p % 2:
            roots = np.r_[roots, -0.5]
        a = np.real(np.poly(roots))
        back = lsf_to_poly_new(poly_to_lsf(a))
        np.testing.assert_allclose(back, a, atol=1e-12 * max(1.0, np.abs(a).max()))
        got = np.sort(np.abs(np.roots(back)))
        np.testing.assert_allclose(got, np.sort(np.abs(roots)), atol=1e-9)
        assert got.max() < 1.0


def test_ma_like_vector_with_tiny_gap_and_lsf_next_to_pi() -> None:
    """Real MA models: gaps of 2e-4 and an LSF within 5e-4 of pi must convert unchanged."""
    q = 17
    lsf = np.linspace(0.15, 3.0, q)
    lsf[7] = lsf[6] + 2e-4
    lsf[-1] = np.pi - 4e-4
    lsf[-2] = lsf[-1] - 2e-4
    assert is_valid_lsf(lsf) and is_valid_lsf(lsf, DEFAULT_MIN_GAP)
    c = lsf_to_poly_new(lsf)
    np.testing.assert_allclose(c, reference_lsf_to_poly(lsf), atol=1e-12)
    assert max_root(c) < 1.0
    back = poly_to_lsf(c)
    np.testing.assert_allclose(back, lsf, rtol=0, atol=1e-10)
    copy = lsf.copy()
    assert repair_lsf(copy, DEFAULT_MIN_GAP) is False
    assert copy.tobytes() == lsf.tobytes()


def test_any_increasing_vector_gives_minimum_phase() -> None:
    rng = np.random.default_rng(7)
    for trial in range(200):
        p = int(rng.integers(1, 21))
        lsf = np.sort(rng.uniform(0.0, np.pi, p))
        if not is_valid_lsf(lsf):
            continue
        assert max_root(lsf_to_poly_new(lsf)) < 1.0, (trial, lsf)


def test_lsf_interpolation_stable_where_coefficient_interpolation_is_not() -> None:
    r = 0.95
    a1 = np.real(np.poly(r * np.exp(1j * np.array([0.9, -0.9, 1.95, -1.95]))))
    a2 = np.real(np.poly(r * np.exp(1j * np.array([0.15, -0.15, 0.22, -0.22]))))
    assert max_root(a1) < 1.0 and max_root(a2) < 1.0
    # averaging coefficients leaves the unit circle ...
    assert max_root(0.5 * (a1 + a2)) > 1.1
    # ... averaging LSFs (any convex weight) never does
    l1, l2 = poly_to_lsf(a1), poly_to_lsf(a2)
    for w in np.linspace(0.0, 1.0, 21):
        lsf = (1 - w) * l1 + w * l2
        assert is_valid_lsf(lsf)
        assert max_root(lsf_to_poly_new(lsf)) < 1.0


def test_poly_to_lsf_rejects_non_minimum_phase() -> None:
    with pytest.raises(ValueError, match="minimum phase"):
        poly_to_lsf(np.real(np.poly([1.01, 0.5])))
    with pytest.raises(ValueError, match="minimum phase"):
        poly_to_lsf(np.real(np.poly([1.05 * np.exp(0.3j), 1.05 * np.exp(-0.3j)])))
    with pytest.raises(ValueError, match="monic"):
        poly_to_lsf(np.array([2.0, 0.1]))
    with pytest.raises(ValueError):
        poly_to_lsf(np.array([1.0, np.nan]))


def test_is_valid_lsf() -> None:
    assert is_valid_lsf(np.array([0.1, 0.2, 3.0]))
    assert is_valid_lsf(np.zeros(0))
    assert not is_valid_lsf(np.array([0.2, 0.1]))
    assert not is_valid_lsf(np.array([0.1, 0.1]))
    assert not is_valid_lsf(np.array([0.0, 0.1]))
    assert not is_valid_lsf(np.array([0.1, np.pi]))
    assert not is_valid_lsf(np.array([0.1, np.nan, 0.3]))
    assert not is_valid_lsf(np.array([0.1, 0.1 + 1e-8]), 1e-6)


def test_repair_leaves_valid_vectors_bit_identical() -> None:
    rng = np.random.default_rng(3)
    for _ in range(100):
        p = int(rng.integers(1, 21))
        lsf = poly_to_lsf(random_stable_poly(rng, p))
        before = lsf.tobytes()
        assert repair_lsf(lsf, DEFAULT_MIN_GAP) is False
        assert lsf.tobytes() == before


@pytest.mark.parametrize(
    "bad",
    [
        [0.5, 0.3, 1.0, 2.0],  # out of order
        [0.5, 0.5, 1.0, 2.0],  # coincident
        [0.5, 0.5 + 1e-9, 1.0, 2.0],  # closer than min_gap
        [-0.1, 0.5, 1.0, 2.0],  # below 0
        [0.0, 0.5, 1.0, 2.0],  # at 0
        [0.5, 1.0, 2.0, 3.5],  # above pi
        [0.5, 1.0, 3.0, 3.3, 3.4],  # two above pi (backward pass)
        [3.0, 2.0, 1.0, 0.5],  # reversed
        [0.5, np.nan, 1.0, 2.0],  # NaN
        [0.5, np.inf, 1.0, 2.0],  # inf
    ],
)
def test_repair_fixes_invalid_vectors(bad: list[float]) -> None:
    lsf = np.array(bad, dtype=np.float64)
    assert repair_lsf(lsf, DEFAULT_MIN_GAP) is True
    assert is_valid_lsf(lsf, DEFAULT_MIN_GAP * (1 - 1e-9))
    assert max_root(lsf_to_poly_new(lsf)) < 1.0
    finite = np.array(bad)
    if np.all(np.isfinite(finite)):
        # entries that were fine and in order stay where they were
        assert np.any(np.isin(lsf, finite))
    else:
        np.testing.assert_allclose(lsf, np.arange(1, len(bad) + 1) * np.pi / (len(bad) + 1))


def test_repair_of_a_cluster_is_valid_but_clusters_are_numerically_fragile() -> None:
    """Three entries above pi become a cluster 1e-6 apart below pi: a valid LSF vector.

    Documented limit (also in lsf.py): a cluster of 3 or more LSFs within ~1e-4 puts poles so close to the
    unit circle that float64 coefficients cannot represent them reliably; arma_synth checks the reflection
    coefficients and refuses such a model. Pairs (real surfaces: gaps >= 2e-4) are fine even at 1e-6.
    """
    lsf = np.array([0.5, 1.0, 3.2, 3.3, 3.4])
    assert repair_lsf(lsf, DEFAULT_MIN_GAP)
    assert is_valid_lsf(lsf, DEFAULT_MIN_GAP * (1 - 1e-9))
    np.testing.assert_allclose(lsf[2:], np.pi - DEFAULT_MIN_GAP * np.array([3, 2, 1]), rtol=0, atol=1e-15)
    pair = np.array([0.5, 1.0, 2.0, np.pi - 2e-6, np.pi - 1e-6])
    assert is_valid_lsf(pair, DEFAULT_MIN_GAP * (1 - 1e-9))
    assert max_root(lsf_to_poly_new(pair)) < 1.0


def test_repair_keeps_valid_entries_of_an_out_of_order_vector() -> None:
    lsf = np.array([0.2, 0.9, 0.6, 1.5, 2.5])
    assert repair_lsf(lsf, DEFAULT_MIN_GAP)
    assert lsf.tolist() == [0.2, 0.6, 0.9, 1.5, 2.5]


def hatt_float32_lsf_to_poly(lsf: np.ndarray) -> np.ndarray:
    """Emulation of HaTT's reconstruction: the same products done in single-precision complex arithmetic."""
    p = len(lsf)
    z = np.exp(1j * lsf.astype(np.float32)).astype(np.complex64)

    def poly32(roots: np.ndarray) -> np.ndarray:
        c = np.ones(1, np.complex64)
        for r in roots:
            c = (np.convolve(c, np.array([1.0, -r], np.complex64))).astype(np.complex64)
        return c

    even = poly32(np.r_[z[0::2], np.conj(z[0::2])])
    odd = poly32(np.r_[z[1::2], np.conj(z[1::2])])
    if p % 2 == 0:
        s = np.convolve(even, np.array([1, 1], np.complex64)).astype(np.complex64)
        d = np.convolve(odd, np.array([1, -1], np.complex64)).astype(np.complex64)
    else:
        s = even
        d = np.convolve(odd, np.array([1, 0, -1], np.complex64)).astype(np.complex64)
    return (np.float32(0.5) * (s + d).real.astype(np.float32))[: p + 1]


def test_float64_beats_hatt_float32_near_unit_circle() -> None:
    """Order-19 model with a pole pair at radius 0.995: float32 reconstruction visibly moves poles; ours does not."""
    rng = np.random.default_rng(11)
    thetas = np.array([0.12, 0.35, 0.6, 0.9, 1.2, 1.6, 2.0, 2.4, 2.9])
    radii = np.r_[0.995, rng.uniform(0.8, 0.97, len(thetas) - 1)]
    roots = np.r_[radii * np.exp(1j * thetas), radii * np.exp(-1j * thetas), 0.3]
    a = np.real(np.poly(roots))
    lsf = poly_to_lsf(a)
    ours = lsf_to_poly_new(lsf)
    theirs = hatt_float32_lsf_to_poly(lsf).astype(np.float64)
    true_r = np.sort(np.abs(roots))
    err64 = np.max(np.abs(np.sort(np.abs(np.roots(ours))) - true_r))
    err32 = np.max(np.abs(np.sort(np.abs(np.roots(theirs))) - true_r))
    coef64 = np.max(np.abs(ours - a))
    coef32 = np.max(np.abs(theirs - a))
    assert err64 < 1e-9
    assert coef64 < 1e-11
    assert err32 > 1e3 * err64 and err32 > 1e-5
    assert coef32 > 1e3 * coef64


def test_inline_cosine_matches_long_double_cosine() -> None:
    """lsf_to_poly's inline -2 cos(w) (a polynomial, not libm) is within 3 ulp of 2 on [0, pi], endpoints included."""
    from flowtex.dsp.lsf import _minus_2cos

    rng = np.random.default_rng(7)
    w = np.r_[0.0, np.pi, np.nextafter(np.pi, 0.0), 1e-300, np.pi / 2, np.linspace(0.0, np.pi, 20001), rng.uniform(0.0, np.pi, 20000)]
    got = np.array([_minus_2cos(x) for x in w], dtype=np.longdouble)
    ref = -2 * np.cos(w.astype(np.longdouble))
    assert float(np.max(np.abs(got - ref))) <= 6e-16


@pytest.mark.parametrize("p", [1, 2, 3, 6, 19])
def test_angles_outside_zero_pi_use_the_exact_cosine(p: int) -> None:
    """Out-of-range entries (not LSFs, but lsf_to_poly must still compute the product they define) and NaN."""
    rng = np.random.default_rng(50 + p)
    lsf = np.sort(rng.uniform(0.1, 3.0, p))
    lsf[-1] = np.pi + 0.5  # outside [0, pi]
    lsf[0] = -0.25 if p > 1 else lsf[0]
    ref = reference_lsf_to_poly(lsf)
    np.testing.assert_allclose(lsf_to_poly_new(lsf), ref, rtol=0, atol=1e-12 * max(1.0, np.abs(ref).max()))
    lsf[p // 2] = np.nan
    out = lsf_to_poly_new(lsf)
    assert out[0] == 1.0 and np.isnan(out[1:]).any()


@pytest.mark.parametrize("p", [1, 2, 7, 12, 20])
def test_roots_to_lsf_matches_the_reference_convention(p: int) -> None:
    # well-conditioned random polynomials: the LSFs from the roots are the angles of the roots of the
    # symmetric / antisymmetric polynomials (reference_lsf_to_poly rebuilds the polynomial from them)
    rng = np.random.default_rng(7 + p)
    for _ in range(5):
        a = random_stable_poly(rng, p, rmax=0.95)
        lsf = roots_to_lsf(np.roots(a))
        assert is_valid_lsf(lsf)
        np.testing.assert_allclose(reference_lsf_to_poly(lsf), a, rtol=0, atol=1e-10)  # np.roots: ~1e-13 here


def test_lsf_round_trip_of_roots_crowded_near_z_1_and_minus_1() -> None:
    # A(z^2) for a HaTT-like A (19 poles to r = 0.985 over 0.1..3 rad) with its roots first mapped to twice the
    # rate (r^0.5, angle / 2): what a 1 kHz model upsampled 4x is made of. 38 roots crowd into 0..0.75 rad and
    # pi..pi+0.75 at r up to 0.9962; |A| spans ~1e-9..1e4. lsf_to_poly of the exact LSFs must keep the spectrum
    # (multiplying the factors in increasing LSF order puts all near-z=1 factors first: 20-60 dB off here).
    from flowtex.datasets.model_sets import hatt_like_model

    z = np.roots(hatt_like_model(5)[0])
    half = np.where(np.abs(z.imag) > 0, np.sqrt(np.abs(z)) * np.exp(0.5j * np.angle(z)), np.sign(z.real) * np.sqrt(np.abs(z)))
    roots = np.r_[np.sqrt(half), -np.sqrt(half)]  # roots of B(z^2), B(z) = prod (1 - half_i z^-1)
    w = np.linspace(0.0, 0.9 * np.pi / 4, 4000)
    exact = np.prod(np.abs(1.0 - roots[None, :] * np.exp(-1j * w)[:, None]) ** 2, axis=1)
    back = lsf_to_poly_new(roots_to_lsf(roots))
    assert back.shape == (39,)
    got = np.abs(np.polyval(back[::-1], np.exp(1j * w))) ** 2  # A(z) = sum a_k z^-k at z = e^jw
    assert np.max(np.abs(10 * np.log10(got / exact))) < 0.05  # measured 0.007 dB (float64 rounding of the product)


def _roots_from(pairs: list[tuple[float, float]], reals: list[float]) -> np.ndarray:
    z = [r * np.exp(1j * t) for r, t in pairs]
    return np.array(z + [np.conj(v) for v in z] + [complex(x) for x in reals], dtype=np.complex128)


def _lsf_60_digits(roots: np.ndarray) -> np.ndarray:
    """The LSFs of prod (1 - r z^-1) over ``roots`` in 60-digit arithmetic (mpmath): the angles in (0, pi) of the
    unit-circle roots of P(z) = A(z) + z^-(p+1) A(1/z) and Q(z) = A(z) - z^-(p+1) A(1/z), from the roots themselves."""
    import mpmath

    with mpmath.workdps(60):
        a = [mpmath.mpc(1)]
        for r in roots:
            c = mpmath.mpc(r.real, r.imag)
            a = [(a[k] if k < len(a) else 0) - (c * a[k - 1] if k else 0) for k in range(len(a) + 1)]
        a = [mpmath.re(x) for x in a]
        p = len(a) - 1
        angles = []
        for sign in (1, -1):
            poly = [(a[k] if k <= p else 0) + sign * (a[p + 1 - k] if 0 <= p + 1 - k <= p else 0) for k in range(p + 2)]
            angles += [mpmath.arg(z) for z in mpmath.polyroots(poly, maxsteps=400, extraprec=300)]
        return np.array(sorted(float(t) for t in angles if 1e-30 < t < mpmath.pi - 1e-30))


@settings(max_examples=60, deadline=None)
@given(pairs=st.lists(st.tuples(st.floats(0.0, 0.97), st.floats(0.05, np.pi - 0.05)), max_size=5),
       reals=st.lists(st.floats(-0.97, 0.97), max_size=2))
def test_roots_to_lsf_property_agrees_with_60_digit_lsfs(pairs, reals) -> None:
    # any stable real polynomial of order <= 12 with roots within 0.97: the LSFs from the roots are valid (p values,
    # strictly increasing in (0, pi)) and equal the LSFs computed from the same roots in 60-digit arithmetic.
    # Tolerance 1e-11 rad: roots_to_lsf's error is float64 rounding (1.9e-15 at most over 2000 examples of this
    # strategy, measured 2026-11-27). poly_to_lsf from the coefficients is not the reference: repeated roots near the circle make the
    # coefficients ill-conditioned (two equal pairs at radius 0.969, 0.055 rad: poly_to_lsf off by 1.1e-7, the
    # 60-digit LSFs and roots_to_lsf agreeing to 1.6e-15, a case hypothesis found).
    roots = _roots_from(pairs, reals)
    if roots.shape[0] == 0:
        return
    lsf = roots_to_lsf(roots)
    assert lsf.shape == (roots.shape[0],) and is_valid_lsf(lsf)
    np.testing.assert_allclose(lsf, _lsf_60_digits(roots), rtol=0, atol=1e-11)


def test_roots_to_lsf_of_a_repeated_pair_near_the_circle() -> None:
    roots = _roots_from([(0.96875, 0.0546875), (0.96875, 0.0546875), (0.875, 0.0546875), (0.9375, 0.0546875)], [])
    np.testing.assert_allclose(roots_to_lsf(roots), _lsf_60_digits(roots), rtol=0, atol=1e-11)


def test_lsf_roots_names_still_import_from_lsf():
    """poly_to_lsf and roots_to_lsf moved to flowtex.dsp.lsf_roots; the old path gives the same functions."""
    import flowtex.dsp.lsf as lsf
    import flowtex.dsp.lsf_roots as lsf_roots

    assert lsf.poly_to_lsf is lsf_roots.poly_to_lsf and lsf.roots_to_lsf is lsf_roots.roots_to_lsf
    with pytest.raises(AttributeError, match="no attribute 'lsf_to_roots'"):
        lsf.lsf_to_roots  # noqa: B018 - the attribute access is the test
