"""Change-point segmentation of free exploration into stationary pieces (piecewise models).

Piecewise models from free exploration: Kuchenbecker & Culbertson 2014; Culbertson & Kuchenbecker 2017.

HaTT segments with Auto-PARM (Davis et al. 2006), a genetic search for the
piecewise-AR model of least MDL. flowtex segments with ``ruptures`` (PELT,
exact and linear-time for a penalised cost) on a short-time feature vector
instead of a piecewise AR likelihood:

* per frame of ``frame_s`` (default 50 ms, no overlap): the log power of the
  vibration in ``bands`` log-spaced bands from 15 Hz to Nyquist (a coarse
  spectral shape: what changes when the ARMA model changes), log(speed + 1)
  and the force (N) - the two variables the models are labelled with;
* every band feature is divided by its noise level, estimated from first
  differences (MAD / sqrt 2, robust to the few real jumps: the frames'
  periodogram noise is white from frame to frame), so the ``l2`` cost of a
  segment is a Gaussian -2 log-likelihood with unit variance; speed and force
  wobble slowly (correlated over many frames, which the differences would not
  see), so they are divided by a resolution instead: ``speed_resolution``
  (relative, default 5 %) and ``force_resolution`` (relative to the largest
  force, default 5 %);
* the penalty per change point is BIC's: (d + 1) ln m for d features and m
  frames (d means + one location), times ``penalty_scale``. Slow wobbles of
  speed and force inside a plateau are correlated over frames; the BIC
  penalty then splits a long plateau now and then, which costs little (two
  models of the same material), whereas merging two plateaus would blur
  them.

Why not Auto-PARM's MDL directly: it needs an AR fit per candidate segment
and a genetic search; PELT on spectral features is exact for its cost and
takes milliseconds for a minute of data, and the AR models are fitted
afterwards on the pieces found.
"""

from __future__ import annotations

import numpy as np

MIN_BAND_HZ = 15.0
"""Lowest band edge (Hz): below it lies the 10 Hz high-pass's skirt."""


def frame_features(x: np.ndarray, speed: np.ndarray, force: np.ndarray, rate_hz: float, frame: int,
                   bands: int = 6) -> np.ndarray:
    """(m, bands + 2) features per frame of ``frame`` samples (see the module docstring), not yet standardised."""
    x = np.asarray(x, float)
    m = x.shape[0] // frame
    if m == 0:
        return np.zeros((0, bands + 2))
    fr = x[:m * frame].reshape(m, frame)
    spec = np.abs(np.fft.rfft((fr - fr.mean(axis=1, keepdims=True)) * np.hanning(frame), axis=1)) ** 2
    freqs = np.fft.rfftfreq(frame, 1.0 / rate_hz)
    edges = np.geomspace(MIN_BAND_HZ, rate_hz / 2.0, bands + 1)
    feats = np.empty((m, bands + 2))
    for b in range(bands):
        sel = (freqs >= edges[b]) & (freqs <= edges[b + 1]) if b == bands - 1 else (freqs >= edges[b]) & (freqs < edges[b + 1])
        if not np.any(sel):
            sel = np.argmin(np.abs(freqs - 0.5 * (edges[b] + edges[b + 1])))
            feats[:, b] = np.log(spec[:, sel] + 1e-300)
        else:
            feats[:, b] = np.log(spec[:, sel].mean(axis=1) + 1e-300)
    feats[:, bands] = np.log1p(np.maximum(np.asarray(speed, float)[:m * frame].reshape(m, frame).mean(axis=1), 0.0))
    feats[:, bands + 1] = np.asarray(force, float)[:m * frame].reshape(m, frame).mean(axis=1)
    return feats


def standardise(feats: np.ndarray, speed_resolution: float = 0.05, force_resolution: float = 0.05) -> np.ndarray:
    """Band columns over their noise level (MAD of first differences x 1.4826 / sqrt 2); speed and force over their resolution."""
    if feats.shape[0] < 3:
        return feats.copy()
    d = np.diff(feats, axis=0)
    noise = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0) / np.sqrt(2.0)
    noise = np.where(noise > 0, noise, 1.0)
    noise[-2] = speed_resolution                                   # log1p(speed): a relative step
    noise[-1] = max(force_resolution * float(np.max(np.abs(feats[:, -1]))), 1e-9)
    return (feats - np.median(feats, axis=0)) / noise


def change_points(feats: np.ndarray, min_frames: int, penalty_scale: float = 1.0) -> list[int]:
    """Frame indices where stationary pieces end (the last is ``len(feats)``), by PELT with an l2 cost and BIC penalty."""
    import ruptures

    m, d = feats.shape
    if m < 2 * min_frames:
        return [m]
    z = standardise(feats)
    pen = penalty_scale * (d + 1) * np.log(m)
    algo = ruptures.Pelt(model="l2", min_size=max(1, min_frames), jump=1).fit(z)
    return [int(b) for b in algo.predict(pen=pen)]


def segment(x: np.ndarray, speed: np.ndarray, force: np.ndarray, rate_hz: float, frame_s: float = 0.05,
            min_piece_s: float = 0.5, penalty_scale: float = 1.0) -> list[tuple[int, int]]:
    """Stationary pieces as sample ranges (start, stop) covering ``x`` (the last frame absorbs the remainder)."""
    frame = max(8, int(round(frame_s * rate_hz)))
    feats = frame_features(x, speed, force, rate_hz, frame)
    ends = change_points(feats, max(1, int(round(min_piece_s * rate_hz / frame))), penalty_scale)
    bounds = [0] + [e * frame for e in ends]
    bounds[-1] = x.shape[0]
    return [(bounds[k], bounds[k + 1]) for k in range(len(bounds) - 1) if bounds[k + 1] > bounds[k]]
