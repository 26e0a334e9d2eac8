"""ARMA estimation: long-AR / Hannan-Rissanen start, then prediction-error (Whittle) Gauss-Newton refinement.

Model (HaTT's convention, see :mod:`flowtex.dsp.arma`): A(z) x = C(z) e with
A = 1 + a1 z^-1 + ... + ap z^-p, C = 1 + c1 z^-1 + ... + cq z^-q, e white
with variance sigma2 (units of x squared).

Why these steps:

1. **Long AR (Burg)** of order L >> p+q whitens x; its residuals are
   estimates of the innovations e (Burg, not Yule-Walker: no window bias for
   poles near the unit circle, and the result is always stable).
2. **Hannan-Rissanen** regression of x_t on its own past and the estimated
   innovations' past gives consistent but inefficient (a, c). The regression
   Gram matrix for all orders up to (P, Q) is built once, so a whole order
   grid is screened with tiny sub-matrix solves (:func:`hr_order_screen`).
3. **Gauss-Newton on the prediction-error variance** sigma2(a, c) =
   (1/M) sum_k S_k |A_k / C_k|^2 over an FFT grid of M frequencies, where
   S_k is the data's zero-padded periodogram (so the sum is the
   autocorrelation-method prediction-error power of the data) or any target
   spectrum (model resampling). For monic minimum-phase A and C the
   Whittle likelihood reduces to this, so the minimiser is the
   (asymptotically efficient) ML estimate. All Gauss-Newton normal-equation
   entries are Toeplitz in the lag, so one iteration costs a few real FFTs
   of length M plus a (p+q)^2 solve, independent of the data length.

Sources: Burg, J. P. (1975), *Maximum entropy spectral analysis*, PhD
thesis, Stanford University (the lattice AR fit of :func:`burg_ar`);
Hannan, E. J. and Rissanen, J. (1982), "Recursive estimation of mixed
autoregressive-moving average order", Biometrika 69(1), 81-94 (the
regression on estimated innovations, :class:`HRDesign`); Whittle, P. (1953),
"Estimation and information in stationary time series", Arkiv for Matematik
2, 423-434 (the frequency-domain likelihood, :func:`whittle_refine`);
Levinson, N. (1947), "The Wiener RMS error criterion in filter design and
prediction", J. Math. Phys. 25, 261-278 (the recursion whose step-down,
:func:`flowtex.dsp.poly.step_down`, tests stability).

Stability and minimum phase: every trial polynomial is stabilised by
:func:`flowtex.dsp.poly.stabilize` (the radius policy: roots outside the unit
circle reflected inside, z -> 1/conj(z), which changes |A(e^jw)| only by a
constant factor, and roots beyond :data:`flowtex.dsp.poly.MAX_RADIUS` pulled
in to it). Nothing is moved further than that.
"""

from __future__ import annotations

import numpy as np

from .poly import MAX_RADIUS, roots_inside, stabilize  # noqa: F401  (re-exported: the one radius policy)


def burg_ar(x: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Burg AR fit (Burg 1975): ([1, a1..aL] of A(z), forward prediction residuals of length N - L).

    Always minimum phase (|reflection coefficients| < 1). O(N L) numpy.
    """
    x = np.asarray(x, dtype=np.float64)
    f = x.copy()
    b = x.copy()
    a = np.array([1.0])
    for _ in range(order):
        fp = f[1:]
        bp = b[:-1]
        den = fp @ fp + bp @ bp
        k = -2.0 * (fp @ bp) / den if den > 0.0 else 0.0
        f = fp + k * bp
        b = bp + k * fp
        ae = np.concatenate([a, [0.0]])
        a = ae + k * ae[::-1]
    return a, f


def long_ar_order(n: int, max_p: int, max_q: int) -> int:
    """Long-AR order used to estimate the innovations: 3 (p+q) but at least 40 and at most n / 10."""
    return int(max(min(max(40, 3 * (max_p + max_q)), n // 10), max_p + max_q + 1))


def lagged_gram(src: list[np.ndarray], lag: list[int], t0: int) -> np.ndarray:
    """Gram matrix G[i, k] = sum_{t=t0}^{n-1} src_i[t - lag_i] src_k[t - lag_k] of lagged copies of a few series.

    Columns of one series with consecutive lags are shifts of each other, so
    only the rows of each series' first lag need dot products over the data;
    every other entry follows from its upper-left neighbour by adding the
    sample entering at t0 - 1 and removing the one leaving at n - 1
    (O(n K + K^2) instead of the O(n K^2) of a matrix product, and no
    multithreaded BLAS call, which stalls on a loaded machine).
    """
    k = len(src)
    n = src[0].shape[0] if k else 0
    G = np.empty((k, k))
    cols = [src[i][t0 - lag[i]:n - lag[i]] for i in range(k)]
    for i in range(k):
        for j in range(i, k):
            if i == 0 or j == 0 or src[i] is not src[i - 1] or src[j] is not src[j - 1] or lag[i] != lag[i - 1] + 1 \
                    or lag[j] != lag[j - 1] + 1:
                G[i, j] = cols[i] @ cols[j]
            else:
                si, sj, li, lj = src[i - 1], src[j - 1], lag[i - 1], lag[j - 1]
                G[i, j] = G[i - 1, j - 1] + si[t0 - 1 - li] * sj[t0 - 1 - lj] - si[n - 1 - li] * sj[n - 1 - lj]
            G[j, i] = G[i, j]
    return G


class HRDesign:
    """Hannan-Rissanen (1982) regression for every order (p, q) <= (P, Q), from one Gram matrix.

    Regressors at time t: -x_{t-1..t-P} and e_{t-1..t-Q} (e: long-AR
    residuals); the response is x_t; t runs over the same samples for every
    order, so residual variances are comparable (BIC).
    """

    def __init__(self, x: np.ndarray, max_p: int, max_q: int, long_order: int | None = None):
        x = np.asarray(x, dtype=np.float64)
        n = x.shape[0]
        L = long_ar_order(n, max_p, max_q) if long_order is None else int(long_order)
        _, resid = burg_ar(x, L)
        e = np.zeros(n)
        e[L:] = resid
        t0 = L + max(max_p, max_q)
        if n - t0 < 2 * (max_p + max_q) + 10:
            raise ValueError(f"{n} samples are too few for ARMA order up to ({max_p}, {max_q})")
        y = x[t0:]
        self.max_p = max_p
        self.max_q = max_q
        self.n = n - t0
        src = [-x] * max_p + [e] * max_q
        lag = list(range(1, max_p + 1)) + list(range(1, max_q + 1))
        self.gram = lagged_gram(src, lag, t0)
        self.zy = np.array([src[i][t0 - lag[i]:n - lag[i]] @ y for i in range(len(src))])
        self.yy = float(y @ y)

    def _index(self, p: int, q: int) -> np.ndarray:
        return np.r_[np.arange(p), self.max_p + np.arange(q)].astype(np.intp)

    def fit(self, p: int, q: int) -> tuple[np.ndarray, np.ndarray, float]:
        """(A, C, residual variance) of the order-(p, q) regression (A, C not yet made minimum phase)."""
        idx = self._index(p, q)
        if idx.size == 0:
            return np.array([1.0]), np.array([1.0]), self.yy / self.n
        G = self.gram[np.ix_(idx, idx)]
        h = self.zy[idx]
        try:
            beta = np.linalg.solve(G, h)
        except np.linalg.LinAlgError:
            beta = np.linalg.lstsq(G, h, rcond=None)[0]
        rss = max(self.yy - float(h @ beta), 1e-300)
        return np.r_[1.0, beta[:p]], np.r_[1.0, beta[p:]], rss / self.n


def hr_order_screen(design: HRDesign, max_p: int, max_q: int) -> np.ndarray:
    """BIC n ln sigma2 + (p + q) ln n of the Hannan-Rissanen regression for every p <= max_p, q <= max_q.

    Returns a (max_p+1, max_q+1) array; (0, 0) is the white-noise model.
    """
    bic = np.empty((max_p + 1, max_q + 1))
    ln_n = np.log(design.n)
    for p in range(max_p + 1):
        for q in range(max_q + 1):
            s2 = design.fit(p, q)[2]
            bic[p, q] = design.n * np.log(s2) + (p + q) * ln_n
    return bic


TAPER = 0.2
"""Tukey taper fraction applied to the data before the periodogram (see :func:`periodogram_grid`)."""


def periodogram_grid(x: np.ndarray, nfft: int | None = None, taper: float = TAPER) -> np.ndarray:
    """Tapered, zero-padded periodogram |X_k|^2 / N on an rfft grid of ``nfft`` >= 2N points (nfft // 2 + 1 values).

    The data are multiplied by a Tukey window (``taper``: fraction of the
    record in the cosine edges) scaled to unit mean square, so the grid
    still sums to the data's power. Why a taper: the prediction-error
    filter A/C of a model with MA zeros at |z| ~ 0.9999 (HaTT) has gain
    ~1e4 at the notch, and a rectangular window's leakage there (the abrupt
    ends of the record) makes the criterion at the *true* model 1e12 times
    the innovation variance; a 20 % Tukey taper brings it back to ~1 while
    keeping 90 % of the samples at full weight. With nfft >= 2N there is no
    circular wrap-around: (1/nfft) sum_k S_k e^{j w_k m} is the (tapered)
    biased sample autocovariance at lag m.
    """
    import scipy.signal

    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    if nfft is None:
        nfft = 1 << int(np.ceil(np.log2(2 * n)))
    if taper > 0.0:
        w = scipy.signal.windows.tukey(n, taper)
        x = x * (w / np.sqrt(np.mean(w * w)))
    X = np.fft.rfft(x, nfft)
    return (X.real ** 2 + X.imag ** 2) / n


def _full_sum(half: np.ndarray, nfft: int) -> float:
    """(1/nfft) sum over the full FFT grid of a real, even spectrum given on the rfft half grid."""
    return float((2.0 * np.sum(half) - half[0] - (half[-1] if nfft % 2 == 0 else 0.0)) / nfft)


_TINY = 1e-300
"""Floor of |C(e^jw)|^2 on the grid: a zero pulled to MAX_RADIUS can sit within rounding of a grid frequency."""


def _spectra(a: np.ndarray, c: np.ndarray, nfft: int) -> tuple[np.ndarray, np.ndarray]:
    """A(e^jw), C(e^jw) on the rfft half grid (one stacked FFT)."""
    import scipy.fft

    buf = np.zeros((2, max(a.shape[0], c.shape[0])))
    buf[0, :a.shape[0]] = a
    buf[1, :c.shape[0]] = c
    F = scipy.fft.rfft(buf, nfft, axis=1)
    return F[0], F[1]


def prediction_error_variance(S: np.ndarray, nfft: int, a: np.ndarray, c: np.ndarray) -> float:
    """(1/M) sum_k S_k |A_k / C_k|^2 over the full grid (S on the rfft half grid of length M // 2 + 1)."""
    A, C = _spectra(a, c, nfft)
    return _full_sum(S * ((A.real ** 2 + A.imag ** 2) / np.maximum(C.real ** 2 + C.imag ** 2, _TINY)), nfft)


def whittle_refine(S: np.ndarray, nfft: int, a: np.ndarray, c: np.ndarray, iterations: int = 30,
                   tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, float]:
    """Gauss-Newton minimisation of the prediction-error variance over monic minimum-phase (A, C) (Whittle 1953).

    ``S``: real spectrum on the rfft half grid (nfft // 2 + 1 values, e.g.
    :func:`periodogram_grid`). ``a``, ``c``: starting polynomials (made
    minimum phase first). Each step solves the Gauss-Newton normal equations
    of the residual r_k = sqrt(S_k) A_k / C_k; steps are Levenberg-Marquardt damped
    (the damping grows until a step lowers the criterion), and iteration
    stops when the relative decrease falls below ``tol`` (for data of n
    samples, 0.01 / n is a change of 0.01 in the log-likelihood). Returns (A, C, sigma2).
    """
    import scipy.fft

    p = a.shape[0] - 1
    q = c.shape[0] - 1
    a = stabilize(a)
    c = stabilize(c)
    f0 = prediction_error_variance(S, nfft, a, c)
    if p + q == 0:
        return a, c, f0
    lags = np.arange(max(p, q) + 1)
    lam = 0.0
    for _ in range(iterations):
        A, C = _spectra(a, c, nfft)
        C2 = np.maximum(C.real ** 2 + C.imag ** 2, _TINY)
        A2 = A.real ** 2 + A.imag ** 2
        Su = S / C2  # spectrum of u = x / C
        spec = np.empty((5, Su.shape[0]), dtype=np.complex128)
        spec[0] = Su  # a-a block (Toeplitz in the lag difference)
        spec[1] = Su * A2 / C2  # c-c block: spectrum of e / C
        spec[2] = Su * A * np.conj(C) / C2  # a-c block (A / C)
        spec[3] = Su * A  # a-gradient: cross-covariance of u and e
        spec[4] = Su * A2 * C / C2  # c-gradient (A2 / conj(C))
        ru, rv, rx, ga, gc = scipy.fft.irfft(spec, nfft, axis=1)
        H = np.empty((p + q, p + q))
        g = np.empty(p + q)
        ii = lags[1:p + 1]
        jj = lags[1:q + 1]
        if p:
            H[:p, :p] = ru[np.abs(ii[:, None] - ii[None, :])]
            g[:p] = ga[ii]
        if q:
            H[p:, p:] = rv[np.abs(jj[:, None] - jj[None, :])]
            g[p:] = -gc[jj]
        if p and q:
            cross = -rx[(ii[:, None] - jj[None, :]) % nfft]
            H[:p, p:] = cross
            H[p:, :p] = cross.T
        d = np.diag(H).copy()
        improved = False
        while lam < 1e8:  # Levenberg-Marquardt damping: shrink after a success, grow after a failure
            try:
                step = -np.linalg.solve(H + lam * np.diag(d), g)
                if not np.all(np.isfinite(step)):
                    raise np.linalg.LinAlgError
            except np.linalg.LinAlgError:
                lam = max(10.0 * lam, 1e-6)
                continue
            a_new = stabilize(np.r_[1.0, a[1:] + step[:p]])
            c_new = stabilize(np.r_[1.0, c[1:] + step[p:]])
            f_new = prediction_error_variance(S, nfft, a_new, c_new)
            if f_new < f0:
                improved = True
                lam = lam / 10.0
                break
            lam = max(10.0 * lam, 1e-6)
        if not improved:
            break
        rel = (f0 - f_new) / f0
        a, c, f0 = a_new, c_new, f_new
        if rel < tol:
            break
    return a, c, f0
