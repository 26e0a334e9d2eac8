"""Polynomial or roots -> line spectral frequencies, in double precision (numpy; run at fit and resample time).

The convention (which LSF belongs to which of S and D, orders even and odd) is the one
:mod:`flowtex.dsp.lsf` states; there is the per-tick inverse, :func:`flowtex.dsp.lsf.lsf_to_poly`.
"""

from __future__ import annotations

import math

import numpy as np

from .lsf import is_valid_lsf


def _half_product_roots(a: np.ndarray, sign: float, trivial: np.ndarray) -> np.ndarray:
    """Angles in (0, pi) of the roots of A(z) + sign z^-(p+1) A(z^-1) after dividing out ``trivial``.

    The deflated polynomial is palindromic of even degree 2m; on the unit
    circle e^{jmw} R(e^{jw}) = r_m + 2 sum_k r_k cos((m-k) w) is a Chebyshev
    series in x = cos w, whose m real roots in (-1, 1) are found with the
    (well conditioned) colleague matrix and then polished by Newton's method
    in w (:func:`_polish`), which stays accurate for roots near 0 and pi where
    arccos is not. Source of the substitution x = cos w (the LSF root search
    on Chebyshev polynomials): Kabal, P. and Ramachandran, R. P. (1986), "The
    computation of line spectral frequencies using Chebyshev polynomials",
    IEEE Trans. Acoustics, Speech, and Signal Processing 34(6), 1419-1426;
    they search sign changes on a grid, here the colleague matrix (Good 1961)
    finds all m roots at once.
    """
    p = a.shape[0] - 1
    full = np.zeros(p + 2)
    full[: p + 1] += a
    full[1:] += sign * a[::-1]
    # deflate: exact synthetic division by the trivial factor (coefficients in z^-1)
    r = full
    for fac in trivial:
        # divide r by (1 + fac z^-1)
        q = np.zeros(r.shape[0] - 1)
        acc = 0.0
        for k in range(q.shape[0]):
            acc = r[k] - fac * acc
            q[k] = acc
        r = q
    m = (r.shape[0] - 1) // 2
    if m == 0:
        return np.zeros(0)
    r = 0.5 * (r + r[::-1])  # enforce exact palindromic symmetry
    cheb = np.empty(m + 1)
    cheb[0] = r[m]
    cheb[1:] = 2.0 * r[m - 1 :: -1]
    x = np.polynomial.chebyshev.chebroots(cheb)
    if np.any(np.abs(x.imag) > 1e-6) or x.shape[0] != m:
        raise ValueError("polynomial is not minimum phase (line spectral roots are off the unit circle)")
    w = np.sort(np.arccos(np.clip(x.real, -1.0, 1.0)))
    return _polish(a, w, sign)


def _polish(a: np.ndarray, w: np.ndarray, sign: float) -> np.ndarray:
    """Newton-polish line spectral roots ``w`` of S (sign +1) or D (sign -1) in extended precision.

    On the unit circle, with h = (p+1)/2, e^{jwh} S(e^{jw}) = 2 sum_k a_k cos((h-k) w) and
    e^{jwh} D(e^{jw}) = 2j sum_k a_k sin((h-k) w): evaluated straight from ``a`` (no deflation,
    no basis change) in numpy's long double, so cancellation among large coefficients (which
    reach ~1e2 for clustered poles near z = 1) does not limit the float64 result.
    """
    ld = np.longdouble
    p = a.shape[0] - 1
    orders = (ld(p + 1) / ld(2)) - np.arange(p + 1, dtype=ld)
    al = a.astype(ld)
    wl = w.astype(ld)
    for _ in range(8):
        ang = np.outer(wl, orders)
        if sign > 0:
            f = np.cos(ang) @ al
            df = -(np.sin(ang) @ (al * orders))
        else:
            f = np.sin(ang) @ al
            df = np.cos(ang) @ (al * orders)
        safe = np.where(df != 0, df, ld(1))
        step = np.where(df != 0, f / safe, ld(0))
        w_new = wl - step
        ok = (w_new > 0) & (w_new < ld(np.pi)) & (np.abs(step) < ld(1e-3))
        wl = np.where(ok, w_new, wl)
    return np.sort(wl.astype(np.float64))


def poly_to_lsf(a: np.ndarray) -> np.ndarray:
    """LSFs (radians, increasing in (0, pi), float64) of a monic minimum-phase polynomial.

    ``a`` = [1, a1, ..., ap] in the A(z) = 1 + a1 z^-1 + ... convention (also
    used for MA polynomials C(z)). Accurate to ~1e-13 rad for poles near the
    unit circle, LSF gaps down to 1e-4 and LSFs within 1e-4 of 0 or pi.
    Raises ValueError if ``a`` is not monic, not finite or not minimum phase.
    """
    a = np.asarray(a, dtype=np.float64).ravel()
    if a.shape[0] == 0 or not np.all(np.isfinite(a)):
        raise ValueError("polynomial must be a non-empty finite vector")
    if a[0] != 1.0:
        raise ValueError(f"polynomial must be monic (leading coefficient 1), got {a[0]!r}")
    p = a.shape[0] - 1
    if p == 0:
        return np.zeros(0)
    roots = np.roots(a)
    if roots.size and np.max(np.abs(roots)) >= 1.0:
        raise ValueError(f"polynomial is not minimum phase: a root has magnitude {np.max(np.abs(roots)):.6g} >= 1")
    if p % 2 == 0:
        ws = _half_product_roots(a, 1.0, np.array([1.0]))  # S / (1 + z^-1)
        wd = _half_product_roots(a, -1.0, np.array([-1.0]))  # D / (1 - z^-1)
    else:
        ws = _half_product_roots(a, 1.0, np.zeros(0))
        wd = _half_product_roots(a, -1.0, np.array([1.0, -1.0]))  # D / (1 - z^-2)
    lsf = np.empty(p)
    if ws.shape[0] != (p + 1) // 2 or wd.shape[0] != p // 2:
        raise ValueError("polynomial is not minimum phase (wrong number of line spectral roots)")
    lsf[0::2] = ws
    lsf[1::2] = wd
    if not is_valid_lsf(lsf):
        raise ValueError("polynomial is not minimum phase (line spectral frequencies do not interlace)")
    return lsf


def roots_to_lsf(roots: np.ndarray) -> np.ndarray:
    """LSFs (radians, increasing in (0, pi)) of A(z) = prod (1 - z_i z^-1) from its roots, without forming A.

    ``roots``: all p roots (conjugate pairs complete, |z_i| < 1). With
    phi(w) = arg A(e^jw) = sum atan2(r_i sin(w - t_i), 1 - r_i cos(w - t_i))
    (each term in (-pi/2, pi/2), so no unwrapping), the LSFs are the p
    solutions of psi(w) = (p + 1) w + 2 phi(w) = k pi, k = 1..p (odd k: the
    symmetric polynomial's, even k: the antisymmetric one's); psi rises
    monotonically from 0 to (p + 1) pi (slope >= 1), so bisection finds each to
    ~1e-16. Why: :func:`poly_to_lsf` works from the coefficients, and a
    polynomial whose roots crowd into a small arc near z = 1 (a model upsampled
    2.5x or more) has coefficients of ~1e5 that cancel to |A| ~ 1e-8 in its
    band; evaluated there, even in long double, LSFs come out ~1e-8 off, which
    moves a resonance by 0.3 dB. From the roots, nothing cancels.
    """
    z = np.asarray(roots, dtype=np.complex128).ravel()
    p = z.shape[0]
    if p == 0:
        return np.zeros(0)
    if not np.all(np.isfinite(z)) or np.max(np.abs(z)) >= 1.0:
        raise ValueError("roots must be finite and strictly inside the unit circle")
    r = np.abs(z)
    t = np.angle(z)
    target = math.pi * np.arange(1, p + 1)
    lo = np.zeros(p)
    hi = np.full(p, math.pi)
    for _ in range(64):
        mid = 0.5 * (lo + hi)
        d = mid[:, None] - t[None, :]
        psi = (p + 1) * mid + 2.0 * np.sum(np.arctan2(r * np.sin(d), 1.0 - r * np.cos(d)), axis=1)
        below = psi < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    lsf = 0.5 * (lo + hi)
    if not is_valid_lsf(lsf):
        raise ValueError("roots too close to the unit circle: their line spectral frequencies coincide in float64")
    return lsf
