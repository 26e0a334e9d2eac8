"""An ARMA model's output power by scipy's discrete Lyapunov solution: a reference independent of flowtex's one
computation (the normalized lattice's ladder weights, flowtex.dsp.arma.filter_power).

var g^2 sum_n h_n^2 of g C(z) / A(z) = var (C P C^T + D^2) for a state-space realisation (A, B, C, D) of it, P solving
P = A P A^T + B B^T. Exact up to the solver's rounding, which grows near the unit circle (two resonances 0.007 rad
apart at radius 0.97 leave it ~7e-7 off; the lattice stays within 1e-9 of the impulse response's energy there).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.signal


def lyapunov_power(ar: np.ndarray, ma: np.ndarray, gain: float, variance: float) -> float:
    """Stationary output power of var, g C(z) / A(z) (units of y squared); ValueError for an unstable A."""
    ar = np.asarray(ar, dtype=np.float64).ravel()
    ma = np.asarray(ma, dtype=np.float64).ravel()
    if ar.size > 1 and np.max(np.abs(np.roots(ar))) >= 1.0:
        raise ValueError("AR polynomial is not stable (a root on or outside the unit circle)")
    num = gain * ma / ar[0]
    den = ar / ar[0]
    n = max(num.size, den.size)
    num = np.r_[num, np.zeros(n - num.size)]
    den = np.r_[den, np.zeros(n - den.size)]
    if n == 1:
        return float(variance * num[0] ** 2)
    A, B, C, D = scipy.signal.tf2ss(num, den)
    P = scipy.linalg.solve_discrete_lyapunov(A, B @ B.T)
    return float(variance * ((C @ P @ C.T)[0, 0] + D[0, 0] ** 2))
