"""Resample one ARMA model to another sample rate by fitting its physical PSD on the new rate's grid.

A model (A, C, g, sigma2) at rate fs1 has the one-sided PSD in physical units
S(f) = 2 g^2 sigma2 |C/A(e^{j 2 pi f / fs1})|^2 / fs1 for 0 <= f <= fs1 / 2.
The model at rate fs2 keeps S below f_lim = min(fs1, fs2) / 2 and has (ideally)
nothing above it. Both directions start from the original poles and zeros
mapped by z -> z^(fs1 / fs2) (impulse invariance: same resonance frequencies
and bandwidths in Hz), and end by setting the excitation variance so that the
new model's power below 0.9 f_lim equals the original's (upsampling: on the model
rebuilt from its LSFs, as rendered).

**Downsampling** (same order): the target on the new grid w = 2 pi f / fs2 is
T(w) = |C/A(e^{j 2 pi f / fs1})|^2 below the new Nyquist (nothing of what lies
above it is folded in) and an ARMA is fitted to it by the prediction-error
(Whittle) Gauss-Newton of :func:`flowtex.fit.fit_arma`
(:func:`flowtex.dsp.arma_estimate.whittle_refine`). Measured: LSD <= 0.01 dB.

**Upsampling**: the band below the old Nyquist must be kept and the new band
above it left (nearly) empty. Fitting that with the Whittle criterion at the
same order left HaTT-like models 0.4-3 dB (2x) and 1-4 dB (4x) from their
spectrum: the criterion barely penalises a model that lies above the target in
its valleys, and it has to spend poles and zeros on the stopband. Instead the
model's log spectrum is fitted directly (:mod:`flowtex.dsp.arma_logfit`):
residuals 10 log10(model / original) where the original is within 40 dB of
its peak up to :data:`BAND_EDGE` x the old Nyquist (the LSD itself), and
one-sided ceilings elsewhere (the valleys, the edge, and
:data:`STOPBAND_CEILING` above the old Nyquist), by Levenberg-Marquardt with
the roots as parameters (stable and minimum phase by box bounds).

A second limit is numerical: the poles of a model upsampled by R crowd into
the arc |angle| < pi / R near z = 1, and their direct-form coefficients (which
the model set's LSFs become in texture_lookup, and which arma_synth turns into
a lattice) grow to ~1e5 while |A| in the band falls to ~1e-10: float64
coefficients of HaTT's 19 poles (up to r = 0.985) mapped to 4x miss the
spectrum by 2-24 dB from rounding alone. So up to :data:`DIRECT_MAX_RATIO`
(2x) the fit keeps the order (p, q); beyond it the model is fitted at fs2 / M
(M = ceil(R / DIRECT_MAX_RATIO)), stretched by z -> z^M (each root becomes M
roots spread around the circle: the coefficients are the fitted model's, at
most 2x compressed) and cascaded with an all-zero (FIR) lowpass that removes
the M - 1 images (its passband ripple is compensated inside the fit; no poles,
which at the band edge would crowd in with the model's own): orders
(M p, M q + n), n the FIR's order (2.5x to 4x: 38/42 from 19/17). The LSFs
are computed from the roots (:func:`flowtex.dsp.lsf_roots.roots_to_lsf`), not from
the coefficients.

Measured on 30 HaTT-like 19/17 models (benchmarks/bench_model_resample.py),
as rendered (rebuilt from the stored LSFs, on which the variance is matched),
2026-11-23, before the level convention (:data:`STOP_DEPTH_DB`) and the bounded fit:
LSD max / median 0.11 / 0.001 dB at 2x (19/17), 0.009 / 0.001 at 2.5x and
0.08 / 0.001 at 4x (38/42); band power within 0.3 %, power above the old
Nyquist <= 0.06 %. At 6x (57/59) one model of 10 missed (2.4 dB) and 8x
(76/78) fails: the float64 coefficients again; the command names the models
that miss and refuses the set unless --allow-misses.

Why not Culbertson et al. 2012's method (match the autocorrelation at the lags common to both
rates, then correct the noise variance): the ACF at the common lags carries
all of the original's power, including what lies above the new Nyquist when
downsampling, which the new model then folds into its band (+30 % measured).
Why not the zero-order-hold rule (Kuchenbecker & Culbertson 2014: the same coefficients driven by
var2 = var1 fs2 / fs1): a held signal has sinc-shaped images, and 27.6 % of
its power lands above the old Nyquist. Sampling the PSD below min Nyquist
keeps the band exact and puts nothing outside it by construction.
"""

from __future__ import annotations

import math

import numpy as np

from .anti_imaging import elliptic_lowpass, fir_lowpass
from .arma_estimate import whittle_refine
from .arma_logfit import fit_log_spectrum_restarted, real_poly
from .lsf import is_valid_lsf, lsf_to_poly_new
from .lsf_roots import roots_to_lsf
from .poly import MAX_RADIUS, stabilize
from .poly import power_spectrum as _model_power_spectrum
from .poly import root_power_spectrum as _root_power_spectrum

START_RADIUS = 0.999
"""Mapped roots (the fit's start) are pulled to at most this radius; the fit then moves them up to the radius policy's
bound (flowtex.dsp.poly.MAX_RADIUS, and at most twice as sharp as the sharpest original pole)."""

STOPBAND_FLOOR = 1e-4
"""Downsampling: target level above the new Nyquist, relative to the band's mean (-40 dB)."""

DOWN_REFIT_DB = 0.2
"""Downsampling: a prediction-error (Whittle) fit further than this (dB, level fitted out) from the band is refitted
on its log spectrum (:func:`_fit_band`) and the closer of the two kept. Measured: rough, flat-to-Nyquist models
(flowtex.datasets.model_sets.rough_model_set) whose spectra rise towards the new Nyquist left Whittle 42 dB off."""

DIRECT_MAX_RATIO = 2.0
"""Largest upsampling ratio fitted at the original order; beyond it the model is fitted at rate_to / M, M = ceil(ratio / it),
and stretched by z -> z^M (measured on 30 HaTT-like 19/17 models: a direct fit at 2.5x left one model 0.75 dB and 14 %
of band power off, its float64 coefficients missing its spectrum; see docs/fitting.md)."""

STOPBAND_CEILING = 0.005
"""Upsampling: ceiling above the old Nyquist, relative to the band's mean power and divided by (ratio - 1)."""

BAND_EDGE = 0.92
"""Band fitted two-sided: up to this fraction of the old Nyquist (the requirement's 0.9, plus a margin)."""

LSD_RANGE_DB = 40.0
"""The LSD's range (lsd_db's band: frequencies within this of the peak below 0.9 x the old Nyquist)."""

RANGE_MARGIN_DB = 6.0
"""Fitted two-sided: frequencies within LSD_RANGE_DB + this of the peak *below 0.9 x the old Nyquist* (the LSD's
band; a peak above it, up to BAND_EDGE, does not set the range: measured, a 46 dB resonance at 0.908 x the old
Nyquist left the lower band one-sided and 5-10 dB off there); the margin covers a peak sampled off its top."""

BAND_POINTS, EDGE_POINTS, STOP_POINTS = 500, 40, 250
"""Frequencies of the upsampling fit: uniform in the band (plus some around sharp poles), from BAND_EDGE to the old Nyquist, and above it.
Measured on HaTT's sets at 2 kHz: 500 / 250 fit as well as 2000 / 1000 (same worst LSD) at a third of the CPU time
(benchmarks/bench_model_resample.py, docs/fitting.md)."""

PEAK_WIDTHS, PEAK_POINTS = 12.0, 97
"""Around a resonance narrower than the band's step: frequencies over +-PEAK_WIDTHS half-bandwidths, PEAK_POINTS of them
(4 per half-bandwidth; see :func:`_band_grid`)."""

STOP_DEPTH_DB = 30.0
"""Upsampling: every fitted monic model lies STOP_DEPTH_DB (ratio - 1) / ratio dB above the original in the band.

Why: a monic minimum-phase |C/A|^2 has log-mean 0 over the whole circle (Jensen), so how deep the new stopband
lies sets the band's level, and with it the variance that restores the band's power: v2 / v1 = (fs2 / fs1)
x exp(mean of ln|C2/A2|^2 over the stopband). With a free level (the fit's dB offset a free parameter and a
one-sided stopband) that factor varied by 5 dB between neighbouring models of a cork-like set; texture_lookup
interpolates variances linearly, so between vertices the 2 kHz render was up to 1.1 dB off the 1 kHz one (the
shapes within 0.1 dB). With the offset fixed, v2 / v1 is one constant for the set, (fs2 / fs1) 10^(-offset / 10)
(for an original with log-mean 0 in the band, the stopband's log-mean then lies STOP_DEPTH_DB below the band's)."""

GRID = 16384
"""FFT grid of the spectral fit (w resolution 2 pi / GRID: ~3.8e-4 rad, finer than HaTT's sharpest resonances)."""


def _map_roots(poly: np.ndarray, ratio: float) -> np.ndarray:
    """Roots z -> z^ratio (|z|^ratio, angle * ratio); angles beyond 0.98 pi (downsampling) are parked at radius 0.5."""
    if poly.shape[0] <= 1:
        return poly
    roots = np.roots(poly)
    r = np.abs(roots) ** ratio
    ang = np.angle(roots) * ratio
    out = np.abs(ang) > 0.98 * math.pi
    ang = np.where(out, np.sign(ang) * 0.98 * math.pi, ang)
    r = np.where(out, 0.5, np.minimum(r, START_RADIUS))
    new = np.real(np.poly(r * np.exp(1j * ang)))
    return stabilize(new / new[0])


def upsampled_order(p: int, q: int, rate_from: float, rate_to: float, keep_order: bool = False, extra: int = 0,
                    lowpass: bool = False) -> tuple[int, int]:
    """(P, Q) of the models :func:`resample_arma` returns: (p + extra, q + extra) unless upsampling by more than :data:`DIRECT_MAX_RATIO`.

    ``lowpass`` (up to DIRECT_MAX_RATIO): plus the order n of the elliptic edge
    (:func:`flowtex.dsp.anti_imaging.elliptic_lowpass`), (p + extra + n, q + extra + n).
    Beyond it (M (p + extra), M (q + extra) + n) with M = :func:`_stretch` and n the order of the
    anti-imaging FIR lowpass (:func:`flowtex.dsp.anti_imaging.fir_lowpass`); the same for every model of a set,
    so LSFs stay interpolable. ``keep_order`` forces (p, q). ``extra`` (even): see :func:`_extra_roots`.
    """
    if keep_order:
        return p, q
    p, q = p + extra, q + extra
    m = _stretch(rate_from, rate_to)
    if m == 1:
        if not lowpass or rate_to <= rate_from:
            return p, q
        poles, zeros = elliptic_lowpass(rate_from, rate_to, BAND_EDGE)
        return p + poles.shape[0], q + zeros.shape[0]
    poles, zeros = fir_lowpass(rate_from, rate_to, m, BAND_EDGE)
    return m * p + poles.shape[0], m * q + zeros.shape[0]


def _extra_roots(a0: np.ndarray, c0: np.ndarray, extra: int, band_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """Start polynomials with ``extra`` (even) more poles and zeros, for models too small to fall off above the old Nyquist.

    A low-order model whose spectrum is still high at the old Nyquist (an AR(1)
    or AR(2), say) has no roots to spend on the new stopband: upsampled at its own
    order it misses its band by 2-3 dB or leaves > 2 % of its power above the old
    Nyquist. The added zeros start as pairs at radius 0.9 spread over the
    stopband (angles between ``band_edge`` (rad/sample, the old Nyquist) and pi),
    the added poles as pairs at radius 0.2 (nearly neutral); the fit moves them.
    """
    if extra % 2 or extra < 0:
        raise ValueError(f"extra order must be even and >= 0, got {extra}")
    pairs = extra // 2
    if band_edge >= math.pi:  # downsampling: no stopband; neutral pairs (radius 0.2) the fit moves where the band needs them
        for _ in range(pairs):
            c0 = np.convolve(c0, [1.0, 0.0, 0.04])
            a0 = np.convolve(a0, [1.0, 0.0, 0.04])
        return a0, c0
    for k in range(pairs):
        ang = band_edge + (math.pi - band_edge) * (k + 1) / (pairs + 1)
        c0 = np.convolve(c0, [1.0, -1.8 * math.cos(ang), 0.81])
        a0 = np.convolve(a0, [1.0, 0.0, 0.04])
    return a0, c0


def _stretch(rate_from: float, rate_to: float) -> int:
    """Integer M by which an upsampled model is stretched (z -> z^M): 1 up to DIRECT_MAX_RATIO, then ceil(ratio / it)."""
    ratio = rate_to / rate_from
    return 1 if ratio <= DIRECT_MAX_RATIO * (1.0 + 1e-12) else math.ceil(ratio / DIRECT_MAX_RATIO - 1e-12)


def _fit_band(ar: np.ndarray, ma: np.ndarray, rate_from: float, rate: float, pre: tuple[np.ndarray, np.ndarray] | None,
              rate_pre: float, extra: int = 0, restarts: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(poles, zeros) at ``rate`` Hz, same orders, whose spectrum times |pre|^2 is the original's below its Nyquist.

    ``pre``: (poles, zeros) of a filter at ``rate_pre`` Hz (the anti-imaging lowpass) or None. When it runs at
    the fitted rate itself (``rate_pre == rate``: the elliptic edge) the stopband ceiling applies to the cascade
    and the level is set so that the fitted roots need not fall above the old Nyquist themselves: the lowpass does.

    Residuals (flowtex.dsp.arma_logfit): 10 log10(model / original) on
    BAND_POINTS frequencies up to BAND_EDGE x the old Nyquist where the original
    is within 40 + RANGE_MARGIN_DB dB of its peak below 0.9 x the old Nyquist (lsd_db's band); one-sided ceilings elsewhere:
    the peak - 40 dB in the band's valleys, the band's peak from BAND_EDGE to the
    old Nyquist, and STOPBAND_CEILING x the band's mean power / (ratio - 1)
    above it (then the power above the old Nyquist is <= ~STOPBAND_CEILING of the band's).
    Start: the original's roots mapped by z -> z^(rate_from / rate), and up to ``restarts`` other starts while the fit
    stays off its band (:func:`flowtex.dsp.arma_logfit.fit_log_spectrum_restarted`). Downsampling (``rate`` < ``rate_from``):
    the band ends at the new Nyquist, there is no stopband and the level is free (the new band is only part of
    the old circle, so Jensen fixes nothing).
    """
    f_lim = 0.5 * min(rate_from, rate)
    a0, c0 = _extra_roots(_map_roots(ar, rate_from / rate), _map_roots(ma, rate_from / rate), extra, math.pi * rate_from / rate)
    # poles at most twice as sharp as the sharpest mapped original pole ((1 - r) halved)
    r_max = float(np.max(np.abs(np.roots(ar)))) ** (rate_from / rate) if ar.shape[0] > 1 else 0.0
    pole_radius = min(MAX_RADIUS, 1.0 - 0.5 * (1.0 - r_max))
    f_in, w_in = _band_grid(ar, rate_from, BAND_EDGE * f_lim)
    t_db = 10.0 * np.log10(_model_power_spectrum(ar, ma, 2.0 * math.pi * f_in / rate_from))
    peak = float(np.max(t_db[f_in <= 0.9 * f_lim]))
    inside = t_db >= peak - LSD_RANGE_DB - RANGE_MARGIN_DB
    f_tr = np.linspace(BAND_EDGE * f_lim, f_lim, EDGE_POINTS)
    f_st = np.linspace(f_lim, 0.5 * rate, STOP_POINTS) if rate > rate_from else np.zeros(0)
    ratio = rate / rate_from
    mean_power = float(np.sum(w_in ** 2 * 10.0 ** (t_db / 10.0)) / np.sum(w_in ** 2))  # per Hz, as on a uniform grid
    ceiling = 10.0 * math.log10(STOPBAND_CEILING / max(ratio - 1.0, 1e-3) * mean_power)
    f = np.r_[f_in, f_tr, f_st]
    top = max(peak, float(np.max(t_db)))
    level = np.r_[np.where(inside, t_db, peak - LSD_RANGE_DB - RANGE_MARGIN_DB), np.full(f_tr.shape[0], top),
                  np.full(f_st.shape[0], ceiling)]
    # the monic model's level fixed (see STOP_DEPTH_DB): the same level convention, so the same v2 / v1, for every model
    offset = -STOP_DEPTH_DB * (ratio - 1.0) / ratio
    if pre is not None and rate_pre == rate:  # the elliptic edge: the cascade is what the ceilings bound
        pre_db = 10.0 * np.log10(_root_power_spectrum(pre[0], pre[1], 2.0 * math.pi * f / rate_pre))
        level -= pre_db
        # the roots' own level neutral (their log-mean the same in band and stopband): the edge does the falling
        offset = -float(np.mean(pre_db[:f_in.shape[0]]))
    elif pre is not None:  # compensate the lowpass in the band and at its edge; the stopband ceiling stays the model's own
        n_pre = f_in.shape[0] + f_tr.shape[0]
        pre_db = 10.0 * np.log10(_root_power_spectrum(pre[0], pre[1], 2.0 * math.pi * f[:n_pre] / rate_pre))
        level[:n_pre] -= pre_db
        # the monic root product's passband gain (22-30 dB) shifts the band; the ceiling must move with it, or it
        # sits that much higher relative to the band (measured before this line: low-order sets at 4x left 9-11 %
        # of their power above the old Nyquist)
        level[n_pre:] -= float(np.mean(pre_db[:f_in.shape[0]]))
        offset -= float(np.mean(pre_db[:f_in.shape[0]]))
    one_sided = np.r_[~inside, np.ones(f_tr.shape[0], dtype=bool), np.ones(f_st.shape[0], dtype=bool)]
    weight = np.r_[w_in, np.ones(f_tr.shape[0] + f_st.shape[0])]
    poles, zeros, _, _ = fit_log_spectrum_restarted(2.0 * math.pi * f / rate, level, weight, one_sided, a0, c0,
                                                    pole_radius, MAX_RADIUS, restarts=restarts,
                                                    offset_db=offset if rate > rate_from else None)
    return poles, zeros


def _band_grid(ar: np.ndarray, rate_from: float, f_edge: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies in (0, ``f_edge``] Hz, residual weights) of the upsampling fit's band.

    :data:`BAND_POINTS` uniform frequencies, plus, around every pole of ``ar`` (at ``rate_from`` Hz) whose
    resonance is narrower than 1.5 uniform steps, :data:`PEAK_POINTS` frequencies over +-:data:`PEAK_WIDTHS`
    half-bandwidths of a pole twice as sharp (the sharpest the fit may make it). Each weight is
    sqrt(local spacing / uniform spacing), so the sum of squared residuals is the uniform grid's (the LSD's
    average over frequency) while a 0.16 Hz wide resonance is still resolved. Before: a uniform grid fine
    enough for the sharpest pole, up to 20000 frequencies for poles at r >= 0.9995 (7x the cost per model).
    """
    du = f_edge / BAND_POINTS
    parts = [np.linspace(0.0, f_edge, BAND_POINTS + 1)[1:]]
    if ar.shape[0] > 1:
        roots = np.roots(ar)
        half_bw = 0.5 * np.maximum(1.0 - np.abs(roots), 1e-9) * rate_from / (2.0 * math.pi)  # Hz
        centre = np.abs(np.angle(roots)) * rate_from / (2.0 * math.pi)
        for f0, bw in zip(centre, half_bw, strict=True):
            if bw < 1.5 * du and f0 <= f_edge + PEAK_WIDTHS * bw:
                parts.append(f0 + bw * np.linspace(-PEAK_WIDTHS, PEAK_WIDTHS, PEAK_POINTS))
    f = np.unique(np.concatenate(parts))
    f = f[(f > 0.0) & (f <= f_edge)]
    spacing = np.gradient(f) if f.shape[0] > 1 else np.array([du])
    return f, np.sqrt(np.minimum(spacing / du, 1.0))


def _stretched_roots(roots: np.ndarray, m: int) -> np.ndarray:
    """Roots of P(z^m) from those of P(z): the m m-th roots of each."""
    k = np.arange(m)
    return (np.abs(roots)[:, None] ** (1.0 / m) * np.exp(1j * (np.angle(roots)[:, None] + 2.0 * math.pi * k[None, :]) / m)).ravel()


def _upsample(ar: np.ndarray, ma: np.ndarray, rate_from: float, rate_to: float, keep_order: bool,
              extra: int = 0, lowpass: bool = False, restarts: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(poles, zeros) at ``rate_to`` > ``rate_from``: a band fit at rate_to / M, stretched by z -> z^M and cascaded with the anti-imaging lowpass.

    Up to DIRECT_MAX_RATIO (M = 1) the band is fitted at ``rate_to`` itself, cascaded with the elliptic edge if ``lowpass``.
    """
    m = 1 if keep_order else _stretch(rate_from, rate_to)
    if m == 1 and lowpass and not keep_order:
        lp_poles, lp_zeros = elliptic_lowpass(rate_from, rate_to, BAND_EDGE)
        poles, zeros = _fit_band(ar, ma, rate_from, rate_to, (lp_poles, lp_zeros), rate_to, extra, restarts)
        return np.r_[poles, lp_poles], np.r_[zeros, lp_zeros]
    if m == 1:
        return _fit_band(ar, ma, rate_from, rate_to, None, rate_to, 0 if keep_order else extra, restarts)
    lp_poles, lp_zeros = fir_lowpass(rate_from, rate_to, m, BAND_EDGE)
    poles, zeros = _fit_band(ar, ma, rate_from, rate_to / m, (lp_poles, lp_zeros), rate_to, extra, restarts)
    return np.r_[_stretched_roots(poles, m), lp_poles], np.r_[_stretched_roots(zeros, m), lp_zeros]


def _check_rates(rate_from: float, rate_to: float) -> None:
    if not (rate_from > 0.0 and rate_to > 0.0 and math.isfinite(rate_from) and math.isfinite(rate_to)):
        raise ValueError(f"sample rates must be positive and finite, got {rate_from} and {rate_to}")


def _band_variance(spectrum_new: np.ndarray, ar: np.ndarray, ma: np.ndarray, variance: float, rate_from: float, rate_to: float,
                   w: np.ndarray) -> float:
    """Variance making the new model's power below 0.9 x the lower Nyquist the original's (both on the new grid ``w``)."""
    f = w * rate_to / (2.0 * math.pi)
    old_power = np.sum(_model_power_spectrum(ar, ma, 2.0 * math.pi * f / rate_from)) / rate_from
    return float(variance) * old_power / (np.sum(spectrum_new) / rate_to)


def resample_arma_lsf(ar: np.ndarray, ma: np.ndarray, gain: float, variance: float, rate_from: float, rate_to: float,
                      keep_order: bool = False, grid: int = GRID, iterations: int = 40, extra: int = 0, lowpass: bool = False,
                      restarts: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None, float, float]:
    """:func:`resample_arma` plus the new model's LSFs: (ar, ma, ar_lsf, ma_lsf, gain, variance).

    When upsampling the LSFs come from the fitted roots (:func:`flowtex.dsp.lsf_roots.roots_to_lsf`), exactly; they
    are None when downsampling (or if they do not come out valid): take them from the polynomials then.
    """
    ar = np.asarray(ar, dtype=np.float64)
    ma = np.asarray(ma, dtype=np.float64)
    _check_rates(rate_from, rate_to)
    if rate_to <= rate_from:
        a1, c1, g, v = resample_arma(ar, ma, gain, variance, rate_from, rate_to, grid=grid, iterations=iterations, extra=extra,
                                     restarts=restarts)
        return a1, c1, None, None, g, v
    poles, zeros = _upsample(ar, ma, rate_from, rate_to, keep_order, extra, lowpass, restarts)
    lsf_a = lsf_c = None
    try:
        lsf_a, lsf_c = roots_to_lsf(poles), roots_to_lsf(zeros)
    except ValueError:
        lsf_a = lsf_c = None
    if lsf_a is not None and not (is_valid_lsf(lsf_a) and is_valid_lsf(lsf_c)):
        lsf_a = lsf_c = None
    a1, c1 = real_poly(poles), real_poly(zeros)
    # the band power is matched on the model as it will be rendered: rebuilt from its LSFs by lsf_to_poly (for the
    # worst-conditioned models the float64 coefficients are where the remaining error lies, ~1 % of band power)
    a_r, c_r = (lsf_to_poly_new(lsf_a), lsf_to_poly_new(lsf_c)) if lsf_a is not None else (a1, c1)
    w = 2.0 * math.pi * np.arange(grid // 2 + 1) / grid
    w = w[w * rate_to / (2.0 * math.pi) < 0.45 * rate_from]
    new_variance = _band_variance(_model_power_spectrum(a_r, c_r, w), ar, ma, variance, rate_from, rate_to, w)
    return a1, c1, lsf_a, lsf_c, float(gain), new_variance


def resample_arma(ar: np.ndarray, ma: np.ndarray, gain: float, variance: float, rate_from: float, rate_to: float,
                  keep_order: bool = False, grid: int = GRID, iterations: int = 40, extra: int = 0, restarts: int = 0
                  ) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(ar, ma, gain, variance) at ``rate_to`` Hz with the same physical PSD below min(rate_from, rate_to) / 2.

    Downsampling keeps the orders (plus ``extra``, even: for sets too small to hold their band at the new
    rate, e.g. an AR(2)); upsampling returns the orders of
    :func:`upsampled_order` (``keep_order``: the original's, at a cost in
    accuracy beyond DIRECT_MAX_RATIO; ``extra``, even: that many more poles
    and zeros, for models too small to fall off above the old Nyquist; ``restarts``: that many more starts of a
    log-spectral fit that stays off its band, see :func:`_fit_band`). The gain is kept and the variance
    carries the power (a silent model, variance 0, stays silent with its
    shape resampled). Rates in Hz. See the module docstring for the method and why.
    """
    ar = np.asarray(ar, dtype=np.float64)
    ma = np.asarray(ma, dtype=np.float64)
    _check_rates(rate_from, rate_to)
    if rate_from == rate_to:
        return ar.copy(), ma.copy(), float(gain), float(variance)
    if rate_to > rate_from:
        a1, c1, _, _, g, v = resample_arma_lsf(ar, ma, gain, variance, rate_from, rate_to, keep_order, grid, iterations, extra,
                                               restarts=restarts)
        return a1, c1, g, v
    # downsampling: prediction-error fit of the band's PSD on the new grid, same order plus ``extra``
    ratio = rate_from / rate_to
    w = 2.0 * math.pi * np.arange(grid // 2 + 1) / grid  # new rate's grid, rad/sample
    f = w * rate_to / (2.0 * math.pi)
    f_lim = 0.5 * rate_to
    shape = _model_power_spectrum(ar, ma, 2.0 * math.pi * np.minimum(f, f_lim) / rate_from)
    T = np.where(f < f_lim, shape, STOPBAND_FLOOR * np.mean(shape[f < f_lim]))
    a0, c0 = _extra_roots(_map_roots(ar, ratio), _map_roots(ma, ratio), extra, math.pi)
    a1, c1, _ = whittle_refine(T, grid, a0, c0, iterations=iterations, tol=1e-10)
    band = f < 0.9 * f_lim
    wb = w[band]
    if _band_lsd(a1, c1, shape[band], wb) > DOWN_REFIT_DB:  # Whittle's criterion let the band go: fit its log spectrum
        poles, zeros = _fit_band(ar, ma, rate_from, rate_to, None, rate_to, extra, restarts)
        a2, c2 = real_poly(poles), real_poly(zeros)
        if _band_lsd(a2, c2, shape[band], wb) < _band_lsd(a1, c1, shape[band], wb):
            a1, c1 = a2, c2
    return a1, c1, float(gain), _band_variance(_model_power_spectrum(a1, c1, wb), ar, ma, variance, rate_from, rate_to, wb)


def _band_lsd(a: np.ndarray, c: np.ndarray, target: np.ndarray, w: np.ndarray) -> float:
    """LSD (dB) of the monic model (a, c) at ``w`` (rad/sample) against ``target``, its level fitted out.

    The level does not count: the variance sets it afterwards. Frequencies within LSD_RANGE_DB of the target's peak.
    """
    d = 10.0 * np.log10(_model_power_spectrum(a, c, w) / target)
    t_db = 10.0 * np.log10(target)
    d = d[t_db >= np.max(t_db) - LSD_RANGE_DB]
    return float(np.sqrt(np.mean((d - np.mean(d)) ** 2)))
