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
from scipy.integrate import trapezoid

from ..dsp.arma import arma_psd
from ..dsp.arma_logfit import RESTARTS
from ..dsp.arma_resample import DIRECT_MAX_RATIO, resample_arma_lsf
from ..dsp.lsf import lsf_to_poly_new
from ..dsp.lsf_roots import poly_to_lsf
from ..dsp.spectral import lsd_db
from ..errors import FlowtexError, InputError
from ..limits import excerpt, signed
from ..models.texture import TextureModelSet
from ..pyvalues import positive_rate
from .arma import min_phase_for_lsf


def _resonances_hz(ar: np.ndarray, rate: float, f_max: float) -> np.ndarray:
    """Frequencies (Hz) of the poles of ``ar`` at ``rate`` Hz up to ``f_max``: where a narrow peak has its top."""
    if ar.shape[0] <= 1:
        return np.zeros(0)
    f = np.abs(np.angle(np.roots(ar))) * rate / (2.0 * math.pi)
    return f[f <= f_max]


def resample_quality(ar1, ma1, g1, v1, rate1, ar2, ma2, g2, v2, rate2) -> tuple[float, float]:
    """(LSD dB, relative band-power error) of model 2 against model 1 up to 0.9 x the lower Nyquist (physical PSDs).

    The LSD (:func:`flowtex.dsp.spectral.lsd_db`, frequencies within 40 dB of model 1's peak) is taken on 4001
    uniform frequencies plus the poles' resonance frequencies of both models: a resonance narrower than the
    grid's step (a pole at r = 0.9995 at 1 kHz is 0.16 Hz wide) would otherwise have its top missed, the
    "peak" would be tens of dB low and the band would take in frequencies far below the true 40 dB range
    (measured: 5-36 dB "misses" of models that match to 0.1 dB within 40 dB of their true peak).
    """
    f_max = 0.45 * min(rate1, rate2)
    f = np.unique(np.r_[np.linspace(0.0, f_max, 4001), _resonances_hz(np.asarray(ar1), rate1, f_max),
                        _resonances_hz(np.asarray(ar2), rate2, f_max)])
    s1 = arma_psd(ar1, ma1, g1, v1, f, rate1)
    s2 = arma_psd(ar2, ma2, g2, v2, f, rate2)
    band = float(trapezoid(s2, f) / trapezoid(s1, f) - 1.0)
    return lsd_db(s2, s1, f, min_freq_hz=0.0), band


def power_above(ar: np.ndarray, ma: np.ndarray, rate: float, f_hz: float) -> float:
    """Fraction of a model's power above ``f_hz`` (Hz) at ``rate`` Hz (dense trapezoid of its PSD; gain and variance cancel)."""
    f = np.linspace(0.0, 0.5 * rate, 40001)
    s = arma_psd(ar, ma, 1.0, 1.0, f, rate)
    return float(trapezoid(s[f >= f_hz], f[f >= f_hz]) / trapezoid(s, f))


MAX_LSD_DB = 0.5
"""A resampled model keeps its spectrum when its LSD (up to 0.9 x the lower Nyquist) is at most this."""

MAX_BAND_ERROR = 0.02
"""... and its power up to 0.9 x the lower Nyquist is within this fraction of the original's."""

MAX_POWER_ABOVE = 0.02
"""An upsampled model may put at most this fraction of its power above the old Nyquist."""

MAX_RATE_RATIO = 16.0
"""Largest change of a model set's rate (up or down): upsampling by M multiplies every model's order by about M / 2."""

MAX_EXTRA_ORDER = 20
"""Largest ``extra_order``: more poles and zeros than this only slow the fit down."""

EXTRA_ORDERS = (0, 2, 4, 6, 8)
"""Order increases tried, in turn, when upsampling by more than 2x leaves some model off (the first that keeps every
model wins)."""

EDGE_ATTEMPTS = ((0, False), (0, True), (2, False), (2, True), (4, False), (4, True), (6, False), (8, False))
"""(extra order, elliptic edge) tried, in turn, when upsampling by up to 2x: the models' own order first, then
cascaded with the elliptic lowpass at the old Nyquist (flowtex.dsp.anti_imaging.elliptic_lowpass), which the
models whose spectrum is still high there need (HaTT's rough surfaces), then more poles and zeros without and
with it: low-order sets (an ARMA(4,2) set: 2 more) fit worse with the edge than with free roots."""

DOWN_ATTEMPTS = ((0, False), (2, False), (4, False))
"""(extra order, edge) tried, in turn, when downsampling: the own order holds HaTT's sets; an AR(2) set's band at
500 Hz needs 2 more poles and zeros (1.3 dB off at its own order)."""

Attempt = tuple[int, bool, int]
"""(extra order, elliptic edge, restarts) of one attempt at a whole set: ``restarts`` more starts of a model's fit while
it stays off its band (flowtex.dsp.arma_logfit.fit_log_spectrum_restarted)."""


def with_restarts(tries: tuple[tuple[int, bool], ...]) -> tuple[Attempt, ...]:
    """``tries`` with one start per fit, then the same again with :data:`RESTARTS` more starts where a fit stays off.

    Levenberg-Marquardt ends in the minimum nearest its start, and the mapped start of some models lies near a poor one:
    fitted sets whose models have real roots at the old Nyquist missed at every order and edge from that start alone.
    A set that keeps its spectrum from single starts is fitted exactly as before (same models, same time)."""
    return tuple((e, edge, 0) for e, edge in tries) + tuple((e, edge, RESTARTS) for e, edge in tries)


@dataclasses.dataclass
class _Model:
    """One model resampled: its LSFs, coefficients, gain and variance, and its quality as rendered."""

    ar_lsf: np.ndarray
    ma_lsf: np.ndarray
    ar_coeff: np.ndarray
    ma_coeff: np.ndarray
    gain: float
    variance: float
    lsd: float
    band: float
    above: float

    def violation(self) -> float:
        """Worst of LSD, band-power error and power above the old Nyquist relative to their limits (<= 1: kept)."""
        return max(self.lsd / MAX_LSD_DB, abs(self.band) / MAX_BAND_ERROR, self.above / MAX_POWER_ABOVE)


def _resample_one(ms: TextureModelSet, m: int, rate_to: float, keep_order: bool, extra: int, lowpass: bool = False,
                  restarts: int = 0) -> _Model:
    """Model ``m`` of ``ms`` at ``rate_to`` Hz with ``extra`` more poles and zeros; quality measured as rendered (from the LSFs)."""
    rate_from = float(ms.sample_rate)
    a = lsf_to_poly_new(ms.ar_lsf[m])
    c = lsf_to_poly_new(ms.ma_lsf[m])
    v1 = float(ms.variance[m])
    # fitted at unit gain and variance (the shape; the resampled variance is linear in the original's and the gain
    # is kept, so both scale out): a model's level never enters the arithmetic, whatever its size. A silent model
    # (variance 0) stays silent: its shape still matters once texture_lookup interpolates it with its neighbours.
    a2, c2, lsf_a, lsf_c, _, v_unit = resample_arma_lsf(a, c, 1.0, 1.0, rate_from, rate_to, keep_order=keep_order,
                                                        extra=extra, lowpass=lowpass, restarts=restarts)
    if lsf_a is None:  # downsampling: LSFs from the (well-conditioned) polynomials
        a2 = min_phase_for_lsf(a2)
        c2 = min_phase_for_lsf(c2)
        lsf_a = poly_to_lsf(a2) if a2.shape[0] > 1 else np.zeros(0)
        lsf_c = poly_to_lsf(c2) if c2.shape[0] > 1 else np.zeros(0)
    # quality of the model as texture_lookup renders it: rebuilt from the stored LSFs
    a_r, c_r = lsf_to_poly_new(lsf_a), lsf_to_poly_new(lsf_c)
    lsd, band = resample_quality(a, c, 1.0, 1.0, rate_from, a_r, c_r, 1.0, v_unit, rate_to)
    above = power_above(a_r, c_r, rate_to, 0.5 * rate_from) if rate_to > rate_from else 0.0
    return _Model(lsf_a, lsf_c, a2, c2, float(ms.gain[m]), v1 * v_unit, lsd, band, above)


class _Progress:
    """Counts model fits for the caller's ``progress(done, total)``; the total grows when an attempt is retried."""

    def __init__(self, callback: Callable[[int, int], None] | None, total: int):
        self.callback, self.done, self.total = callback, 0, total

    def step(self) -> None:
        self.done += 1
        self.total = max(self.total, self.done)
        if self.callback is not None:
            self.callback(self.done, self.total)


FitCache = dict
"""Resampled models kept across calls of :func:`resample_model_set` on sets that share models (adaptive densifying,
flowtex.fit.resample_densify): keyed by the attempt, the target rate and order rule and the model's own numbers."""


def _model_key(ms: TextureModelSet, m: int) -> bytes:
    """What model ``m``'s resampled fit depends on: the set's rate and the model's LSFs, variance and gain."""
    return np.r_[ms.sample_rate, ms.variance[m], ms.gain[m], ms.ar_lsf[m], ms.ma_lsf[m]].tobytes()


def _resample_models(ms: TextureModelSet, rate_to: float, keep_order: bool, tries: tuple[Attempt, ...],
                     progress: _Progress, cache: FitCache | None = None) -> tuple[Attempt, list[_Model]]:
    """(attempt, every model) for the first of ``tries`` with which every model keeps its spectrum (else the last).

    Stopping rule (bounded: at most len(tries) x models fits, each itself bounded, see
    :func:`flowtex.dsp.arma_logfit.fit_log_spectrum`): the models are fitted in turn, those that missed at a
    earlier attempt first. An attempt stops at its first miss unless it is the last; the model that missed is
    then tried alone at the next attempts until it keeps its spectrum, and the set is attempted there.
    Results are cached per (attempt, model) in ``cache`` (a fresh one if None): nothing is fitted twice.
    """
    m_count = ms.num_models
    cache = {} if cache is None else cache

    def get(attempt: Attempt, m: int) -> _Model:
        key = (attempt, rate_to, keep_order, _model_key(ms, m))
        if key not in cache:
            cache[key] = _resample_one(ms, m, rate_to, keep_order, *attempt)
            progress.step()
        return cache[key]

    hard: list[int] = []
    i = 0
    while True:
        attempt = tries[i]
        last = i == len(tries) - 1
        order = hard + [m for m in range(m_count) if m not in hard]
        missed = next((m for m in order if get(attempt, m).violation() > 1.0 and not last), None)
        if missed is None:
            return attempt, [get(attempt, m) for m in range(m_count)]
        if missed not in hard:
            hard.insert(0, missed)
        progress.total += m_count  # another attempt
        i += 1
        while i < len(tries) - 1 and get(tries[i], missed).violation() > 1.0:
            i += 1


def check_rate_ratio(rate_from: float, rate_to: float, option: str = "--rate", what: str = "model set") -> None:
    """Raise FlowtexError unless ``rate_to`` (Hz) is within :data:`MAX_RATE_RATIO` of ``rate_from`` (Hz) either way."""
    if not (math.isfinite(rate_to) and rate_from / MAX_RATE_RATIO <= rate_to <= rate_from * MAX_RATE_RATIO):
        raise FlowtexError(f"{option} {rate_to:g}: valid range for this {rate_from:g} Hz {what} is {rate_from / MAX_RATE_RATIO:g} "
                           f"to {rate_from * MAX_RATE_RATIO:g} Hz (at most {MAX_RATE_RATIO:g}x up or down)")


def resample_model_set(ms: TextureModelSet, rate_hz: float, progress: Callable[[int, int], None] | None = None,
                       keep_order: bool = False, extra_order: int | None = None, option: str = "--rate",
                       cache: FitCache | None = None) -> TextureModelSet:
    """A copy of ``ms`` whose models run at ``rate_hz`` (Hz) with the same physical PSDs below min Nyquist.

    Upsampling by more than 2x raises every model's order alike
    (:func:`flowtex.dsp.arma_resample.upsampled_order`) unless ``keep_order``.
    ``extra_order`` (even, 0..:data:`MAX_EXTRA_ORDER`) adds exactly that many poles and zeros to
    every model (and no elliptic edge); None tries :data:`EDGE_ATTEMPTS` (up to 2x up), :data:`EXTRA_ORDERS`
    (beyond) or :data:`DOWN_ATTEMPTS` (down) in turn and keeps the first with which every model keeps its spectrum (LSD <= 0.5 dB, band power
    within 2 %, <= 2 % of its power above the old Nyquist) -- most of HaTT's sets need nothing added, those
    whose spectra are still high at the old Nyquist the edge -- or the last (see :func:`_resample_models` for
    the stopping rule: the call always ends).
    ``metadata["resample"]`` records the source rate, the orders, the method,
    the worst LSD (dB), band-power error and power above the old Nyquist
    of the models as rendered, i.e. rebuilt from the stored LSFs (see :func:`resample_quality`), and
    ``misses``: the models that still miss those limits (index, speed, force and figures; see :func:`misses_text`),
    ``quality``: every model's [LSD dB, band-power error, power above the old Nyquist], ``edge_lowpass`` and
    ``fit_restarts`` (the attempt's restarts, :func:`with_restarts`).
    ``progress(done, total)`` is called after each model fit (the total grows if an extra order is tried).
    ``option`` names the rate in errors. The rate may change by at most :data:`MAX_RATE_RATIO` either way.
    ``cache``: fits kept from an earlier call on a set sharing models (:data:`FitCache`), reused and extended.
    """
    if not isinstance(ms, TextureModelSet):
        raise InputError(f"resample_model_set takes a TextureModelSet (flowtex.io.modelset.load_model_set(path) loads "
                         f"one), got {type(ms).__name__} {excerpt(ms)}")
    rate_hz = positive_rate(option, rate_hz)  # numpy numbers too
    if extra_order is not None and not (0 <= extra_order <= MAX_EXTRA_ORDER and extra_order % 2 == 0):
        raise FlowtexError(f"--extra-order must be an even number from 0 to {MAX_EXTRA_ORDER}, got {extra_order}")
    rate_from = float(ms.sample_rate)
    check_rate_ratio(rate_from, rate_hz, option, "model set")
    ms.validate()  # a set built in memory too: a power beyond float64 is named, not an OverflowError
    rate_to = float(rate_hz)
    upsampling = rate_to > rate_from
    direct = rate_to <= DIRECT_MAX_RATIO * (1.0 + 1e-12) * rate_from
    if keep_order and upsampling:
        tries = with_restarts(((0, False),))
    elif extra_order is not None:
        tries = with_restarts(((extra_order, False),))
    else:
        tries = with_restarts(DOWN_ATTEMPTS if not upsampling else EDGE_ATTEMPTS if direct else tuple((e, False) for e in EXTRA_ORDERS))
    (best_extra, edge, restarts), models = _resample_models(ms, rate_to, keep_order, tries, _Progress(progress, ms.num_models),
                                                    cache)
    p0, q0 = ms.ar_order, ms.ma_order
    p, q = models[0].ar_lsf.shape[0], models[0].ma_lsf.shape[0]
    metadata = dict(ms.metadata)
    if not upsampling:
        method = "prediction-error fit of the PSD below the new Nyquist (log-spectral refit where it leaves the band)"
        method += f"; {best_extra} more poles and zeros" if best_extra else ", same order"
    else:
        method = "log-spectral fit of the PSD below the old Nyquist, stopband ceiling above"
        if best_extra:
            method += f"; {best_extra} more poles and zeros"
        if edge:
            method += f"; cascaded with an order-{p - p0 - best_extra} elliptic lowpass edge at the old Nyquist"
        elif (p, q) != (p0 + best_extra, q0 + best_extra) and not keep_order:
            method += "; fitted at 1/M of the rate, stretched z -> z^M and cascaded with an FIR anti-imaging lowpass"
    if restarts:
        method += f"; a fit that stayed off its band restarted from up to {restarts} other starts"
    misses = [{"model": m, "speed": float(ms.speeds[m]), "force": float(ms.forces[m]), "lsd_db": r.lsd,
               "band_power_error": r.band, "power_above_old_nyquist": r.above}
              for m, r in enumerate(models) if r.violation() > 1.0]
    metadata["resample"] = {"from_hz": rate_from, "to_hz": rate_to, "method": method,
                            "from_order": [p0, q0], "to_order": [p, q], "extra_order": best_extra,
                            "edge_lowpass": edge, "fit_restarts": restarts,
                            "worst_lsd_db": max(r.lsd for r in models),
                            "worst_band_power_error": max(abs(r.band) for r in models),
                            "worst_power_above_old_nyquist": max(r.above for r in models), "misses": misses,
                            "quality": [[r.lsd, r.band, r.above] for r in models]}
    out = dataclasses.replace(ms, sample_rate=rate_to, ar_lsf=np.array([r.ar_lsf for r in models]).reshape(len(models), p),
                              ma_lsf=np.array([r.ma_lsf for r in models]).reshape(len(models), q),
                              variance=np.array([r.variance for r in models]), gain=np.array([r.gain for r in models]),
                              ar_coeff=np.array([r.ar_coeff for r in models]), ma_coeff=np.array([r.ma_coeff for r in models]),
                              source=None, metadata=metadata, rule=ms.rule,  # the set's rendering rule carries over
                              speeds=np.array(ms.speeds, dtype=np.float64), forces=np.array(ms.forces, dtype=np.float64),
                              triangles=np.array(ms.triangles, dtype=np.int64))
    return out.validate()


def misses_text(ms: TextureModelSet, limit: int = 5) -> str:
    """One line naming the models of a resampled set that miss the limits, with their figures ('' if none)."""
    misses = ms.metadata.get("resample", {}).get("misses", [])
    if not misses:
        return ""
    worst = sorted(misses, key=lambda d: -max(d["lsd_db"] / MAX_LSD_DB, abs(d["band_power_error"]) / MAX_BAND_ERROR,
                                               d["power_above_old_nyquist"] / MAX_POWER_ABOVE))
    items = [f"model {d['model']} ({d['speed']:g} mm/s, {d['force']:g} N): LSD {d['lsd_db']:.2f} dB, band power "
             f"{signed(100 * d['band_power_error'], 1)} %, {100 * d['power_above_old_nyquist']:.1f} % above the old Nyquist"
             for d in worst[:limit]]
    more = f" and {len(misses) - limit} more" if len(misses) > limit else ""
    return (f"{len(misses)} of {ms.num_models} models miss LSD <= {MAX_LSD_DB} dB / band power within "
            f"{100 * MAX_BAND_ERROR:g} % / <= {100 * MAX_POWER_ABOVE:g} % above the old Nyquist: " + "; ".join(items) + more)


def check_misses(ms: TextureModelSet, allow_misses: bool, where: str) -> str:
    """'' if every model of a resampled set keeps its spectrum; else the warning (``allow_misses``) or FlowtexError naming them."""
    text = misses_text(ms)
    if not text:
        return ""
    if allow_misses:
        return f"warning: {where}: {text}"
    extra = ms.metadata["resample"]["extra_order"]
    hint = (f"try --extra-order {extra + 2}" if extra + 2 <= MAX_EXTRA_ORDER else "no larger --extra-order is allowed")
    raise FlowtexError(f"{where}: {text}; nothing written ({hint}, or --allow-misses to write the set anyway)")


def resample_summary(source: str, ms: TextureModelSet, out: TextureModelSet, target: str, keep_order: bool) -> tuple[str, str | None]:
    """(one-line summary, warning or None) of ``out`` = ``ms`` resampled, as ``flowtex models resample`` prints them."""
    info = out.metadata["resample"]
    (p0, q0), (p, q) = info["from_order"], info["to_order"]
    orders = f"orders {p0}/{q0}" + (f" -> {p}/{q}" if (p, q) != (p0, q0) else "")
    if info["extra_order"]:
        orders += f" ({info['extra_order']} more poles and zeros)"
    if info.get("edge_lowpass"):
        orders += " (elliptic lowpass edge at the old Nyquist)"
    line = (f"{source}: {ms.num_models} models {info['from_hz']:g} Hz -> {info['to_hz']:g} Hz, {orders}, written to {target}; "
            f"worst LSD {info['worst_lsd_db']:.2f} dB, worst band-power error {100 * info['worst_band_power_error']:.2f} % "
            f"(up to 0.9 x the lower Nyquist)"
            + (f", worst power above the old Nyquist {100 * info['worst_power_above_old_nyquist']:.2f} %"
               if info["to_hz"] > info["from_hz"] else ""))
    warning = check_misses(out, True, source) or None  # refused before writing unless --allow-misses (cmd_models_resample)
    if warning:
        warning += (" (--keep-order: upsampling by more than 2x needs the higher order; see docs/fitting.md)" if keep_order
                    else " (see docs/fitting.md)")
    return line, warning


def tqdm_progress(total: int, desc: str) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """(progress callback, close) showing a tqdm bar on a terminal; (None, no-op) otherwise."""
    if not sys.stderr.isatty():
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit="model", leave=False)

    def update(done: int, total_now: int) -> None:
        bar.total = total_now
        bar.n = done
        bar.refresh()

    return update, bar.close
