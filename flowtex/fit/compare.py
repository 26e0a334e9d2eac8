"""How faithful a surface is: render it along a recording's own speed and force, and compare with the recording.

:func:`compare_surface` (``flowtex compare``, ``fit texture --holdout``) renders
the model set with ``texture_lookup`` + ``arma_synth`` (flowtex.fit.texture_graph,
the nodes every graph renders with) along the recorded speed (mm/s) and normal
force (N), ``seeds`` times with different excitation seeds, and measures, on the
recording and on the renders alike:

* both signals go through the 10 Hz 4th-order zero-phase Butterworth high-pass
  of ``fit texture`` (``highpass_hz``) and the first ``skip_s`` (0.5 s) are
  dropped (the synthesis filter's start-up);
* ``power_ratio_db``: 10 log10 of the rendered power over the recorded power,
  both from ``min_freq_hz`` (12 Hz) up (integrated Welch PSDs); the rendered
  power is the mean over the seeds (one render scatters by about 0.5 dB);
* ``lsd_db``: the LSD of the renders' mean Welch PSD against the recording's
  (flowtex.dsp.spectral.lsd_db over ``band_hz``, where the recording is within
  40 dB of its peak); ``shape_lsd_db`` the same once the levels are matched
  (the standard deviation of the dB difference: LSD^2 = shape_lsd^2 + mean
  dB offset^2, so a render 3 dB too loud everywhere has LSD 3 and shape LSD 0);
  ``gfc``: Culbertson et al. 2012's GFC of the two
  amplitude spectra (square roots of the PSDs) from ``min_freq_hz`` up;
  ``centroid_hz`` / ``rendered_centroid_hz``: the spectral centroids;
* ``band_hz``: the band [``min_freq_hz``, top] of the LSD, GFC, centroids and
  octave bands (top: ``max_freq_hz`` or the Nyquist frequency), stated in the
  output;
* ``octave_bands``: the rendered over recorded power (``error_db``) in every
  octave band of ``band_hz`` (flowtex.dsp.spectral.octave_bands): where in
  the spectrum the power is missing;
* ``rms_correlation``: the Pearson correlation between the recorded and the
  rendered RMS of consecutive ``window_s`` (1 s) windows (the rendered RMS is
  the root of the seeds' mean power): does the render get louder where the
  recording does? With fewer than :data:`MIN_WINDOWS` windows (or a constant
  RMS) a correlation means nothing: NaN (null in the JSON), and a warning says
  why (``warnings``);
* the same figures per window (``windows``).

Welch PSDs use Hann segments of ``rate / resolution_hz`` samples (50 %
overlap), so the spectral resolution is the same at every sample rate (4 Hz:
250 samples at 1 kHz, 1000 at 4 kHz) and so is the LSD's scatter: with a
segment fixed in samples, the 1, 2 and 4 kHz versions of one surface scored
very different LSDs (docs/fitting.md).

``ranges`` (held-out one-second blocks, flowtex.fit.crossval) restricts every
figure to those sample ranges of a render along the whole path: the PSDs are
the segment-weighted mean of each range's Welch PSD, windows never straddle
two ranges, so no splice ever enters a spectrum. Units: acceleration m/s^2,
power (m/s^2)^2, frequencies Hz.
"""

from __future__ import annotations

import math
import shlex
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from ..dsp.contact import CONTACT_ON_N
from ..dsp.filter_design import zero_phase_highpass
from ..dsp.spectral import gfc, lsd_db, octave_bands, psd_band_power, psd_centroid, welch_psd
from ..errors import DataError, InputError
from ..limits import excerpt, signed
from ..models.texture import TextureModelSet
from .inputs import api_signals, sample_ranges
from .resampled_band import resampled_band_hz

MIN_WINDOWS = 10
"""Fewest windows a window-RMS correlation is computed over (with 4-5, one recording scored +-1.00)."""


def welch_length(rate: float, resolution_hz: float) -> int:
    """Welch segment length (samples) for a spectral resolution of ``resolution_hz`` at ``rate`` Hz (at least 16)."""
    return max(16, int(round(rate / resolution_hz)))


@dataclass
class CompareOptions:
    """Settings of :func:`compare_surface` (see the module docstring)."""

    seeds: int = 4
    highpass_hz: float = 10.0
    skip_s: float = 0.5
    min_freq_hz: float = 12.0
    window_s: float = 1.0
    resolution_hz: float = 4.0
    """Welch segment length in Hz (the segment is rate / resolution_hz samples)."""
    max_freq_hz: float = math.inf
    """Top of the band of the LSD, GFC and centroids (Hz); :func:`compare_surface` lowers it for a resampled set."""
    lookup: dict[str, Any] = field(default_factory=dict)
    """Extra ``texture_lookup`` parameters for the render (e.g. ``{"outside": "fade"}``)."""


@dataclass
class Comparison:
    """The figures of :func:`compare_surface` (module docstring); ``windows`` holds one dict per window."""

    lsd_db: float
    gfc: float
    centroid_hz: float
    rendered_centroid_hz: float
    power_ratio_db: float
    power_ratio_spread_db: float
    """Standard deviation of the single renders' power ratios (dB)."""
    rms_correlation: float
    recorded_rms: float
    rendered_rms: float
    seconds: float
    seeds: int
    windows: list[dict[str, float]]
    max_freq_hz: float = math.inf
    """Top of the shape band (Hz; inf: the Nyquist frequency)."""
    shape_lsd_db: float = float("nan")
    """LSD once the levels are matched (module docstring)."""
    band_hz: list[float] = field(default_factory=list)
    """[low, high] Hz of the LSD, GFC, centroids and octave bands."""
    resolution_hz: float = 4.0
    """Spectral resolution of the Welch PSDs (Hz)."""
    octave_bands: list[dict[str, float]] = field(default_factory=list)
    """Per octave band: centre_hz, low_hz, high_hz, recorded_power, rendered_power ((m/s^2)^2), error_db."""
    warnings: list[str] = field(default_factory=list)
    """Why a figure is null (e.g. too few windows for rms_correlation)."""
    freqs: np.ndarray | None = field(default=None, repr=False)
    """Welch frequencies (Hz) of the two PSDs below (not in the JSON)."""
    recorded_psd: np.ndarray | None = field(default=None, repr=False)
    """Recorded Welch PSD ((m/s^2)^2/Hz), high-passed, start skipped."""
    rendered_psd: np.ndarray | None = field(default=None, repr=False)
    """Mean of the renders' Welch PSDs."""

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict of the figures (keys as the fields, without the PSD arrays; NaN becomes None)."""
        def clean(v: Any) -> Any:
            if isinstance(v, float) and not np.isfinite(v):
                return None
            if isinstance(v, list):
                return [clean(x) for x in v]
            if isinstance(v, dict):
                return {k: clean(x) for k, x in v.items()}
            return v
        d = asdict(self)
        for key in ("freqs", "recorded_psd", "rendered_psd"):
            d.pop(key)
        return clean(d)


def render_along(ms: TextureModelSet, speed: np.ndarray, force: np.ndarray, seeds: list[int] | range,
                 lookup: Mapping[str, Any] | None = None) -> list[np.ndarray]:
    """Vibrations (m/s^2) of ``ms`` along (speed mm/s, force N), one per excitation seed; the graph is compiled once."""
    from .texture_graph import texture_builder

    graph = texture_builder(ms, float(ms.sample_rate), lookup).build()
    inputs = {"speed": np.asarray(speed, float), "force": np.asarray(force, float)}
    return [np.asarray(graph.run(inputs, seed=int(s))["accel"], float).reshape(-1) for s in seeds]


def _shape(freqs: np.ndarray, rec: np.ndarray, ren: np.ndarray, min_freq: float,
           max_freq: float = math.inf) -> tuple[float, float, float, float]:
    """(LSD dB, GFC, recorded centroid Hz, rendered centroid Hz) of two PSDs on ``freqs``, ``min_freq`` to ``max_freq`` Hz."""
    band = (freqs >= min_freq) & (freqs <= max_freq)
    if not np.any(rec[band] > 0):
        return float("nan"), float("nan"), float("nan"), psd_centroid(freqs, ren, min_freq, max_freq)
    lsd = lsd_db(ren, rec, freqs, min_freq_hz=min_freq, max_freq_hz=max_freq)
    return (lsd, gfc(np.sqrt(ren[band]), np.sqrt(rec[band])), psd_centroid(freqs, rec, min_freq, max_freq),
            psd_centroid(freqs, ren, min_freq, max_freq))


def _mean_psd(x: np.ndarray, ranges: list[tuple[int, int]], rate: float, nperseg: int) -> tuple[np.ndarray, np.ndarray]:
    """Segment-weighted mean of the Welch PSDs of ``x[a:b]`` over ``ranges`` (ranges shorter than a segment are left out)."""
    total, weight, freqs = None, 0, None
    for a, b in ranges:
        if b - a < nperseg:
            continue
        freqs, psd = welch_psd(x[a:b], rate, nperseg)
        segs = 1 + (b - a - nperseg) // (nperseg // 2)
        total = psd * segs if total is None else total + psd * segs
        weight += segs
    assert total is not None and freqs is not None
    return freqs, total / weight


def _octaves(freqs: np.ndarray, rec: np.ndarray, ren: np.ndarray, low: float, high: float) -> list[dict[str, float]]:
    out = []
    for centre, a, b in octave_bands(low, high):
        p_rec = psd_band_power(freqs, rec, a, b)
        p_ren = psd_band_power(freqs, ren, a, b)
        err = 10 * np.log10(p_ren / p_rec) if p_rec > 0 and p_ren > 0 else float("nan")
        out.append({"centre_hz": centre, "low_hz": a, "high_hz": b, "recorded_power": p_rec, "rendered_power": p_ren,
                    "error_db": float(err)})
    return out


def compare_signals(recorded: np.ndarray, renders: list[np.ndarray], rate: float, opt: CompareOptions | None = None,
                    ranges: list[tuple[int, int]] | None = None) -> Comparison:
    """Compare a recorded vibration with renders of the same path (module docstring); all 1-D, same length, m/s^2.

    ``ranges``: (start, stop) sample ranges to compare (default: all); the first ``skip_s`` are left out either way.
    """
    opt = opt or CompareOptions()
    if not isinstance(renders, (list, tuple)) or not renders:
        raise InputError(f"renders must be a non-empty list of rendered signals, got {excerpt(renders)}")
    rate, (recorded, *renders) = api_signals("recording", rate, recorded=recorded, **{f"renders[{k}]": r for k, r in enumerate(renders)})
    ranges = sample_ranges("recording", "ranges", ranges, recorded.shape[0])
    return compare_highpassed(highpassed(recorded, rate, opt), [highpassed(r, rate, opt) for r in renders], rate, opt, ranges)


def highpassed(x: np.ndarray, rate: float, opt: CompareOptions) -> np.ndarray:
    """``x`` (m/s^2) through the comparison's zero-phase high-pass (``opt.highpass_hz``), as :func:`compare_signals` takes it."""
    return zero_phase_highpass(np.asarray(x, float), rate, opt.highpass_hz)


def compare_highpassed(x: np.ndarray, ys: list[np.ndarray], rate: float, opt: CompareOptions,
                       ranges: list[tuple[int, int]] | None = None, where: str | None = None) -> Comparison:
    """:func:`compare_signals` on a recording and renders already through :func:`highpassed`; errors name ``where``.

    Each range is measured on its own (Welch PSDs and windows inside it), so the renders may come from different
    surfaces in different ranges (flowtex.fit.crossval's out-of-fold comparison) without a splice entering a spectrum.
    """
    try:
        return _compare(x, ys, rate, opt, ranges)
    except DataError as exc:
        if where is None:
            raise
        raise DataError(f"{where}: {exc}") from None


def _compare(x: np.ndarray, ys: list[np.ndarray], rate: float, opt: CompareOptions,
             ranges: list[tuple[int, int]] | None) -> Comparison:
    skip = int(round(opt.skip_s * rate))
    n_all = x.shape[0]
    keep = [(max(a, skip), min(b, n_all)) for a, b in (ranges if ranges is not None else [(0, n_all)])]
    keep = [(a, b) for a, b in keep if b > a]
    nperseg = welch_length(rate, opt.resolution_hz)
    n = sum(b - a for a, b in keep)
    if not any(b - a >= nperseg for a, b in keep):
        raise DataError(f"recording too short to compare: {n} samples after skipping {opt.skip_s:g} s; "
                        f"it needs a stretch of at least {nperseg / rate:.2f} s ({opt.resolution_hz:g} Hz resolution)")
    freqs, s_rec = _mean_psd(x, keep, rate, nperseg)
    s_each = [_mean_psd(y, keep, rate, nperseg)[1] for y in ys]
    s_ren = np.mean(s_each, axis=0)
    p_rec = psd_band_power(freqs, s_rec, opt.min_freq_hz)
    if p_rec <= 0:
        raise DataError(f"the recorded vibration has no power above {opt.min_freq_hz:g} Hz: nothing to compare")
    ratios = [10 * np.log10(max(psd_band_power(freqs, s, opt.min_freq_hz), 1e-300) / p_rec) for s in s_each]
    p_ren = float(np.mean([psd_band_power(freqs, s, opt.min_freq_hz) for s in s_each]))
    top = min(opt.max_freq_hz, rate / 2.0)
    lsd, g, c_rec, c_ren = _shape(freqs, s_rec, s_ren, opt.min_freq_hz, top)
    shape_lsd = lsd_db(s_ren, s_rec, freqs, min_freq_hz=opt.min_freq_hz, max_freq_hz=top, shape_only=True) \
        if np.isfinite(lsd) else float("nan")
    windows = _windows(x, ys, rate, opt, keep, nperseg)
    rms_rec = np.array([w["recorded_rms"] for w in windows])
    rms_ren = np.array([w["rendered_rms"] for w in windows])
    warnings = []
    corr = float("nan")
    if len(windows) < MIN_WINDOWS:
        warnings.append(f"rms_correlation is null: {len(windows)} windows of {opt.window_s:g} s, fewer than {MIN_WINDOWS} "
                        f"(compare a longer recording)")
    elif np.std(rms_rec) > 0 and np.std(rms_ren) > 0:
        corr = float(np.corrcoef(rms_rec, rms_ren)[0, 1])
    else:
        warnings.append("rms_correlation is null: the window RMS is constant")
    return Comparison(lsd_db=lsd, gfc=g, centroid_hz=c_rec, rendered_centroid_hz=c_ren,
                      power_ratio_db=float(10 * np.log10(max(p_ren, 1e-300) / p_rec)),
                      power_ratio_spread_db=float(np.std(ratios)) if len(ratios) > 1 else float("nan"),
                      rms_correlation=corr, recorded_rms=float(np.sqrt(p_rec)), rendered_rms=float(np.sqrt(p_ren)),
                      seconds=n / rate, seeds=len(ys), windows=windows, max_freq_hz=opt.max_freq_hz,
                      shape_lsd_db=shape_lsd, band_hz=[float(opt.min_freq_hz), float(top)], resolution_hz=float(rate / nperseg),
                      octave_bands=_octaves(freqs, s_rec, s_ren, opt.min_freq_hz, top), warnings=warnings,
                      freqs=freqs, recorded_psd=s_rec, rendered_psd=s_ren)


def _windows(x: np.ndarray, ys: list[np.ndarray], rate: float, opt: CompareOptions, keep: list[tuple[int, int]],
             nperseg: int) -> list[dict[str, float]]:
    """Per-window figures over consecutive whole ``window_s`` windows inside each range (a last partial window is left out)."""
    size = max(nperseg, int(round(opt.window_s * rate)))
    out = []
    for lo, hi in keep:
        for a in range(lo, hi - size + 1, size):
            b = a + size
            freqs, s_rec = welch_psd(x[a:b], rate, nperseg)
            s_ren = np.mean([welch_psd(y[a:b], rate, nperseg)[1] for y in ys], axis=0)
            lsd, g, c_rec, c_ren = _shape(freqs, s_rec, s_ren, opt.min_freq_hz, opt.max_freq_hz)
            out.append({"start_s": a / rate, "seconds": (b - a) / rate,
                        "recorded_rms": float(np.sqrt(psd_band_power(freqs, s_rec, opt.min_freq_hz))),
                        "rendered_rms": float(np.sqrt(psd_band_power(freqs, s_ren, opt.min_freq_hz))),
                        "lsd_db": lsd, "gfc": g, "centroid_hz": c_rec, "rendered_centroid_hz": c_ren})
    return out


def compare_surface(ms: TextureModelSet, accel: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float,
                    opt: CompareOptions | None = None, where: str = "recording",
                    ranges: list[tuple[int, int]] | None = None) -> Comparison:
    """Render ``ms`` along the recording's (speed mm/s, force N) and compare with its acceleration (module docstring).

    ``ranges``: compare only these (start, stop) sample ranges of the whole path's render (held-out blocks).
    """
    opt = opt or CompareOptions()
    rate, (accel, speed, force) = api_signals(where, rate, accel=accel, speed=speed, force=force)
    ranges = sample_ranges(where, "ranges", ranges, accel.shape[0])
    renders, opt = surface_renders(ms, accel, speed, force, rate, opt, where)
    cmp = compare_highpassed(highpassed(accel, rate, opt), [highpassed(r, rate, opt) for r in renders], rate, opt,
                             ranges, where)
    cmp.warnings.extend(path_range_warnings(ms, speed, force))
    return cmp


OUT_OF_RANGE = 2.0
"""A recorded path whose median speed or force in contact lies this many times outside the surface's measured models'
range is rendered by extrapolation only (or is in other units: m/s or mN give a factor of 1000): a warning says so."""


def path_range_warnings(ms: TextureModelSet, speed: np.ndarray, force: np.ndarray) -> list[str]:
    """Warnings for a recorded path (speed mm/s, force N) whose median in contact is far outside the measured models' range."""
    measured = ms.variance > 0
    contact = force >= CONTACT_ON_N
    if not measured.any() or not contact.any():
        return []
    out = []
    for name, unit, values, points in (("speed", "mm/s", speed, ms.speeds), ("normal force", "N", force, ms.forces)):
        lo, hi = float(np.min(points[measured])), float(np.max(points[measured]))
        median = float(np.median(values[contact]))
        if median < lo / OUT_OF_RANGE or median > hi * OUT_OF_RANGE:
            out.append(f"the recorded {name} in contact (median {median:.3g} {unit}) is more than {OUT_OF_RANGE:g}x outside "
                       f"the surface's measured {name}s ({lo:.3g}-{hi:.3g} {unit}): the render there is extrapolated; "
                       f"is the signal in {unit}?")
    return out


def surface_renders(ms: TextureModelSet, accel: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float,
                    opt: CompareOptions, where: str = "recording") -> tuple[list[np.ndarray], CompareOptions]:
    """(``opt.seeds`` renders of ``ms`` along the recorded path, ``opt`` with the band a resampled set knows): what
    :func:`compare_surface` compares, checked (matching rate, at least one seed, something rendered)."""
    if not isinstance(ms, TextureModelSet):
        raise InputError(f"the surface must be a TextureModelSet (flowtex.io.modelset.load_model_set(path) loads one), "
                         f"got {type(ms).__name__} {excerpt(ms)}")
    if opt.seeds < 1:
        raise DataError(f"--seeds must be at least 1, got {opt.seeds}")
    if abs(ms.sample_rate - rate) > 1e-9 * rate:
        surface = shlex.quote(str(ms.source)) if ms.source is not None else "SURFACE"
        raise DataError(f"{where} is at {rate:g} Hz but the surface's models are for {ms.sample_rate:g} Hz; "
                        f"resample the surface with `flowtex models resample {surface} --rate {rate:g} -o OUT.json`")
    top = resampled_band_hz(ms)
    if top <= opt.min_freq_hz:
        raise DataError(f"{ms.source or ms.material}: its resampling record (metadata resample.from_hz "
                        f"{ms.metadata['resample']['from_hz']:g} Hz) leaves the models a band up to {top:g} Hz, below the "
                        f"{opt.min_freq_hz:g} Hz where the comparison starts: nothing to compare (is the record right?)")
    if top < opt.max_freq_hz:
        opt = replace(opt, max_freq_hz=top)
    _check_moving(speed, force, opt.lookup, where)
    renders = render_along(ms, speed, force, range(opt.seeds), opt.lookup)
    _check_rendered(renders, accel, speed, force, where)
    return renders, opt


def _check_moving(speed: np.ndarray, force: np.ndarray, lookup: Mapping[str, Any], where: str) -> None:
    """Refuse a recording on which the tool never moves in contact: texture_lookup renders its rest models there (speed
    below its ``low_speed``), which a HaTT set leaves a faint residual in, so the render was not silent and the
    comparison went on, grading HaTT's rest residual against the sensor's noise under a warning that the speed might
    be in other units."""
    from ..nodes.texture import TextureLookup

    rest = float(lookup.get("low_speed", TextureLookup.params["low_speed"].default))
    contact = force >= CONTACT_ON_N
    if not contact.any() or np.any(np.abs(speed[contact]) >= rest):
        return  # out of contact throughout: _check_rendered says so
    raise DataError(f"{where}: the tool is at rest along this recording: in contact (from {CONTACT_ON_N:g} N) its speed "
                    f"reaches at most {float(np.max(np.abs(speed[contact]))):g} mm/s, below the {rest:g} mm/s under which "
                    "texture_lookup renders the set's rest models; compare on a recording of the tool moving in contact")


SILENT_RATIO = 1e-6
"""A render whose RMS is below this fraction of the recording's (-120 dB) rendered nothing: the figures would be noise."""


def _check_rendered(renders: list[np.ndarray], accel: np.ndarray, speed: np.ndarray, force: np.ndarray, where: str) -> None:
    """Refuse to compare a render of nothing: a recording whose force never reaches contact (:data:`CONTACT_ON_N`), or
    a render that is silent (the tool rests): say so instead of -3000 dB and an infinite LSD."""
    recorded = float(np.sqrt(np.mean(np.square(accel)))) if accel.size else 0.0
    rendered = max((float(np.sqrt(np.mean(np.square(r)))) for r in renders if r.size), default=0.0)
    if float(np.max(force, initial=0.0)) >= CONTACT_ON_N and rendered > SILENT_RATIO * recorded and rendered > 0.0:
        return
    raise DataError(f"{where}: nothing was rendered along this recording: its normal force reaches at most "
                    f"{float(np.max(force, initial=0.0)):g} N (contact from {CONTACT_ON_N:g} N) and its speed "
                    f"{float(np.max(np.abs(speed), initial=0.0)):g} mm/s (rendered RMS {rendered:.3g} m/s^2 against {recorded:.3g} "
                    "recorded); compare on a recording of the tool moving in contact")


def correlation_text(c: Comparison) -> str:
    """``rms_correlation`` as printed and drawn: "0.89 over 19 windows", or "null (6 windows, fewer than 10)" as the
    JSON has it (never 'nan')."""
    n = len(c.windows)
    if math.isfinite(c.rms_correlation):
        return f"{c.rms_correlation:.2f} over {n} windows"
    why = f"fewer than {MIN_WINDOWS}" if n < MIN_WINDOWS else "the window RMS is constant"
    return f"null ({n} windows, {why})"


def summary_lines(c: Comparison) -> list[str]:
    """The comparison in a few printable lines."""
    return [f"rendered along the recorded path ({c.seconds:.1f} s, {c.seeds} render(s)):",
            f"  power ratio {signed(c.power_ratio_db, 2)} dB (rendered over recorded, > 12 Hz; "
            + (f"one render scatters by {c.power_ratio_spread_db:.2f} dB" if math.isfinite(c.power_ratio_spread_db)
               else "one render: its scatter unknown, --seeds 4 measures it")
            + f"); RMS {c.rendered_rms:.3g} rendered, {c.recorded_rms:.3g} recorded (m/s^2)",
            f"  LSD {c.lsd_db:.2f} dB ({c.shape_lsd_db:.2f} dB with the levels matched), GFC {c.gfc:.3f}, "
            f"centroid {c.rendered_centroid_hz:.0f} Hz rendered, {c.centroid_hz:.0f} Hz recorded "
            f"(band {c.band_hz[0]:g}-{c.band_hz[1]:g} Hz, {c.resolution_hz:.3g} Hz resolution"
            + ("; the set was resampled from another rate)" if math.isfinite(c.max_freq_hz) else ")"),
            "  octave-band power error (dB): " + ", ".join(f"{b['centre_hz']:g} Hz {signed(b['error_db'], 1)}" for b in c.octave_bands),
            f"  {c.windows[0]['seconds'] if c.windows else 0:g}-s window RMS correlation {correlation_text(c)}",
            *(f"  warning: {w}" for w in c.warnings)]
