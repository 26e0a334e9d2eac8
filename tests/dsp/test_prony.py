"""Prony / Steiglitz-McBride on filters with known impulse responses (004 ch. 4)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from flowtex.dsp.prony import fit_iir, impulse_response, is_stable, prony, refit_numerator, sad, stabilize, steiglitz_mcbride


def _filter(radii=(0.95, 0.8), angles=(0.6, 1.5), b=(0.0, 1.0, -0.5, 0.3, 0.1)):
    poles = [r * np.exp(s * 1j * w) for r, w in zip(radii, angles, strict=True) for s in (1, -1)]
    return np.asarray(b, float), np.real(np.poly(poles))


def test_prony_is_exact_on_a_noise_free_response():
    b, a = _filter()
    h = scipy.signal.lfilter(b, a, np.r_[1.0, np.zeros(79)])  # independent reference: scipy's filter
    bb, aa = prony(h, 4, 4)
    # exact up to rounding: the linear prediction equations are consistent; 1e-9 allows for their conditioning
    np.testing.assert_allclose(aa, a, atol=1e-9)
    np.testing.assert_allclose(bb, b, atol=1e-9)
    # over-specified orders reproduce the response too (extra poles cancel extra zeros)
    bb, aa = prony(h, 6, 6)
    assert sad(h, bb, aa) < 1e-9


def test_pole_near_the_unit_circle_and_stabilization():
    b, a = _filter(radii=(0.999, 0.5))
    h = impulse_response(b, a, 200)
    bb, aa = steiglitz_mcbride(h, 4, 4)
    assert is_stable(aa)
    assert sad(h, bb, aa) < 1e-3 * np.mean(np.abs(h))  # 0.999 < STABLE_RADIUS: representable, so the fit is near exact
    unstable = np.real(np.poly([1.2, 0.5]))
    fixed = stabilize(unstable)
    np.testing.assert_allclose(np.sort(np.abs(np.roots(fixed))), [0.5, 1 / 1.2])  # 1.2 reflected to 1/1.2


@pytest.mark.parametrize("level", [0.01, 0.05, 0.10])
def test_refinement_beats_prony_under_noise(level):
    b, a = _filter()
    h = impulse_response(b, a, 80)
    rng = np.random.default_rng(int(level * 100))
    ratios = []
    for _ in range(20):
        noisy = h + level * np.std(h) * rng.standard_normal(h.size)
        b1, a1 = prony(noisy, 4, 4)
        if not is_stable(a1):
            a1 = stabilize(a1)
            b1 = refit_numerator(noisy, a1, 4)
        b2, a2 = steiglitz_mcbride(noisy, 4, 4)
        assert is_stable(a2)  # the guarantee: always stable
        ratios.append(sad(h, b1, a1) / sad(h, b2, a2))  # errors against the noise-free truth
    # 004 measured 5-10x at 5 % noise; we require the refinement to win in most cases and by >= 2x in the median
    assert np.mean(np.array(ratios) > 1.0) >= 0.8
    assert np.median(ratios) > 2.0


def test_order_selection_picks_the_true_order():
    b, a = _filter(b=(0.2, 1.0, -0.4, 0.2, 0.0))
    h = impulse_response(b, a, 100)
    fit = fit_iir(h, orders=range(1, 9))
    # orders < 4 cannot represent 4 poles; 4 is exact so higher orders cannot improve by > 2 %
    assert fit.p == 4 and fit.sad < 1e-9


def test_bad_inputs():
    with pytest.raises(ValueError, match="at least"):
        prony(np.ones(5), 4, 4)
    with pytest.raises(ValueError, match="NaN"):
        prony(np.r_[1.0, np.nan, np.zeros(20)], 2, 2)
    b, a = prony(np.zeros(30), 2, 2)  # a zero response: no NaN out
    assert np.all(np.isfinite(b)) and np.all(np.isfinite(a))


@pytest.mark.parametrize("true_order", [2, 4])
def test_bic_picks_the_true_order_under_noise(true_order):
    """criterion='bic' (n ln(RSS/n) + k ln n): the true order of a noisy response, not a higher one that fits the noise."""
    from flowtex.datasets.patterns import parallel, resonance
    from flowtex.dsp.prony import bic

    filt = resonance(120.0, 0.0095, 1000.0)
    if true_order == 4:
        filt = parallel([filt, resonance(300.0, 0.006, 1000.0)])
    clean = impulse_response(*filt, 80)
    h = clean + 0.02 * np.max(np.abs(clean)) * np.random.default_rng(true_order).standard_normal(80)
    fit = fit_iir(h, orders=range(1, 9), criterion="bic")
    assert fit.p == true_order
    big = fit_iir(h, orders=[8])
    assert big.sad < fit.sad and bic(h, fit.b, fit.a) < bic(h, big.b, big.a)  # order 8 fits the noise better, and pays for it
    with pytest.raises(ValueError, match="unknown criterion"):
        fit_iir(h, orders=[2], criterion="aic")
