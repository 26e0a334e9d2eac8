"""``flowtex fit pattern``: a patterned texture (features + IIR filters) from a recording (Guruswamy thesis ch. 4).

Steps: (1) the acceleration's Welch PSD is smoothed (dB, 9-bin centred moving
average) and the band edges are the minima either side of its global maximum;
(2) a 5th-order Butterworth band-pass over that band, run forwards and backwards
(zero phase, so segment starts stay aligned with the raw signal), serves only
segmentation: a segment starts where a peak of |a| is larger than the peak before
it (dsp.patterns.segment_starts); (3) each segment of the *full-band* acceleration,
minus the ring-downs of earlier features still sounding, is normalised by its peak
A_k and fitted as an impulse response (dsp.prony.fit_iir, guarded Steiglitz-McBride,
orders 2..8, least SAD); (4) feature k sits where the tool was at its segment's start,
along the principal axis of the recorded motion.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..dsp.patterns import RING_DECAY, band_edges, segment_starts
from ..dsp.prony import fit_iir, impulse_response, ring_length
from ..dsp.spectral import welch_psd
from ..errors import DataError
from ..io.patternfile import Pattern
from ..io.recordings import load_recording
from .recording_signals import recording_rate, signal

MIN_SAMPLES = 256
"""Shortest recording a pattern is fitted to: one Welch segment."""


def principal_axis(position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit axis, origin) of a path (n, 3) mm: the direction of largest spread, pointing along the motion; origin = first point."""
    centred = position - position.mean(axis=0)
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    if np.dot(position[-1] - position[0], axis) < 0:
        axis = -axis
    return axis, position[0].copy()


def fit_pattern(accel: np.ndarray, position: np.ndarray, rate_hz: float, orders: range = range(2, 9),
                min_peak_fraction: float = 0.25) -> Pattern:
    """Fit a :class:`Pattern` to acceleration (n,) or (n, axes) m/s^2 recorded along ``position`` (n, 3) mm."""
    import scipy.signal

    accel = np.asarray(accel, dtype=np.float64)
    if accel.ndim == 2 and accel.shape[1] > 1:  # project on the principal vibration axis
        accel = (accel - accel.mean(axis=0)) @ np.linalg.svd(accel - accel.mean(axis=0), full_matrices=False)[2][0]
    a = accel.ravel() - np.mean(accel)
    if a.size < MIN_SAMPLES:
        raise DataError(f"the recording has {a.size} samples; a pattern fit needs at least {MIN_SAMPLES} (the band-pass alone needs 34)")
    if np.max(np.abs(a)) == 0.0:
        raise DataError("the acceleration is constant: there is no texture to fit")
    freqs, psd = welch_psd(a, rate_hz, nperseg=min(256, a.size))
    lo, hi = band_edges(freqs, psd)
    nyq = rate_hz / 2
    lo, hi = max(lo, 1e-3 * nyq), min(hi, 0.999 * nyq)
    sos = scipy.signal.butter(5, [lo, hi], btype="bandpass", fs=rate_hz, output="sos")
    bp = scipy.signal.sosfiltfilt(sos, a)
    starts = segment_starts(bp, min_peak_fraction)
    if starts.size == 0:
        raise DataError("no features found: the band-passed acceleration has no rising peaks")
    axis, origin = principal_axis(position)
    x = (position - origin) @ axis
    rendered = np.zeros(a.size)
    bs, as_, amps, pos, sads, ords = [], [], [], [], [], []
    ends = np.append(starts[1:], a.size)
    for start, end in zip(starts, ends, strict=True):
        target = a[start:end] - rendered[start:end]
        amp = float(np.max(np.abs(target)))
        if end - start < 6 or amp == 0.0:
            continue
        # a feature's ring-down must die out "a short time after" it (Guruswamy thesis sec. 4.3.3): here to 1 % within 3 segment lengths,
        # otherwise slow poles that the short segment cannot pin down would ring on under the next features
        fit = fit_iir(target / amp, orders, radius=0.01 ** (1.0 / (3.0 * (end - start))))
        ring = min(a.size - start, ring_length(fit.b, fit.a, RING_DECAY))
        rendered[start:start + ring] += amp * impulse_response(fit.b, fit.a, ring)
        bs.append(fit.b)
        as_.append(fit.a)
        amps.append(amp)
        pos.append(float(0.5 * (x[start - 1] + x[start])) if start > 0 else float(x[start]))  # crossed on tick `start`
        sads.append(fit.sad * amp)
        ords.append(fit.p)
    order = np.argsort(pos, kind="stable")
    p_sorted = np.asarray(pos)[order]
    meta: dict[str, Any] = {
        "band_hz": [lo, hi], "segments": len(pos), "mean_order": float(np.mean(ords)),
        "mean_sad": float(np.mean(sads)), "median_spacing_mm": float(np.median(np.diff(p_sorted))) if len(pos) > 1 else None,
        "mean_spacing_mm": _mean_spacing(p_sorted),
    }
    return Pattern(rate_hz, axis, origin, p_sorted, np.asarray(amps)[order], [bs[i] for i in order], [as_[i] for i in order], meta)


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
    rec = load_recording(recording)
    rate = recording_rate(rec, from_rate)
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
