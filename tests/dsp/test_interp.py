"""dsp.interp: LSF blending, the validity check fused into the blend, and repair of blends closer than min_gap.

References are independent of flowtex.dsp: barycentric weights solved with
numpy.linalg, LSF -> polynomial by full complex products (numpy.poly), and the
repaired vector written out by hand from repair_lsf's documented rule.
"""

from __future__ import annotations

import numpy as np

from flowtex.dsp.interp import initial_state, pack_texture_table, texture_lookup_block

SPEEDS = np.array([1.0, 11.0, 1.0])
FORCES = np.array([1.0, 1.0, 11.0])
TRI = np.array([[0, 1, 2]])


def reference_poly(lsf: np.ndarray) -> np.ndarray:
    """A(z) from LSFs by full complex products (MATLAB lsf2poly convention)."""
    p = len(lsf)
    z = np.exp(1j * np.asarray(lsf))
    even = np.real(np.poly(np.r_[z[0::2], np.conj(z[0::2])]))
    odd = np.real(np.poly(np.r_[z[1::2], np.conj(z[1::2])]))
    if p % 2 == 0:
        s, d = np.convolve(even, [1.0, 1.0]), np.convolve(odd, [1.0, -1.0])
    else:
        s, d = even, np.convolve(odd, [1.0, 0.0, -1.0])
    return (0.5 * (s + d))[: p + 1]


def lookup(ar_lsf, ma_lsf, speed, force):
    tab = pack_texture_table(SPEEDS, FORCES, TRI, ar_lsf, ma_lsf, np.array([1.0, 2.0, 3.0]), np.array([0.5, 1.0, 1.5]), 20.0, 20.0)
    p, q = ar_lsf.shape[1], ma_lsf.shape[1]
    s, si = initial_state(p, q)
    n = len(speed)
    ar, ma, gain, var = np.empty((n, p + 1)), np.empty((n, q + 1)), np.empty((n, 1)), np.empty((n, 1))
    texture_lookup_block(tab, s, si, np.reshape(speed, (n, 1)).astype(float), np.reshape(force, (n, 1)).astype(float), ar, ma, gain, var)
    return ar, ma, gain[:, 0], var[:, 0]


def models():
    ar = np.array([[0.3, 0.9, 1.5, 2.4], [0.4, 1.1, 1.9, 2.6], [0.2, 0.7, 1.2, 2.0]])
    ma = np.array([[0.5, 1.5, 2.5], [0.6, 1.6, 2.9], [0.45, 1.2, 2.2]])
    return ar, ma


def test_interior_blend_matches_numpy_weights_and_full_products() -> None:
    ar_lsf, ma_lsf = models()
    pts = np.array([[4.0, 3.0], [2.0, 7.5], [6.0, 5.0]])
    ar, ma, gain, var = lookup(ar_lsf, ma_lsf, pts[:, 0], pts[:, 1])
    for t, (x, y) in enumerate(pts):
        w = np.linalg.solve(np.vstack([SPEEDS, FORCES, np.ones(3)]), np.array([x, y, 1.0]))
        np.testing.assert_allclose(ar[t], reference_poly(w @ ar_lsf), rtol=0, atol=1e-13)
        np.testing.assert_allclose(ma[t], reference_poly(w @ ma_lsf), rtol=0, atol=1e-13)
        np.testing.assert_allclose([gain[t], var[t]], [w @ [0.5, 1.0, 1.5], w @ [1.0, 2.0, 3.0]], rtol=1e-14)


def test_blend_closer_than_min_gap_is_repaired_and_valid_neighbours_are_not() -> None:
    """A model with an LSF gap of 1e-9 (< DEFAULT_MIN_GAP = 1e-6) is pushed apart at its vertex; the other vertices stay exact."""
    ar_lsf, ma_lsf = models()
    ar_lsf[0, 2] = ar_lsf[0, 1] + 1e-9  # AR gap below min_gap
    ma_lsf[2, 2] = np.pi - 1e-9  # MA LSF closer than min_gap to pi
    ar, ma, _, _ = lookup(ar_lsf, ma_lsf, SPEEDS, FORCES)
    fixed_ar = ar_lsf[0].copy()
    fixed_ar[2] = fixed_ar[1] + 1e-6
    np.testing.assert_allclose(ar[0], reference_poly(fixed_ar), rtol=0, atol=1e-13)
    fixed_ma = ma_lsf[2].copy()
    fixed_ma[2] = np.pi - 1e-6
    np.testing.assert_allclose(ma[2], reference_poly(fixed_ma), rtol=0, atol=1e-13)
    # unrepaired vertices: exactly the model's own LSFs
    np.testing.assert_allclose(ar[1], reference_poly(ar_lsf[1]), rtol=0, atol=1e-13)
    np.testing.assert_allclose(ma[0], reference_poly(ma_lsf[0]), rtol=0, atol=1e-13)
    # and the repair really changed something (the test looks at the right numbers)
    assert np.max(np.abs(reference_poly(fixed_ar) - reference_poly(ar_lsf[0]))) > 1e-8
