"""Change a texture model set's sample rate: every model resampled on its own (flowtex.dsp.arma_resample).

A lookup exactly at a model's (speed, force) then gives the resampled model;
the triangulation, operating points, maxima and mu are kept.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Callable

import numpy as np

from ..dsp.arma import arma_psd
from ..dsp.arma_resample import resample_arma_lsf, upsampled_order
from ..dsp.lsf import lsf_to_poly_new, poly_to_lsf
from ..dsp.spectral import lsd_db
from ..errors import FlowtexError
from ..models.texture import TextureModelSet
from .arma import min_phase_for_lsf


def resample_quality(ar1, ma1, g1, v1, rate1, ar2, ma2, g2, v2, rate2) -> tuple[float, float]:
    """(LSD dB, relative band-power error) of model 2 against model 1 up to 0.9 x the lower Nyquist (physical PSDs)."""
    f = np.linspace(0.0, 0.45 * min(rate1, rate2), 4001)
    s1 = arma_psd(ar1, ma1, g1, v1, f, rate1)
    s2 = arma_psd(ar2, ma2, g2, v2, f, rate2)
    band = float(np.trapezoid(s2, f) / np.trapezoid(s1, f) - 1.0)
    return lsd_db(s2, s1, f, min_freq_hz=0.0), band


def power_above(ar: np.ndarray, ma: np.ndarray, rate: float, f_hz: float) -> float:
    """Fraction of a model's power above ``f_hz`` (Hz) at ``rate`` Hz (dense trapezoid of its PSD; gain and variance cancel)."""
    f = np.linspace(0.0, 0.5 * rate, 40001)
    s = arma_psd(ar, ma, 1.0, 1.0, f, rate)
    return float(np.trapezoid(s[f >= f_hz], f[f >= f_hz]) / np.trapezoid(s, f))


MAX_LSD_DB = 0.5
"""A resampled model keeps its spectrum when its LSD (up to 0.9 x the lower Nyquist) is at most this (issue 11)."""

MAX_POWER_ABOVE = 0.02
"""An upsampled model may put at most this fraction of its power above the old Nyquist (issue 11)."""

MAX_RATE_RATIO = 16.0
"""Largest change of a model set's rate (up or down): upsampling by M multiplies every model's order by about M / 2."""

MAX_EXTRA_ORDER = 20
"""Largest ``extra_order``: more poles and zeros than this only slow the fit down."""

EXTRA_ORDERS = (0, 2, 4, 6)
"""Order increases tried, in turn, when upsampling leaves some model off (the first that keeps every model wins)."""


@dataclasses.dataclass
class _Resampled:
    ar_lsf: np.ndarray
    ma_lsf: np.ndarray
    ar_coeff: np.ndarray
    ma_coeff: np.ndarray
    variance: np.ndarray
    gain: np.ndarray
    worst_lsd: float
    worst_band: float
    worst_above: float

    def violation(self) -> float:
        """Worst LSD and power above the old Nyquist relative to their limits (<= 1: every model keeps its spectrum)."""
        return max(self.worst_lsd / MAX_LSD_DB, self.worst_above / MAX_POWER_ABOVE)


def _resample_models(ms: TextureModelSet, rate_to: float, keep_order: bool, extra: int,
                     progress: Callable[[int, int], None] | None) -> _Resampled:
    """Every model of ``ms`` at ``rate_to`` Hz, ``extra`` more poles and zeros; quality measured as rendered (from the LSFs)."""
    rate_from = float(ms.sample_rate)
    m_count = ms.num_models
    p, q = upsampled_order(ms.ar_order, ms.ma_order, rate_from, rate_to, keep_order, extra) if rate_to > rate_from \
        else (ms.ar_order, ms.ma_order)
    out = _Resampled(np.empty((m_count, p)), np.empty((m_count, q)), np.empty((m_count, p + 1)), np.empty((m_count, q + 1)),
                     np.empty(m_count), np.empty(m_count), 0.0, 0.0, 0.0)
    for m in range(m_count):
        a = lsf_to_poly_new(ms.ar_lsf[m])
        c = lsf_to_poly_new(ms.ma_lsf[m])
        v1 = float(ms.variance[m])
        # a silent model (variance 0) is resampled at unit variance and stays silent: its shape still matters once
        # texture_lookup interpolates it with its neighbours
        v_fit = v1 if v1 > 0.0 else 1.0
        a2, c2, lsf_a, lsf_c, g2, v2 = resample_arma_lsf(a, c, float(ms.gain[m]), v_fit, rate_from, rate_to,
                                                         keep_order=keep_order, extra=extra)
        if lsf_a is None:  # downsampling: LSFs from the (well-conditioned) polynomials
            a2 = min_phase_for_lsf(a2)
            c2 = min_phase_for_lsf(c2)
            lsf_a = poly_to_lsf(a2) if p else out.ar_lsf[m]
            lsf_c = poly_to_lsf(c2) if q else out.ma_lsf[m]
        out.ar_lsf[m] = lsf_a
        out.ma_lsf[m] = lsf_c
        out.ar_coeff[m] = a2
        out.ma_coeff[m] = c2
        out.gain[m] = g2
        out.variance[m] = v2 if v1 > 0.0 else 0.0
        # quality of the model as texture_lookup renders it: rebuilt from the stored LSFs
        a_r, c_r = lsf_to_poly_new(out.ar_lsf[m]), lsf_to_poly_new(out.ma_lsf[m])
        lsd, band = resample_quality(a, c, float(ms.gain[m]), v_fit, rate_from, a_r, c_r, g2, v2, rate_to)
        out.worst_lsd = max(out.worst_lsd, lsd)
        out.worst_band = max(out.worst_band, abs(band))
        if rate_to > rate_from:
            out.worst_above = max(out.worst_above, power_above(a_r, c_r, rate_to, 0.5 * rate_from))
        if progress is not None:
            progress(m + 1, m_count)
    return out


def resample_model_set(ms: TextureModelSet, rate_hz: float, progress: Callable[[int, int], None] | None = None,
                       keep_order: bool = False, extra_order: int | None = None, option: str = "--rate") -> TextureModelSet:
    """A copy of ``ms`` whose models run at ``rate_hz`` (Hz) with the same physical PSDs below min Nyquist.

    Upsampling by more than 2x raises every model's order alike
    (:func:`flowtex.dsp.arma_resample.upsampled_order`) unless ``keep_order``.
    When upsampling, ``extra_order`` (even) adds that many poles and zeros to
    every model; None tries :data:`EXTRA_ORDERS` in turn and keeps the first
    with which every model keeps its spectrum (LSD <= 0.5 dB, <= 2 % of its
    power above the old Nyquist) — sets of HaTT's size need none, an AR(2) set
    needs 2 — or the one closest to those limits if none does.
    ``metadata["resample"]`` records the source rate, the orders, the method
    and the worst LSD (dB), band-power error and power above the old Nyquist
    of the models as rendered, i.e. rebuilt from the stored LSFs (see :func:`resample_quality`).
    ``progress(done, total)`` is called after each model (of each attempt). ``option`` names the rate in errors.
    The rate may change by at most :data:`MAX_RATE_RATIO` either way.
    """
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise FlowtexError(f"{option} must be a positive number of Hz, got {rate_hz!r}")
    if extra_order is not None and (extra_order < 0 or extra_order % 2 or extra_order > MAX_EXTRA_ORDER):
        raise FlowtexError(f"--extra-order must be an even number from 0 to {MAX_EXTRA_ORDER}, got {extra_order}")
    rate_from = float(ms.sample_rate)
    if not rate_from / MAX_RATE_RATIO <= rate_hz <= rate_from * MAX_RATE_RATIO:
        raise FlowtexError(f"{option} {rate_hz:g}: valid range for this {rate_from:g} Hz model set is {rate_from / MAX_RATE_RATIO:g} "
                           f"to {rate_from * MAX_RATE_RATIO:g} Hz (at most {MAX_RATE_RATIO:g}x up or down)")
    rate_to = float(rate_hz)
    upsampling = rate_to > rate_from
    tries = (0,) if not upsampling or keep_order else EXTRA_ORDERS if extra_order is None else (extra_order,)
    best: _Resampled | None = None
    best_extra = 0
    for extra in tries:
        res = _resample_models(ms, rate_to, keep_order, extra, progress)
        if best is None or res.violation() < best.violation():
            best, best_extra = res, extra
        if res.violation() <= 1.0:
            best, best_extra = res, extra
            break
    assert best is not None
    p0, q0 = ms.ar_order, ms.ma_order
    p, q = best.ar_lsf.shape[1], best.ma_lsf.shape[1]
    metadata = dict(ms.metadata)
    if not upsampling:
        method = "prediction-error fit of the PSD below the new Nyquist, same order"
    else:
        method = "log-spectral fit of the PSD below the old Nyquist, stopband ceiling above"
        if best_extra:
            method += f"; {best_extra} more poles and zeros"
        if (p, q) != (p0 + best_extra, q0 + best_extra) and not keep_order:
            method += "; fitted at 1/M of the rate, stretched z -> z^M and cascaded with an FIR anti-imaging lowpass"
    metadata["resample"] = {"from_hz": rate_from, "to_hz": rate_to, "method": method,
                            "from_order": [p0, q0], "to_order": [p, q], "extra_order": best_extra,
                            "worst_lsd_db": best.worst_lsd, "worst_band_power_error": best.worst_band,
                            "worst_power_above_old_nyquist": best.worst_above}
    out = dataclasses.replace(ms, sample_rate=rate_to, ar_lsf=best.ar_lsf, ma_lsf=best.ma_lsf, variance=best.variance,
                              gain=best.gain, ar_coeff=best.ar_coeff, ma_coeff=best.ma_coeff, source=None, metadata=metadata,
                              speeds=np.array(ms.speeds, dtype=np.float64), forces=np.array(ms.forces, dtype=np.float64),
                              triangles=np.array(ms.triangles, dtype=np.int64))
    return out.validate()


def resample_summary(source: str, ms: TextureModelSet, out: TextureModelSet, target: str, keep_order: bool) -> tuple[str, str | None]:
    """(one-line summary, warning or None) of ``out`` = ``ms`` resampled, as ``flowtex models resample`` prints them."""
    info = out.metadata["resample"]
    (p0, q0), (p, q) = info["from_order"], info["to_order"]
    orders = f"orders {p0}/{q0}" + (f" -> {p}/{q}" if (p, q) != (p0, q0) else "")
    if info["extra_order"]:
        orders += f" ({info['extra_order']} more poles and zeros)"
    line = (f"{source}: {ms.num_models} models {info['from_hz']:g} Hz -> {info['to_hz']:g} Hz, {orders}, written to {target}; "
            f"worst LSD {info['worst_lsd_db']:.2f} dB, worst band-power error {100 * info['worst_band_power_error']:.2f} % "
            f"(up to 0.9 x the lower Nyquist)"
            + (f", worst power above the old Nyquist {100 * info['worst_power_above_old_nyquist']:.2f} %"
               if info["to_hz"] > info["from_hz"] else ""))
    warning = None
    if info["worst_lsd_db"] > MAX_LSD_DB or info.get("worst_power_above_old_nyquist", 0.0) > MAX_POWER_ABOVE:
        warning = ("warning: some models do not keep their spectrum (LSD <= 0.5 dB, <= 2 % of the power above the old Nyquist)"
                   + (" (--keep-order: upsampling by more than 2x needs the higher order; see docs/fitting.md)" if keep_order else
                      " (see docs/fitting.md)"))
    return line, warning


def tqdm_progress(total: int, desc: str) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """(progress callback, close) showing a tqdm bar on a terminal; (None, no-op) otherwise."""
    if not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit="model", leave=False)

    def update(done: int, _total: int) -> None:
        bar.n = done
        bar.refresh()

    return update, bar.close
