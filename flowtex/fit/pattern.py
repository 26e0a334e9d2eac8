"""``flowtex fit pattern``: a patterned texture (features + IIR filters) from a recording (Guruswamy thesis ch. 4).

Steps: (1) the acceleration's Welch PSD is smoothed (dB, over 100 Hz) and the band edges
are the minima either side of its global maximum; (2) a 5th-order Butterworth band-pass
over that band, run forwards and backwards, serves only to find the features: one per run
of rising peaks of |band-passed| (dsp.patterns.feature_onsets); (3) each onset is placed on
the full-band waveform, at the largest prediction error of a Burg AR model of the whole
recording inside the feature's band-passed window; (4) each segment of the *full-band*
acceleration from its onset to the next, minus the ring-downs of earlier features still
sounding, is normalised by its peak A_k and fitted as an impulse response
(dsp.prony.fit_iir, guarded Steiglitz-McBride, orders 2..8, least BIC: the simplest order
that explains the waveform); (5) feature k sits where the tool was at its onset, along the
principal axis of the recorded motion. A tool that does not move is refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..dsp.patterns import RING_DECAY, band_edges, feature_onsets
from ..dsp.prony import fit_iir, impulse_response, ring_length
from ..dsp.spectral import welch_psd
from ..errors import DataError
from ..models.patterns import Pattern
from .inputs import api_signals, load, signal

MIN_SAMPLES = 256
"""Shortest recording a pattern is fitted to: one Welch segment."""
MIN_TRAVEL_MM = 1e-3
"""Least travel (mm) along the principal axis: a tool that does not move crosses no feature."""


def principal_axis(position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit axis, origin) of a path (n, 3) mm: the direction of largest spread, pointing along the motion; origin = first point."""
    centred = position - position.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    if np.dot(position[-1] - position[0], axis) < 0:
        axis = -axis
    return axis, position[0].copy()


ONSET_AR_ORDER = 8
"""Order of the Burg AR model whose prediction error marks the features' onsets (up to 4 resonances)."""
ONSET_GUARD = 1
"""Ticks the onset is moved before the largest prediction error (an impulse response's first sample may be 0)."""


def fit_pattern(accel: np.ndarray, position: np.ndarray, rate_hz: float, orders: range = range(2, 9),
                min_peak_fraction: float = 0.25) -> Pattern:
    """Fit a :class:`Pattern` to acceleration (n,) or (n, axes) m/s^2 recorded along ``position`` (n, 3) mm."""
    import scipy.signal

    rate, (accel, position) = api_signals("recording", rate_hz, {"accel": None, "position": 3}, accel=accel, position=position)
    assert rate is not None and accel is not None and position is not None
    rate_hz = rate
    if accel.ndim == 2 and accel.shape[1] > 1:  # project on the principal vibration axis
        accel = (accel - accel.mean(axis=0)) @ np.linalg.svd(accel - accel.mean(axis=0), full_matrices=False)[2][0]
    a = accel.ravel() - np.mean(accel)
    if a.size < MIN_SAMPLES:
        raise DataError(f"the recording has {a.size} samples; a pattern fit needs at least {MIN_SAMPLES} (the band-pass alone needs 34)")
    if np.max(np.abs(a)) == 0.0:
        raise DataError("the acceleration is constant: there is no texture to fit")
    axis, origin = principal_axis(position)
    x = (position - origin) @ axis
    extent = float(np.ptp(x))
    if not extent > MIN_TRAVEL_MM:
        raise DataError(f"the position moves {extent:.3g} mm along the surface: a pattern needs the tool to travel "
                        f"(at least {MIN_TRAVEL_MM:g} mm) over its features; check --position names the tool position in mm")
    freqs, psd = welch_psd(a, rate_hz, nperseg=min(256, a.size))
    lo, hi = band_edges(freqs, psd)
    nyq = rate_hz / 2
    lo, hi = max(lo, 1e-3 * nyq), min(hi, 0.999 * nyq)
    sos = scipy.signal.butter(5, [lo, hi], btype="bandpass", fs=rate_hz, output="sos")
    bp = scipy.signal.sosfiltfilt(sos, a)
    starts, tops = feature_onsets(bp, min_peak_fraction, min_gap=int(rate_hz / (2.0 * (hi - lo))))
    if starts.size == 0:
        raise DataError("no features found: the band-passed acceleration has no rising peaks")
    onsets = _full_band_onsets(a, starts, tops)
    feats = _fit_features(a, onsets, np.append(onsets[1:], a.size), orders)
    pos = [float(0.5 * (x[t - 1] + x[t])) if t > 0 else float(x[t]) for t, *_ in feats]  # crossed on tick t
    order = np.argsort(pos, kind="stable")
    p_sorted = np.asarray(pos)[order]
    meta: dict[str, Any] = {
        "band_hz": [lo, hi], "segments": len(pos), "mean_order": float(np.mean([f[3].p for f in feats])),
        "mean_sad": float(np.mean([f[3].sad * f[2] for f in feats])),
        "median_spacing_mm": float(np.median(np.diff(p_sorted))) if len(pos) > 1 else None,
        "mean_spacing_mm": _mean_spacing(p_sorted), "order_criterion": "BIC",
    }
    return Pattern(rate_hz, axis, origin, p_sorted, np.asarray([feats[i][2] for i in order]),
                   [feats[i][3].b for i in order], [feats[i][3].a for i in order], meta)


def _full_band_onsets(a: np.ndarray, starts: np.ndarray, tops: np.ndarray) -> np.ndarray:
    """Each feature's onset tick on the full-band waveform, between its band-passed start and highest peak.

    A Burg AR model of order ``ONSET_AR_ORDER`` fitted to the whole recording
    predicts the ring-downs in progress; each feature's excitation is what it
    cannot predict. The onset is the tick of the largest |prediction error| in
    the feature's band-passed window, moved ``ONSET_GUARD`` ticks earlier (a
    zero-phase band-pass puts its starts up to half its response early, and
    its peaks late, so the full band decides).
    """
    import scipy.signal

    from ..dsp.arma_estimate import burg_ar

    poly, _residual = burg_ar(a, min(ONSET_AR_ORDER, a.size // 4))
    err = np.abs(scipy.signal.lfilter(poly, [1.0], a))
    onsets = np.empty(starts.size, np.int64)
    prev = -1
    for k, (s, top) in enumerate(zip(starts, tops, strict=True)):
        onsets[k] = prev = max(int(s + np.argmax(err[s:top + 1])) - ONSET_GUARD, prev + 1)
    return onsets


def _fit_features(a: np.ndarray, starts: np.ndarray, ends: np.ndarray, orders: range) -> list:
    """[(start, end, amplitude A_k, IIRFit)] of every feature, fitted in order on the full-band segments."""
    rendered = np.zeros(a.size)
    out = []
    for start, end in zip(starts, ends, strict=True):
        if end - start < 6:
            continue
        fit = _add_feature(a, rendered, int(start), int(end), orders)
        if fit is not None:
            out.append((int(start), int(end), *fit))
    if not out:
        raise DataError("no features found: every segment is shorter than 6 ticks or silent")
    return out


def _add_feature(a: np.ndarray, rendered: np.ndarray, start: int, end: int, orders: range) -> tuple[float, Any] | None:
    """Fit a[start:end] minus the ring-downs in ``rendered`` as A_k times an impulse response; add its ring-down to ``rendered``.

    The order is the one with the least BIC (dsp.prony.bic) on the full-band
    segment. A feature's ring-down must die out "a short time after" it
    (Guruswamy thesis sec. 4.3.3): here to 1 % within 3 segment lengths, otherwise
    slow poles that the short segment cannot pin down would ring on under the next features.
    """
    target = a[start:end] - rendered[start:end]
    amp = float(np.max(np.abs(target)))
    if amp == 0.0:
        return None
    fit = fit_iir(target / amp, orders, radius=0.01 ** (1.0 / (3.0 * (end - start))), criterion="bic")
    ring = min(a.size - start, ring_length(fit.b, fit.a, RING_DECAY))
    rendered[start:start + ring] += amp * impulse_response(fit.b, fit.a, ring)
    return amp, fit


def _mean_spacing(p: np.ndarray) -> float | None:
    """Mean gap between neighbouring features, ignoring gaps outside 0.5..1.5 x the median (missed or doubled features)."""
    if p.size < 2:
        return None
    d = np.diff(p)
    med = np.median(d)
    keep = d[(d > 0.5 * med) & (d < 1.5 * med)]
    return float(np.mean(keep)) if keep.size else float(med)


def fit_pattern_recording(recording: str | Path, accel: str, position: str, from_rate: float | None = None,
                          speed: str | None = None, max_order: int = 8) -> Pattern:
    """Fit a :class:`Pattern` to one recording (signals named as the options; filter orders 2..``max_order``)."""
    rec, rate = load(recording, from_rate)
    acc = signal(rec, accel, "--accel", (1, 2, 3))
    pos = signal(rec, position, "--position", (3,))
    if max_order < 2:
        raise DataError(f"--max-order must be at least 2, got {max_order}")
    try:
        pat = fit_pattern(acc, pos, rate, orders=range(2, max_order + 1))
    except DataError as exc:
        raise DataError(f"{recording}: {exc}") from None
    pat.metadata["recording"] = str(recording)
    if speed:
        pat.metadata["mean_speed_mm_s"] = float(np.mean(np.abs(signal(rec, speed, "--speed", (1,)))))
    return pat


def pattern_summary(pat: Pattern) -> str:
    """One line: features, band, mean order, SAD and spacing."""
    m = pat.metadata
    return (f"{m['segments']} features, band {m['band_hz'][0]:.0f}-{m['band_hz'][1]:.0f} Hz, "
            f"mean order {m['mean_order']:.1f}, mean SAD {m['mean_sad']:.4g} m/s^2, spacing {m['mean_spacing_mm']:.4g} mm")
