"""Lower-order texture models: the Levinson step-down of each polynomial, power kept.

A(z) of order p has reflection coefficients k_1..k_p (|k| < 1 for a
minimum-phase polynomial). Stepping down, A_{m-1}(z) = (A_m(z) - k_m z^-m
A_m(1/z)) / (1 - k_m^2) with k_m the last coefficient of A_m, gives the
order-m' predictor that shares A's first m' reflection coefficients: the
order-m' all-pole model with the same first m' autocorrelation lags as 1/A
(Levinson), and minimum phase by construction. C(z) is treated the same way.
The excitation variance is then rescaled so the reduced model's output power
(:func:`flowtex.dsp.arma.arma_output_variance`) equals the full model's: the
vibration power -- the texture's salience -- is kept, the spectral detail goes.
"""

from __future__ import annotations

import numpy as np

from .arma import arma_output_variance
from .lsf import lsf_to_poly_new
from .lsf_roots import poly_to_lsf
from .poly import step_down  # noqa: F401  (re-exported)


def truncate_models(ar_lsf: np.ndarray, ma_lsf: np.ndarray, variance: np.ndarray, gain: np.ndarray,
                    ar_order: int, ma_order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ar_lsf, ma_lsf, variance) of every model reduced to orders (ar_order, ma_order), output power kept."""
    count = ar_lsf.shape[0]
    new_ar = np.empty((count, ar_order))
    new_ma = np.empty((count, ma_order))
    new_var = np.asarray(variance, dtype=np.float64).copy()
    for m in range(count):
        a = lsf_to_poly_new(ar_lsf[m])
        c = lsf_to_poly_new(ma_lsf[m])
        a2 = step_down(a, ar_order)
        c2 = step_down(c, ma_order)
        new_ar[m] = poly_to_lsf(a2)
        new_ma[m] = poly_to_lsf(c2)
        if new_var[m] > 0:
            full = arma_output_variance(a, c, gain[m], 1.0)
            reduced = arma_output_variance(a2, c2, gain[m], 1.0)
            new_var[m] *= full / reduced
    return new_ar, new_ma, new_var
