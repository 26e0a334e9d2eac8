"""flowtex.dsp.npmath rounds as numpy does: complex products and |.| bit for bit against numpy's own arrays.

numpy chooses its loops for the CPU it runs on; this file checks, on this machine, what the module docstring states
(a failure on another CPU means numpy rounds differently there, and the kernels built on npmath no longer give
numpy's bits there, though they stay within the same error bounds).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from flowtex.dsp.npmath import cabs, cmul


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
        np.testing.assert_array_equal(out.view(float), (a * b).view(float))


def test_complex_abs_is_numpys_bit_for_bit():
    rng = np.random.default_rng(1)
    for n in (1, 5, 16, 10_001):
        a = _values(rng, n)
        out = np.empty(n)
        _abs(a, out)
        with np.errstate(all="ignore"):
            np.testing.assert_array_equal(out, np.abs(a))
