"""Line spectral frequencies (LSF) <-> polynomial, in double precision.

Convention (the one of HaTT and of MATLAB's ``poly2lsf``/``lsf2poly``): for a
monic polynomial A(z) = 1 + a1 z^-1 + ... + ap z^-p of order p, let

    S(z) = A(z) + z^-(p+1) A(z^-1)      (palindromic, degree p+1)
    D(z) = A(z) - z^-(p+1) A(z^-1)      (anti-palindromic, degree p+1)

so that A = (S + D) / 2. A is minimum phase iff all roots of S and D lie on
the unit circle, are simple and interlace. The LSFs are the angles in (0, pi)
of those roots, sorted, without the trivial roots at z = +-1. For the LSF
vector w (0-based): the even-index ones w[0], w[2], ... are S's conjugate
root pairs, the odd-index ones w[1], w[3], ... are D's. For even p,
S = (1 + z^-1) * prod_even and D = (1 - z^-1) * prod_odd; for odd p,
S = prod_even and D = (1 - z^-2) * prod_odd (the smaller product gets the
(1 - z^-2) factor), where each product is over second-order factors
1 - 2 cos(w) z^-1 + z^-2.

HaTT rebuilds polynomials from LSFs in single precision (its coefficients are
off by up to 2.4e-3, pole radii by up to 0.13 on real surfaces); everything
here is float64 and :func:`lsf_to_poly` allocates nothing, so it can run
every tick inside a graph kernel.

Storage trick of :func:`lsf_to_poly`: both products are palindromic, so only
their first half (without the leading 1) is needed: the even-index product's
half goes ascending into ``out[1..ne]``, the odd-index product's half into
``out[ne+1..p]`` (ne = ceil(p/2)); together they take exactly p slots, and
before the products are built the same slots hold the factors' -2 cos(w).
The odd half is then reversed (``out[p], out[p-1], ...``) and the final combination A[k] = (S[k] + D[k]) / 2, A[p+1-k] = (S[k] - D[k]) / 2
is then an in-place butterfly on the slot pair (k, p+1-k).

This module holds the per-tick direction (numba kernels: LSF -> polynomial, validity, repair).
The other direction, polynomial or roots -> LSF (numpy, run when a model is fitted or
resampled), is in :mod:`flowtex.dsp.lsf_roots`; ``poly_to_lsf`` and ``roots_to_lsf`` still
import from here, lazily.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..moved import moved_names
from .fastmath import FASTMATH

DEFAULT_MIN_GAP = 1e-6
"""Smallest gap (rad) :func:`repair_lsf` accepts between neighbouring LSFs and to 0 and pi.

Published HaTT surfaces have MA LSF gaps down to 2e-4 rad and LSFs within
5e-4 rad of pi; 1e-6 is 200x below both, so no real model is ever altered.
An isolated close pair (or one LSF next to 0 or pi) at this gap still gives a
float64 polynomial that is minimum phase (pole ~1e-6 inside the circle, far
above the ~1e-15 rounding of the coefficients). Limit: a cluster of three or
more LSFs within ~1e-4 of each other puts a pole so close to the circle that
float64 coefficients no longer resolve it (it can land on or outside the
circle); no LSF-side gap small enough to leave real models alone prevents
that, so consumers of the coefficients (arma_synth) check the reflection
coefficients and refuse such models.
"""


# Taylor coefficients (-1)^n / (2n+1)! of sin, n = 1..11 (n = 0 is 1); see _minus_2cos.
_S1, _S2, _S3, _S4, _S5, _S6, _S7, _S8, _S9, _S10, _S11 = ((-1) ** n / math.factorial(2 * n + 1) for n in range(1, 12))
_PIO2_HI = 1.5707963267948966  # float64 nearest pi/2
_PIO2_LO = 6.123233995736766e-17  # pi/2 - _PIO2_HI

_FAST = FASTMATH
"""numba fast-math flags: FMA contraction only, unless FLOWTEX_CONTRACT=0 (flowtex.dsp.fastmath)."""


@njit(cache=True, inline="always", fastmath=_FAST)
def _minus_2cos(x):
    """-2 cos(x) for x in [0, pi], inline and branch-free (no libm call), absolute error <= 6e-16 (3 ulp of 2).

    cos(x) = -sin(t) with t = x - pi/2 in [-pi/2, pi/2] (pi/2 subtracted in two
    parts, Cody-Waite), sin by its Taylor series to degree 23 (truncation
    < 1e-20 on that interval) in Horner form. Being a plain polynomial it
    overlaps with the product recursion in the CPU pipeline, which is why it
    beats a libm call (about 5-9 ns each) per factor.
    """
    t = (x - _PIO2_HI) - _PIO2_LO
    u = t * t
    r = _S11
    r = r * u + _S10
    r = r * u + _S9
    r = r * u + _S8
    r = r * u + _S7
    r = r * u + _S6
    r = r * u + _S5
    r = r * u + _S4
    r = r * u + _S3
    r = r * u + _S2
    r = r * u + _S1
    return 2.0 * (t + t * (u * r))


@njit(cache=True, inline="always", fastmath=_FAST)
def _half_product(out, base, m):
    """Half of prod_{i=1..m} (1 + b_i z^-1 + z^-2) in place: out[base + i] holds b_i on entry, coefficient i on exit.

    The product is palindromic of degree 2m, so coefficients 1..m determine it
    (coefficient 0 is an implicit 1; out[base] is never read or written).
    Multiplying a degree-2(i-1) product s by factor i gives
    r[k] = s[k] + b_i s[k-1] + s[k-2], with s[i] = s[i-2] by symmetry for the
    new middle (r[i] = 2 s[i-2] + b_i s[i-1]), which lands on the slot that held
    b_i (read first); later factors' b's sit above it, untouched. k = 1, 2 (which
    would read the implicit 1 or a 0) are peeled off, so the inner loop has
    no branches, and it walks downwards with the old values rolling through
    registers (one load per coefficient).
    """
    if m >= 2:
        b = out[base + 2]
        f1 = out[base + 1]
        out[base + 2] = (1.0 + b * f1) + 1.0
        out[base + 1] = f1 + b
    for i in range(3, m + 1):
        b = out[base + i]
        s1 = out[base + i - 1]
        s2 = out[base + i - 2]
        out[base + i] = (s2 + b * s1) + s2
        for k in range(base + i - 1, base + 2, -1):
            s3 = out[k - 2]
            out[k] = (s1 + b * s2) + s3
            s1 = s2
            s2 = s3
        out[base + 2] = (s1 + b * s2) + 1.0
        out[base + 1] = s2 + b
    return m


@njit(cache=True, fastmath=_FAST)
def lsf_to_poly(lsf: np.ndarray, out: np.ndarray) -> None:
    """Monic polynomial of order p = len(lsf) from its LSFs (radians, increasing in (0, pi)).

    Writes the p+1 coefficients [1, a1, ..., ap] of A(z) = 1 + a1 z^-1 + ...
    into ``out`` (length >= p+1). No allocation, no scratch. The result is
    minimum phase whenever ``lsf`` is strictly increasing in (0, pi); the
    caller checks that (see :func:`is_valid_lsf`, :func:`repair_lsf`).

    Cost (orders 19 and 17 together, shared 2-core machine): ~0.25 us,
    against ~0.8 us for the first version (a libm cosine per factor, a branch
    per coefficient read); see benchmarks/bench_texture.py. Accuracy is that of
    the products themselves (float64 rounding amplified by cancellation among
    coefficients, ~1e-12 relative to the largest coefficient at order 20):
    the cosines add at most ~2 ulp. Entries outside [0, pi] (or NaN) fall
    back to libm's cosine for the whole vector.
    """
    p = lsf.shape[0]
    out[0] = 1.0
    if p == 0:
        return
    ne = (p + 1) // 2
    no = p // 2
    fast = True
    for i in range(p):
        w = lsf[i]
        if not (w >= 0.0 and w <= math.pi):  # also False for NaN
            fast = False
    # b = -2 cos(w) of every factor, even-index LSFs into out[1..ne], odd-index into out[ne+1..p]: a tight loop of
    # polynomials the compiler vectorises (libm only for vectors with entries outside [0, pi]).
    # Factors are multiplied lowest, highest, second lowest, second highest, ... LSF (slot k takes LSF number
    # k // 2 or n - 1 - k // 2 of its group): a product of factors that all sit near z = 1 (or all near -1) has
    # binomial-sized coefficients that cancel later and whose rounding swamps a spectrum spanning 100 dB or more
    # (a 1 kHz HaTT model upsampled 4x: 20-50 dB off when multiplied in increasing order, < 0.01 dB interleaved).
    if fast:
        for k in range(ne):
            j = k // 2 if k % 2 == 0 else ne - 1 - k // 2
            out[1 + k] = _minus_2cos(lsf[2 * j])
        for k in range(no):
            j = k // 2 if k % 2 == 0 else no - 1 - k // 2
            out[ne + 1 + k] = _minus_2cos(lsf[2 * j + 1])
    else:
        for k in range(ne):
            j = k // 2 if k % 2 == 0 else ne - 1 - k // 2
            out[1 + k] = -2.0 * math.cos(lsf[2 * j])
        for k in range(no):
            j = k // 2 if k % 2 == 0 else no - 1 - k // 2
            out[ne + 1 + k] = -2.0 * math.cos(lsf[2 * j + 1])
    _half_product(out, 0, ne)
    _half_product(out, ne, no)
    # odd half: ascending in out[ne+1..p] -> descending (O[k] in out[p+1-k]) for the in-place butterfly below
    lo = ne + 1
    hi = p
    while lo < hi:
        t = out[lo]
        out[lo] = out[hi]
        out[hi] = t
        lo += 1
        hi -= 1
    if p % 2 == 0:
        # S = prod_even * (1 + z^-1): S[k] = E[k] + E[k-1], k = 1..ne (ne = p/2, E[0] = 1)
        for k in range(ne, 1, -1):
            out[k] = out[k] + out[k - 1]
        out[1] = out[1] + 1.0
        # D = prod_odd * (1 - z^-1): D[k] = O[k] - O[k-1], k = 1..no (O[k] in out[p+1-k], O[0] = 1)
        for k in range(no, 1, -1):
            out[p + 1 - k] = out[p + 1 - k] - out[p + 2 - k]
        out[p] = out[p] - 1.0
        # Butterfly on slot pairs (k, p+1-k), k = 1..p/2.
        for k in range(1, p // 2 + 1):
            s = out[k]
            d = out[p + 1 - k]
            out[k] = 0.5 * (s + d)
            out[p + 1 - k] = 0.5 * (s - d)
    else:
        # S = prod_even (degree p+1, its half k = 1..(p+1)/2 is in place already).
        # D = prod_odd * (1 - z^-2): D[k] = O[k] - O[k-2], k = 1..no (O[0] = 1, O[-1] = 0); middle D[(p+1)/2] = 0.
        for k in range(no, 2, -1):
            out[p + 1 - k] = out[p + 1 - k] - out[p + 3 - k]
        if no >= 2:
            out[p - 1] = out[p - 1] - 1.0
        for k in range(1, no + 1):
            s = out[k]
            d = out[p + 1 - k]
            out[k] = 0.5 * (s + d)
            out[p + 1 - k] = 0.5 * (s - d)
        mid = (p + 1) // 2
        out[mid] = 0.5 * out[mid]


def lsf_to_poly_new(lsf: np.ndarray) -> np.ndarray:
    """Allocating convenience wrapper of :func:`lsf_to_poly` for Python callers."""
    lsf = np.ascontiguousarray(lsf, dtype=np.float64)
    out = np.empty(lsf.shape[0] + 1)
    lsf_to_poly(lsf, out)
    return out


@njit(cache=True)
def is_valid_lsf(lsf: np.ndarray, min_gap: float = 0.0) -> bool:
    """True if ``lsf`` is finite, strictly increasing and inside (0, pi) with all gaps >= ``min_gap``.

    With ``min_gap = 0`` this is exactly the condition for the polynomial to
    be minimum phase. Gaps are also measured to 0 and to pi.
    """
    prev = 0.0
    for i in range(lsf.shape[0]):
        w = lsf[i]
        if not (w - prev > 0.0 and w - prev >= min_gap):  # False for NaN too
            return False
        prev = w
    last = math.pi - prev
    return last > 0.0 and last >= min_gap


@njit(cache=True)
def repair_lsf(lsf: np.ndarray, min_gap: float = DEFAULT_MIN_GAP) -> bool:
    """Make ``lsf`` a valid LSF vector in place, changing it only where it is invalid.

    A vector that is already valid (finite, increasing, every gap -- also to
    0 and pi -- at least ``min_gap``) is left bit-for-bit unchanged and False
    is returned. Otherwise, and True is returned:

    * out-of-order entries are sorted;
    * entries closer than ``min_gap`` to 0 or pi, or outside (0, pi), are
      moved to ``min_gap`` / ``pi - min_gap``;
    * coincident entries (gap < ``min_gap``) are pushed apart to ``min_gap``
      (forward pass, then a backward pass if the top hit pi).

    Non-finite entries (NaN, inf): the whole vector is replaced by the LSFs of
    A(z) = 1, i.e. (k+1) pi / (p+1). A NaN means the source of the vector is
    broken, so its other entries are not trusted either; the result is a flat,
    valid model rather than a propagated NaN. Callers that can do better
    (texture_lookup holds the last valid model on NaN input) should not pass
    NaN here. Choose ``min_gap`` well below real gaps (see
    :data:`DEFAULT_MIN_GAP`) and below pi / (p+1).
    """
    p = lsf.shape[0]
    if is_valid_lsf(lsf, min_gap):
        return False
    for i in range(p):
        if not math.isfinite(lsf[i]):
            for j in range(p):
                lsf[j] = (j + 1) * math.pi / (p + 1)
            return True
    # insertion sort (p is small)
    for i in range(1, p):
        w = lsf[i]
        j = i - 1
        while j >= 0 and lsf[j] > w:
            lsf[j + 1] = lsf[j]
            j -= 1
        lsf[j + 1] = w
    lo = min_gap
    hi = math.pi - min_gap
    for i in range(p):
        if lsf[i] < lo:
            lsf[i] = lo
        elif lsf[i] > hi:
            lsf[i] = hi
    for i in range(1, p):
        if lsf[i] - lsf[i - 1] < min_gap:
            lsf[i] = lsf[i - 1] + min_gap
    if p > 0 and lsf[p - 1] > hi:
        lsf[p - 1] = hi
        for i in range(p - 2, -1, -1):
            if lsf[i + 1] - lsf[i] < min_gap:
                lsf[i] = lsf[i + 1] - min_gap
    return True


__getattr__ = moved_names(__name__, dict.fromkeys(("poly_to_lsf", "roots_to_lsf"), "flowtex.dsp.lsf_roots"))
"""Names that moved to :mod:`flowtex.dsp.lsf_roots` still import from here (lazily: lsf_roots imports this module)."""
