"""The model spectrum and Jacobian that flowtex.dsp.arma_logfit.fit_log_spectrum minimises over (its compiled kernel).

References computed independently: the dB spectrum from the roots by products of distances
(flowtex.dsp.poly.root_power_spectrum, one factor per root), and from the coefficients by numpy's polyval; the
Jacobian by central differences of the kernel's own value.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.dsp.arma_logfit import _full_roots, _Layout, log_spectrum_db, real_poly

DB = 10.0 / np.log(10.0)


def _params(draw, lay: _Layout) -> np.ndarray:
    floats = st.floats
    x = np.empty(lay.size)
    x[0] = draw(floats(-40.0, 40.0))
    for p0, r0, end in ((lay.zp, lay.zr, lay.pp), (lay.pp, lay.pr, lay.size)):
        for k in range(p0, r0, 2):
            x[k] = np.log1p(-draw(floats(0.0, 0.98)))  # radius up to 0.98: the differences below stay well conditioned
            x[k + 1] = draw(floats(0.0, np.pi))
        for k in range(r0, end):
            x[k] = draw(floats(-0.95, 0.95))
    return x


@st.composite
def models(draw):
    counts = [draw(st.integers(0, 4)) for _ in range(4)]
    lay = _Layout(*counts)
    return lay, _params(draw, lay)


W = np.linspace(0.003, np.pi - 0.003, 257)


@settings(max_examples=60)
@given(models())
def test_value_is_the_model_db_from_roots_and_from_coefficients(model):
    lay, x = model
    s, J = log_spectrum_db(W, x, lay)
    assert J is None
    off, zr, za, zx, pr, pa, px = lay.unpack(x)
    zeros, poles = _full_roots(zr, za, zx), _full_roots(pr, pa, px)
    e = np.exp(1j * W)[:, None]
    by_roots = off + DB * np.log(np.prod(np.abs(1.0 - zeros[None, :] / e) ** 2, axis=1)
                                 / np.prod(np.abs(1.0 - poles[None, :] / e) ** 2, axis=1))
    z = np.exp(-1j * W)
    c, a = real_poly(zeros), real_poly(poles)
    C, A = np.polynomial.polynomial.polyval(z, c), np.polynomial.polynomial.polyval(z, a)
    by_coefficients = off + DB * np.log(np.abs(C) ** 2 / np.abs(A) ** 2)
    # each factor is within [(1 - 0.98)^2, 4] and rounds to a few ulps: 1e-9 dB is far above rounding, far below a fit's 0.02 dB
    np.testing.assert_allclose(s, by_roots, rtol=0, atol=1e-9)
    # Horner's error bound (Higham 2002, eq. 5.3): |error| <= gamma_2n sum |p_k| at |z| = 1, complex arithmetic twice
    # that; relative to |P|, doubled for |P|^2, in dB: large where P is small (a pole pair near w = 0 leaves |A| ~ 1e-6)
    eps = np.finfo(float).eps
    reference_error = DB * 2 * sum(4 * p.size * eps * np.sum(np.abs(p)) / np.abs(P) for p, P in ((c, C), (a, A)))
    assert np.all(np.abs(s - by_coefficients) <= reference_error + 1e-9)


@settings(max_examples=40)
@given(models())
def test_jacobian_is_the_derivative_of_the_value(model):
    lay, x = model
    s, J = log_spectrum_db(W, x, lay, jac=True)
    np.testing.assert_array_equal(s, log_spectrum_db(W, x, lay)[0])  # the value does not depend on jac
    h = 1e-6
    for k in range(lay.size):
        up, down = x.copy(), x.copy()
        up[k] += h
        down[k] -= h
        fd = (log_spectrum_db(W, up, lay)[0] - log_spectrum_db(W, down, lay)[0]) / (2 * h)
        # central difference: truncation ~h^2 |s'''| and rounding ~1e-16 |s| / h; both below 1e-4 dB per unit here
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-5, atol=1e-4)


def test_given_cosines_and_sines_change_nothing():
    lay = _Layout(2, 1, 3, 1)
    x = np.array([1.0, -0.5, 0.3, -1.0, 2.0, 0.2, -2.0, 0.7, -0.1, 1.4, -3.0, 2.9, -0.4])
    assert x.shape[0] == lay.size
    a, ja = log_spectrum_db(W, x, lay, jac=True)
    b, jb = log_spectrum_db(W, x, lay, jac=True, cs=(np.cos(W), np.sin(W)))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ja, jb)
