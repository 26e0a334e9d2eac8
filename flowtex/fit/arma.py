"""Fit one stationary vibration with an ARMA model: :func:`fit_arma`, order choice and fit quality.

The estimator (flowtex.dsp.arma_estimate) is Hannan-Rissanen followed by a
Gauss-Newton minimisation of the prediction-error variance (the Whittle /
ML estimate for monic minimum-phase models). Units: ``x`` in m/s^2 (any unit
works; the model's variance has the square of it).

Order choice (``order=None``): BIC = n ln sigma2 + (p + q) ln n of the refined
(maximum-likelihood) prediction-error variance. Why not Culbertson et al. 2012's GFC + 1/BIC:
1/BIC depends on the units of sigma2 (its sign even flips when sigma2
crosses 1), and GFC is nearly flat across orders (a flat spectrum scores
0.60 against a true ARMA(10,6)), so the sum is dominated by whichever is
larger in the data's units. BIC alone is a consistent order estimator. The
search screens every (p, q) with the cheap Hannan-Rissanen regression
(one Gram matrix for all orders) and refines only the best few candidates.
GFC (Culbertson et al. 2012's definition) and the LSD are reported beside it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..dsp.arma import arma_output_variance, arma_psd
from ..dsp.arma_estimate import MAX_RADIUS, HRDesign, hr_order_screen, periodogram_grid, stabilize, whittle_refine
from ..dsp.lsf import is_valid_lsf
from ..dsp.lsf_roots import poly_to_lsf
from ..dsp.spectral import gfc_data_model, lsd_db, welch_psd
from ..errors import DataError
from ..limits import excerpt
from ..pyvalues import float_signal, plain, positive_rate, whole_count

REFINE_CANDIDATES = 4
"""Number of best orders by the screening BIC that get a quick refinement before the neighbour walk."""
SEARCH_ITERATIONS = 4
"""Gauss-Newton iterations per order during the search (the winner then gets :data:`REFINE_ITERATIONS` more)."""
REFINE_ITERATIONS = 20
"""Gauss-Newton iterations at most (fewer when the log-likelihood stops changing by 0.01). Measured on HaTT-size models
(19/17, 10 s, 10 seeds): median LSD against the truth 0.50 dB after 10 and 0.46 dB after 20, but single models
stuck on a plateau (0.86 dB) after 10 reach 0.3 dB by 20."""


@dataclass
class ArmaFit:
    """An ARMA model fitted to one signal, in HaTT's convention, with its fit statistics.

    y_n = -sum a_i y_{n-i} + g (e_n + sum c_j e_{n-j}), e ~ N(0, variance).
    One-sided PSD in physical units: S(f) = 2 g^2 variance |C/A(e^{j 2 pi f / fs})|^2 / fs.
    """

    ar: np.ndarray
    """[1, a1..ap] of A(z)."""
    ma: np.ndarray
    """[1, c1..cq] of C(z)."""
    gain: float
    """MA gain g: scales the model's output power to the data's variance."""
    variance: float
    """Innovation variance sigma2 (the final prediction error, units of x squared)."""
    order: tuple[int, int]
    """(p, q)."""
    n_samples: int
    """Samples fitted."""
    data_variance: float
    """Variance of the (mean-removed) data."""
    bic: float
    """n ln sigma2 + (p + q) ln n of this fit."""
    gfc: float
    """Culbertson et al. 2012's Goodness-of-Fit Criterion: smoothed data |DFT| against the model's |C/A| (1 = same shape)."""

    @property
    def output_variance(self) -> float:
        """g^2 sigma2 ||C/A||^2, the model's output power (units of x squared)."""
        return arma_output_variance(self.ar, self.ma, self.gain, self.variance)

    @property
    def power_error(self) -> float:
        """Relative error of the model's output power against the data's variance (0.01 = 1 %)."""
        if self.data_variance == 0.0:
            return 0.0
        return self.output_variance / self.data_variance - 1.0

    @property
    def power_error_db(self) -> float:
        """The model's output power over the data's variance in dB (0 dB = the same power; -inf for a silent model)."""
        if self.data_variance == 0.0:
            return 0.0
        ratio = self.output_variance / self.data_variance
        return 10.0 * math.log10(ratio) if ratio > 0.0 else -math.inf

    def psd(self, freqs_hz: np.ndarray, rate_hz: float) -> np.ndarray:
        """One-sided PSD S(f) in (units of x)^2 / Hz at ``freqs_hz`` for a signal sampled at ``rate_hz``."""
        return arma_psd(self.ar, self.ma, self.gain, self.variance, freqs_hz, positive_rate("ArmaFit.psd: rate_hz", rate_hz))

    def lsd_db(self, x: np.ndarray, rate_hz: float, nperseg: int = 1024) -> float:
        """LSD (dB) of the model's PSD against the Welch PSD of ``x`` (the project's definition: > 15 Hz, 40 dB range),
        its segments spread over all of ``x`` (``welch_psd(whole=True)``: a short piece's last samples count too)."""
        rate_hz = positive_rate("ArmaFit.lsd_db: rate_hz", rate_hz)
        freqs, s_data = welch_psd(float_signal("x", x, "ArmaFit.lsd_db: signal"), rate_hz, nperseg, whole=True)
        return lsd_db(self.psd(freqs, rate_hz), s_data, freqs)


def _check_signal(x: np.ndarray) -> np.ndarray:
    x = float_signal("x", x, "fit_arma: signal")  # complex, masked or text refused: converting would change them
    if x.ndim != 1:
        raise DataError(f"fit_arma needs a 1-D signal, got shape {x.shape}: pass one axis (or reduce 3 axes with DFT321)")
    bad = ~np.isfinite(x)
    if np.any(bad):
        raise DataError(f"signal has {int(np.sum(bad))} NaN/inf samples (first at index {int(np.argmax(bad))}): "
                        "remove or interpolate them before fitting")
    return x


def min_phase_for_lsf(poly: np.ndarray) -> np.ndarray:
    """Pull near-unit roots in (doubling their distance to the circle) until the LSFs are strictly increasing."""
    if poly.shape[0] <= 1:
        return poly
    margin = 1.0 - MAX_RADIUS
    for _ in range(20):
        try:
            if is_valid_lsf(poly_to_lsf(poly)):
                return poly
        except ValueError:
            pass
        margin *= 2.0
        poly = stabilize(poly, 1.0 - margin)
    raise DataError("could not make the fitted polynomial minimum phase with valid line spectral frequencies")


def _finish(x: np.ndarray, a: np.ndarray, c: np.ndarray, sigma2: float) -> ArmaFit:
    a = min_phase_for_lsf(a)
    c = min_phase_for_lsf(c)
    n = x.shape[0]
    var_x = float(np.var(x))
    p, q = a.shape[0] - 1, c.shape[0] - 1
    sigma2 = max(float(sigma2), 1e-300)
    unit_power = arma_output_variance(a, c, 1.0, sigma2)
    gain = float(np.sqrt(var_x / unit_power)) if unit_power > 0.0 else 1.0
    return ArmaFit(ar=a, ma=c, gain=gain, variance=sigma2, order=(p, q), n_samples=n, data_variance=var_x,
                   bic=float(n * np.log(sigma2) + (p + q) * np.log(n)), gfc=gfc_data_model(x, a, c))


@dataclass
class _Prepared:
    """One signal ready for fitting: mean removed, Hannan-Rissanen design, periodograms (full and search grids)."""

    x: np.ndarray
    design: HRDesign
    spectrum: np.ndarray
    nfft: int
    search_spectrum: np.ndarray
    search_nfft: int


def _prepare(x: np.ndarray, max_p: int, max_q: int) -> _Prepared:
    x = _check_signal(x)
    xc = x - np.mean(x)
    if not np.any(xc):
        raise DataError("signal is constant: an ARMA model needs a vibration (variance > 0)")
    try:
        design = HRDesign(xc, max_p, max_q)
    except ValueError as exc:
        raise DataError(f"signal too short for the order: {exc}; record longer or lower the order") from None
    # Wrap-around of the tapered autocovariance only at lags > nfft - n, where it is ~0 (measured: 1.5 n and 2 n
    # give the same fits). The order search uses a grid half as fine: ranking orders does not need the last digit.
    nfft = 1 << int(np.ceil(np.log2(1.5 * xc.shape[0])))
    S = periodogram_grid(xc, nfft)
    return _Prepared(xc, design, S, nfft, S[::2].copy(), nfft // 2)


def _refine(prep: _Prepared, a: np.ndarray, c: np.ndarray, search: bool) -> tuple[np.ndarray, np.ndarray, float]:
    S, nfft = (prep.search_spectrum, prep.search_nfft) if search else (prep.spectrum, prep.nfft)
    return whittle_refine(S, nfft, a, c, iterations=SEARCH_ITERATIONS if search else REFINE_ITERATIONS,
                          tol=0.01 / prep.x.shape[0])


def _fit_order(prep: _Prepared, p: int, q: int) -> ArmaFit:
    a0, c0, _ = prep.design.fit(p, q)
    return _finish(prep.x, *_refine(prep, a0, c0, search=False))


def fit_arma(x: np.ndarray, order: tuple[int, int] | None = None, max_order: int = 20) -> ArmaFit:
    """Fit an ARMA(p, q) model to the 1-D signal ``x`` as given (its mean is removed; nothing is filtered).

    ``order=(p, q)`` fixes the order; ``None`` chooses it by BIC over
    p, q <= ``max_order`` (see the module docstring). The result is stable
    and minimum phase with strictly increasing LSFs, and its output power
    equals the data's variance (``gain`` absorbs the difference between the
    innovation variance and the data's power). Raises :class:`DataError`
    for a signal that is not 1-D, has NaN/inf, is constant or too short.
    """
    if order is not None:
        p, q = _order(order)
        return _fit_order(_prepare(x, p, q), p, q)
    return fit_arma_auto([x], whole_count("fit_arma: max_order", max_order, 0))[0]


def _order(order: Any) -> tuple[int, int]:
    """``order`` as two non-negative ints (p, q); numpy integers too, but never a float cut to an int."""
    value = plain(order)
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in value)):
        raise DataError(f"ARMA order must be two non-negative integers (p, q), e.g. order=(19, 17); got {excerpt(order)}")
    return value[0], value[1]


def select_order(bic_grid: np.ndarray, count: int = REFINE_CANDIDATES) -> list[tuple[int, int]]:
    """The ``count`` orders (p, q) with the lowest values in a BIC grid indexed [p, q]."""
    flat = np.argsort(bic_grid, axis=None)[:count]
    return [tuple(int(v) for v in np.unravel_index(i, bic_grid.shape)) for i in flat]


def _search(pieces: Sequence[np.ndarray], max_order: int) -> tuple[tuple[int, int], list[ArmaFit]]:
    """Order search: screen every order cheaply, refine the best few, then walk to lower-BIC neighbours.

    The Hannan-Rissanen screening BIC tends to favour orders with an extra,
    nearly cancelling pole-zero pair, so the true order is often not among
    its best few, while the refined BIC does rank it first. Hence: quick
    refinements (:data:`SEARCH_ITERATIONS` on a coarser grid) of the best
    :data:`REFINE_CANDIDATES` screened orders and of the best screened order
    inside each box p, q <= m for m = 2, 5, 8, ..., then a descent on that BIC over
    the 8 neighbouring orders (smaller ones tried first, moving to the first
    that is lower), then the full refinement of the winner only.
    """
    prepared = [_prepare(x, max_order, max_order) for x in pieces]
    screen = sum(hr_order_screen(prep.design, max_order, max_order) for prep in prepared)
    done: dict[tuple[int, int], tuple[float, list]] = {}

    def bic(order: tuple[int, int]) -> float:
        if order not in done:
            p, q = order
            total = 0.0
            starts = []
            for prep in prepared:
                a0, c0, _ = prep.design.fit(p, q)
                a, c, s2 = _refine(prep, a0, c0, search=True)
                n = prep.x.shape[0]
                total += n * np.log(max(s2, 1e-300)) + (p + q) * np.log(n)
                starts.append((a, c))
            done[order] = (total, starts)
        return done[order][0]

    # the screening's best few, and its best inside each box p, q <= m (m = 2, 5, 8, ...): descents from large
    # orders can stop in a local minimum of the BIC surface far from a low true order
    candidates = select_order(screen) + [select_order(screen[:m + 1, :m + 1], 1)[0] for m in range(2, max_order, 3)]
    for order in candidates:
        bic(order)
    best = min(done, key=bic)
    moved = True
    while moved:
        moved = False
        p, q = best
        for dp, dq in ((-1, -1), (-1, 0), (0, -1), (-1, 1), (1, -1), (0, 1), (1, 0), (1, 1)):
            cand = (p + dp, q + dq)
            if 0 <= cand[0] <= max_order and 0 <= cand[1] <= max_order and bic(cand) < bic(best):
                best = cand
                moved = True
                break
    fits = [_finish(prep.x, *_refine(prep, a, c, search=False)) for prep, (a, c) in zip(prepared, done[best][1], strict=True)]
    return best, fits


def select_shared_order(pieces: Sequence[np.ndarray], max_order: int = 20) -> tuple[int, int]:
    """One order (p, q) for several signals (Culbertson et al. 2012: the same order for every model of a material).

    Minimises the sum of the pieces' BICs (the BIC of the joint model with
    one (p, q) shared and separate coefficients per piece).
    """
    if len(pieces) == 0:
        raise DataError("no signal pieces to choose an order from")
    return _search(pieces, max_order)[0]


def fit_arma_auto(pieces: Sequence[np.ndarray], max_order: int = 20) -> list[ArmaFit]:
    """Fit every piece at the one order :func:`select_shared_order` chooses (the fits are reused, not redone)."""
    if len(pieces) == 0:
        raise DataError("no signal pieces to fit")
    return _search(pieces, max_order)[1]
