"""flowtex.dsp.npmath rounds as numpy does: complex products and |.| bit for bit against numpy's own arrays where
numpy's loops fuse as npmath does (tests/dsp/numpy_rounding.py: x86-64 with AVX2 and FMA3), and within two roundings
of numpy's values on every CPU (numpy picks its loops for the CPU it runs on).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from flowtex.dsp.npmath import cabs, cmul
from tests.dsp.numpy_rounding import NUMPY_ROUNDS_AS_NPMATH

EPS = np.finfo(np.float64).eps / 2  # one rounding, relative


@njit(cache=True)
def _products(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    for k in range(a.shape[0]):
        re, im = cmul(a[k].real, a[k].imag, b[k].real, b[k].imag)
        out[k] = complex(re, im)


@njit(cache=True)
def _abs(a: np.ndarray, out: np.ndarray) -> None:
    for k in range(a.shape[0]):
        out[k] = cabs(a[k].real, a[k].imag)


def _values(rng: np.random.Generator, n: int) -> np.ndarray:
    """Complex values over many binades, with zeros, subnormals, infinities and nans among them."""
    mag = 10.0 ** rng.uniform(-300, 300, (2, n))
    x = rng.choice([-1.0, 1.0], (2, n)) * mag
    special = np.array([0.0, -0.0, 5e-324, -5e-324, np.inf, -np.inf, np.nan, 1.0, 1e308])
    pick = rng.random((2, n)) < 0.05
    x[pick] = rng.choice(special, pick.sum())
    out = np.empty(n, complex)
    out.real, out.imag = x
    return out


def test_complex_products_are_numpys_bit_for_bit():
    rng = np.random.default_rng(0)
    for n in (1, 3, 8, 17, 10_001):
        a, b = rng.standard_normal(n) + 1j * rng.standard_normal(n), rng.standard_normal(n) + 1j * rng.standard_normal(n)
        out = np.empty(n, complex)
        _products(a, b, out)
        ref = a * b
        # each part is a sum of two products: fused or not, two roundings of at most EPS x (|ar br| + |ai bi|) each
        scale_re = np.abs(a.real * b.real) + np.abs(a.imag * b.imag)
        scale_im = np.abs(a.real * b.imag) + np.abs(a.imag * b.real)
        assert np.all(np.abs(out.real - ref.real) <= 4 * EPS * scale_re)
        assert np.all(np.abs(out.imag - ref.imag) <= 4 * EPS * scale_im)
        if NUMPY_ROUNDS_AS_NPMATH:
            np.testing.assert_array_equal(out.view(float), ref.view(float))


def test_complex_abs_is_numpys_bit_for_bit():
    rng = np.random.default_rng(1)
    for n in (1, 5, 16, 10_001):
        a = _values(rng, n)
        out = np.empty(n)
        _abs(a, out)
        with np.errstate(all="ignore"):
            ref = np.abs(a)
            same_class = (np.isnan(out) == np.isnan(ref)) & (np.isinf(out) == np.isinf(ref))
            finite = np.isfinite(ref) & (ref > 1e-300)  # below, subnormal results carry fewer digits
            assert same_class.all()
            # a scaled sqrt(1 + r^2) and libm's hypot: a few roundings each, 4 EPS relative apart at most
            assert np.all(np.abs(out[finite] - ref[finite]) <= 4 * EPS * ref[finite])
            if NUMPY_ROUNDS_AS_NPMATH:
                np.testing.assert_array_equal(out, ref)
