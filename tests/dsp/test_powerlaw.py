"""flowtex.dsp.powerlaw: the one least-squares power law in speed and force (trend rule, pooled fit)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.dsp.powerlaw import fit_power_law, power_law_design


@settings(max_examples=50)
@given(b0=st.floats(-5, 5), ks=st.floats(0, 3), kf=st.floats(-1, 3), seed=st.integers(0, 2**32 - 1))
def test_a_noiseless_power_law_is_recovered(b0, ks, kf, seed):
    rng = np.random.default_rng(seed)
    s, f = rng.uniform(130, 320, 9), rng.uniform(0.3, 4.3, 9)
    y = np.exp(b0) * s**ks * f**kf  # ground truth
    for w in (None, rng.integers(50, 5000, 9)):
        np.testing.assert_allclose(fit_power_law(power_law_design(s, f), y, w), [b0, ks, kf], rtol=1e-7, atol=1e-7)


def test_a_weight_counts_as_that_many_copies_of_its_row():
    rng = np.random.default_rng(4)
    s, f, y = rng.uniform(130, 320, 6), rng.uniform(0.3, 4.3, 6), rng.uniform(0.01, 2.0, 6)
    w = np.array([1, 3, 2, 1, 4, 2])
    rep = np.repeat(np.arange(6), w)
    np.testing.assert_allclose(fit_power_law(power_law_design(s, f), y, w),
                               fit_power_law(power_law_design(s[rep], f[rep]), y[rep]), rtol=1e-10, atol=1e-12)
