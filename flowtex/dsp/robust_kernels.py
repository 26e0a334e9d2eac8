"""Compiled pieces of the IRLS fits (:mod:`flowtex.dsp.robust`, :mod:`flowtex.dsp.hetero`) that give numpy's values
bit for bit.

Why bit for bit: the fits iterate (IRLS until a relative change of 1e-10, median regression until 1e-12), so a
last-bit change in a scale or a weight can move a fitted coefficient in its last bits and a derived figure (an
interval, a rejected sample) with it; tests/dsp/test_robust_speed.py checks every fit against the old code kept in
tests/dsp/robust_old.py.

- A median is an order statistic (the mean of the two middle ones for an even count): the same value whatever the
  selection algorithm, and numpy's mean of two values is (a + b) / 2. :func:`median` selects among the values
  inside a bracket found from a sample (:func:`_bracketed`; one pass over the data, then a few % of it), else among
  all, by quickselect (Hoare's partition, median-of-three pivots) on a copy; an array holding a nan has median nan, as numpy's; a selection that
  goes deeper than :data:`DEPTH_PER_BIT` log2(n) + :data:`DEPTH_SLACK` partitions (an adversarial order) hands back
  to ``np.median`` (time stays linear in n).
- The IRLS weights are the elementwise formulas of the numpy code, each operation rounded once as numpy's ufuncs do
  (``x ** 2`` is numpy's ``x * x``; no fused multiply-add: numba does not contract without fastmath).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

HUBER = 0
BISQUARE = 1
DEPTH_PER_BIT = 4
"""A selection gives up after DEPTH_PER_BIT log2(n) + DEPTH_SLACK partitions (quickselect needs about 2 log2(n))."""
DEPTH_SLACK = 16


def _depth(n: int) -> int:
    return DEPTH_PER_BIT * int(np.log2(n + 1)) + DEPTH_SLACK


@njit(cache=True)
def _select(a: np.ndarray, k: int, depth: int) -> tuple[float, bool]:
    """(the k-th smallest value of ``a``, True), ``a`` reordered in place so that a[:k] <= it <= a[k+1:]; (0, False)
    when the selection needs more than ``depth`` partitions (the caller then uses numpy)."""
    lo = 0
    hi = a.shape[0] - 1
    while hi > lo:
        depth -= 1
        if depth < 0:
            return 0.0, False
        mid = (lo + hi) >> 1
        if a[mid] < a[lo]:
            a[mid], a[lo] = a[lo], a[mid]
        if a[hi] < a[lo]:
            a[hi], a[lo] = a[lo], a[hi]
        if a[hi] < a[mid]:
            a[hi], a[mid] = a[mid], a[hi]
        p = a[mid]
        i = lo
        j = hi
        while i <= j:
            while a[i] < p:
                i += 1
            while a[j] > p:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return a[k], True
    return a[k], True


@njit(cache=True)
def _median_inplace(a: np.ndarray, depth: int) -> tuple[float, bool]:
    """(median of ``a``'s values as numpy gives it, True) with ``a`` reordered; (nan, True) if any is nan; (0, False)
    when the selection gave up. ``a`` has at least one value."""
    n = a.shape[0]
    for i in range(n):
        if math.isnan(a[i]):
            return math.nan, True
    h = n // 2
    m, ok = _select(a, h, depth)
    if not ok:
        return 0.0, False
    if n % 2 == 0:
        lo = a[0]
        for i in range(1, h):
            if a[i] > lo:
                lo = a[i]
        m = (lo + m) / 2.0
    return m, True


BRACKET_MIN = 1024
"""Below this many values the median is selected from all of them; from it on, first from a bracket."""


@njit(cache=True)
def _bracketed(src: np.ndarray, buf: np.ndarray, depth: int) -> tuple[float, int]:
    """The median of ``src`` (not modified) selected among the values inside a bracket (Floyd & Rivest 1975,
    "Expected time bounds for selection", CACM 18:165): sort an evenly spaced sample of n^(2/3) values, bracket the
    median's rank by about 2 sqrt(sample) sample ranks either side, count the values below the bracket in one pass
    and copy those inside to ``buf``; the median is then selected among the copies (a few % of n). Returns
    (median, 1); (nan, 1) if any value is nan; (0, 0) when the bracket missed the middle ranks or the selection gave
    up (the caller selects among all values)."""
    n = src.shape[0]
    m = int(n ** (2.0 / 3.0))
    step = n // m
    smp = np.empty(m)
    for i in range(m):
        smp[i] = src[i * step]
    smp = np.sort(smp)
    h = n // 2
    ks = (h * m) // n
    gap = int(2.0 * math.sqrt(m)) + 2
    if ks - gap < 0 or ks + gap >= m:
        return 0.0, 0
    lo = smp[ks - gap]
    hi = smp[ks + gap]
    below = 0
    inside = 0
    nans = 0
    max_below = -math.inf
    for i in range(n):  # without branches (the data decide them at random): write always, advance when inside
        v = src[i]
        under = v < lo
        below += under
        max_below = max(max_below, v if under else -math.inf)
        buf[inside] = v
        inside += (v >= lo) & (v <= hi)
        nans += v != v
    if nans:
        return math.nan, 1
    if not below <= h < below + inside:
        return 0.0, 0
    part = buf[:inside]
    med, ok = _select(part, h - below, depth)
    if not ok:
        return 0.0, 0
    if n % 2 == 0:
        low = max_below
        for i in range(h - below):
            if part[i] > low:
                low = part[i]
        med = (low + med) / 2.0
    return med, 1


@njit(cache=True)
def _median_of(src: np.ndarray, buf: np.ndarray, depth: int) -> tuple[float, bool]:
    """(numpy's median of ``src``, True), ``src`` kept, ``buf`` (same length) overwritten; (0, False) when the
    selection gave up."""
    if src.shape[0] >= BRACKET_MIN:
        med, found = _bracketed(src, buf, depth)
        if found:
            return med, True
    buf[:] = src
    return _median_inplace(buf, depth)


@njit(cache=True)
def _median_kernel(x: np.ndarray, depth: int) -> tuple[float, bool]:
    return _median_of(x, np.empty(x.shape[0]), depth)


@njit(cache=True)
def _mad_kernel(r: np.ndarray, work: np.ndarray, depth: int) -> tuple[float, bool]:
    """(median |r - median r|, True) as numpy gives it, or (0, False) when a selection gave up; ``work`` (2, n) is
    overwritten."""
    n = r.shape[0]
    buf = work[0]
    m, ok = _median_of(r, buf, depth)
    if not ok:
        return 0.0, False
    dev = work[1]
    for i in range(n):
        dev[i] = abs(r[i] - m)
    return _median_of(dev, buf, depth)


def median(x: np.ndarray) -> float:
    """``float(np.median(x))`` of a 1-d float64 array, bit for bit, without numpy's sort-based overhead."""
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    if x.shape[0] == 0:
        return float(np.median(x))
    m, ok = _median_kernel(x, _depth(x.shape[0]))
    return float(m) if ok else float(np.median(x))


def mad(r: np.ndarray, work: np.ndarray | None = None) -> float:
    """``float(np.median(np.abs(r - np.median(r))))`` of a 1-d float64 array, bit for bit (module docstring).

    ``work``: scratch of shape (2, len(r)) to reuse between calls (an iteration's allocations cost, in page faults,
    as much as its selections); None allocates it.
    """
    r = np.ascontiguousarray(r, dtype=np.float64).reshape(-1)
    if r.shape[0] > 0:
        if work is None or work.shape != (2, r.shape[0]):
            work = np.empty((2, r.shape[0]))
        d, ok = _mad_kernel(r, work, _depth(r.shape[0]))
        if ok:
            return float(d)
    return float(np.median(np.abs(r - np.median(r))))


@njit(cache=True, error_model="numpy")
def weighted_rows(X: np.ndarray, y: np.ndarray, r: np.ndarray, s: float, kind: int, huber_k: float,
                  bisquare_c: float, w: np.ndarray, Xw: np.ndarray, yw: np.ndarray) -> None:
    """Into ``w``, ``Xw``, ``yw``: w, X * sqrt(w)[:, None], y * sqrt(w), the IRLS weights of the residuals ``r`` at
    scale ``s`` and the reweighted rows, each value as the numpy formulas they replaced give it
    (tests/dsp/robust_old.py).

    Huber: w = 1 where |u| <= k, else k / max(|u|, 1e-300); bisquare: (1 - (u / c)^2)^2 where |u| < c, else 0;
    u = r / s.
    """
    n, k = X.shape
    for i in range(n):
        u = r[i] / s
        a = abs(u)
        if kind == HUBER:
            if a <= huber_k:
                wi = 1.0
            else:
                wi = huber_k / (1e-300 if a < 1e-300 else a)
        else:
            if a < bisquare_c:
                v = u / bisquare_c
                t = 1.0 - v * v
                wi = t * t
            else:
                wi = 0.0
        w[i] = wi
        sw = math.sqrt(wi)
        for j in range(k):
            Xw[i, j] = X[i, j] * sw
        yw[i] = y[i] * sw
