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


EPS = float(np.finfo(np.float64).eps)


LATTICE_SLACK = 64.0
"""Relative error of flowtex's lattice power (filter_power) over eps x the power gain of 1 / A: at most 7.8 over 1500
random models of tests/dsp/test_power_interp.py's strategy against a 2^16-point Parseval sum (2026-11-27), 2e-4 on the
clustered 12-pole model hypothesis found there; 64 is 8x the former."""


def lattice_error_bound(ar: np.ndarray) -> float:
    """Relative error bound of the lattice's output power for the AR polynomial ``ar``: :data:`LATTICE_SLACK` x eps x
    the power gain of 1 / A (mean |1 / A|^2 on a 2^16-point grid, a0 = 1), which grows as resonances cluster near the
    circle, where the step-down's rounding grows too."""
    a = np.asarray(ar, dtype=np.float64).ravel()
    _, h = scipy.signal.freqz([a[0]], a, worN=2**16, whole=True)
    return LATTICE_SLACK * EPS * float(np.mean(np.abs(h) ** 2))


LYAPUNOV_SLACK = 64.0
"""Forward error of :func:`lyapunov_power` over eps x cond(I - A (x) A) of its companion realisation: at most 15.3 over
400 random models of tests/dsp/test_power_interp.py's strategy against a 2^16-point Parseval sum (2026-11-27); 64 is
4x that."""


def lyapunov_error_bound(ar: np.ndarray) -> float:
    """Relative error bound of :func:`lyapunov_power` for the AR polynomial ``ar`` (the solve's condition number times
    eps, times :data:`LYAPUNOV_SLACK`): beyond 1 for clustered resonances, where the solver says nothing."""
    a = np.asarray(ar, dtype=np.float64).ravel()
    n = a.size - 1
    if n < 1:
        return 0.0
    A = scipy.signal.tf2ss(np.r_[1.0, np.zeros(n)], a)[0]
    return LYAPUNOV_SLACK * EPS * float(np.linalg.cond(np.eye(n * n) - np.kron(A, A)))
