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

Stability and minimum phase: every trial polynomial has its roots outside
the unit circle reflected inside (z -> 1/conj(z), which changes |A(e^jw)|
only by a constant factor) and roots closer than :data:`MAX_RADIUS` to the
circle pulled in to it. Nothing is moved further than that.
"""

from __future__ import annotations

import numpy as np

MAX_RADIUS = 1.0 - 1e-5
"""Largest root radius kept (AR poles and MA zeros). HaTT's MA zeros sit at |z| ~ 0.9999, 10x further in; at 1 - 1e-5
the line spectral frequencies of an isolated root pair near z = -1 are still ~1e-5 rad apart, which
:func:`flowtex.dsp.lsf.poly_to_lsf` resolves (the caller checks and pulls further in only if it does not)."""


def burg_ar(x: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Burg AR fit: ([1, a1..aL] of A(z), forward prediction residuals of length N - L).

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


class HRDesign:
    """Hannan-Rissanen regression for every order (p, q) <= (P, Q), from one Gram matrix.

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
        m = n - t0
        cols = [-x[t0 - i:n - i] for i in range(1, max_p + 1)] + [e[t0 - j:n - j] for j in range(1, max_q + 1)]
        Z = np.stack(cols, axis=1) if cols else np.zeros((m, 0))
        y = x[t0:]
        self.max_p = max_p
        self.max_q = max_q
        self.n = m
        self.gram = Z.T @ Z
        self.zy = Z.T @ y
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


def stabilize(poly: np.ndarray, max_radius: float = MAX_RADIUS) -> np.ndarray:
    """Monic polynomial with roots outside the unit circle reflected in and roots beyond ``max_radius`` pulled to it.

    A polynomial already inside ``max_radius`` is returned unchanged (same
    array values). Reflection keeps |P(e^jw)| up to a constant factor.
    """
    poly = np.asarray(poly, dtype=np.float64)
    if poly.shape[0] <= 1:
        return poly
    roots = np.roots(poly)
    r = np.abs(roots)
    if np.all(r <= max_radius):
        return poly
    big = r > 1.0
    roots = np.where(big, 1.0 / np.conj(roots), roots)
    r = np.abs(roots)
    roots = np.where(r > max_radius, roots * (max_radius / np.maximum(r, 1e-300)), roots)
    out = np.real(np.poly(roots))
    return out / out[0]


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


def prediction_error_variance(S: np.ndarray, nfft: int, a: np.ndarray, c: np.ndarray) -> float:
    """(1/M) sum_k S_k |A_k / C_k|^2 over the full grid (S on the rfft half grid of length M // 2 + 1)."""
    A = np.fft.rfft(a, nfft)
    C = np.fft.rfft(c, nfft)
    return _full_sum(S * (np.abs(A) ** 2 / np.abs(C) ** 2), nfft)


def whittle_refine(S: np.ndarray, nfft: int, a: np.ndarray, c: np.ndarray, iterations: int = 30,
                   tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, float]:
    """Gauss-Newton minimisation of the prediction-error variance over monic minimum-phase (A, C).

    ``S``: real spectrum on the rfft half grid (nfft // 2 + 1 values, e.g.
    :func:`periodogram_grid`). ``a``, ``c``: starting polynomials (made
    minimum phase first). Each step solves the Gauss-Newton normal equations
    of the residual r_k = sqrt(S_k) A_k / C_k; steps are Levenberg-Marquardt damped
    (the damping grows until a step lowers the criterion), and iteration stops when the
    relative decrease falls below ``tol``. Returns (A, C, sigma2).
    """
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
        A = np.fft.rfft(a, nfft)
        C = np.fft.rfft(c, nfft)
        C2 = C.real ** 2 + C.imag ** 2
        Su = S / C2  # spectrum of u = x / C
        ru = np.fft.irfft(Su, nfft)  # Toeplitz entries of the a-a block (per 1/M)
        Sv = Su * (A.real ** 2 + A.imag ** 2) / C2  # spectrum of e / C
        rv = np.fft.irfft(Sv, nfft)
        X = Su * A / C  # cross term a-c
        rx = np.fft.irfft(X, nfft)
        ga = np.fft.irfft(Su * A, nfft)  # a-gradient (cross-covariance of u and e)
        gc = np.fft.irfft(Su * (A.real ** 2 + A.imag ** 2) / np.conj(C), nfft)
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
