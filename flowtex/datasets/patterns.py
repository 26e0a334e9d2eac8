"""Synthetic recordings with known truth for patterned textures and WHaT compliance (tests, examples, benchmarks).

* :func:`patterned_recording` -- a tool moving along x over features every
  ``spacing_mm``; crossing feature k starts a decaying resonance of amplitude A_k
  (a 2-pole, 2-zero filter excited at the crossing tick); the recorded acceleration
  is the sum of all ring-downs plus white noise whose standard deviation is
  ``noise`` times the clean signal's RMS.
* :func:`stroking_recording` -- strokes of varying normal force separated by
  lift-offs. How acceleration is tied to force, and why: Guruswamy thesis sec. 5.2 (after Lang &
  Andrews) observes the RMS vibration growing linearly with the applied force, with
  a slope that grows with stiffness (a soft material absorbs the vibration; for
  m u'' + b u' + k u = f the response to the texture's excitation grows with k).
  The simulation makes exactly that model true: the acceleration is a unit-RMS
  band-limited texture vibration v(t) (2nd-order Butterworth band 50..300 Hz) times
  the envelope ``a0 + (k_c / k_g) (f(t) - f_min)`` (m/s^2), plus white sensor noise,
  plus a constant offset (gravity, removed by the estimator's high-pass). Its
  ground truth is therefore k_c under the simulation's own normalisation k_g.
"""

from __future__ import annotations

import numpy as np


def resonance(freq_hz: float, decay_s: float, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of a decaying sinusoid exp(-t / decay_s) sin(2 pi f t) sampled at ``rate_hz`` (Guruswamy thesis eq. 4)."""
    r = np.exp(-1.0 / (decay_s * rate_hz))
    w = 2 * np.pi * freq_hz / rate_hz
    return np.array([0.0, r * np.sin(w)]), np.array([1.0, -2 * r * np.cos(w), r * r])


def feature_crossings(x_mm: np.ndarray, features_mm: np.ndarray) -> list[tuple[int, int]]:
    """(tick, feature index) for every crossing of a feature by the 1-D path ``x_mm`` (either direction)."""
    out = []
    for t in range(1, x_mm.size):
        lo, hi = x_mm[t - 1], x_mm[t]
        if hi > lo:
            ks = np.nonzero((features_mm > lo) & (features_mm <= hi))[0]
        else:
            ks = np.nonzero((features_mm >= hi) & (features_mm < lo))[0]
        out.extend((t, int(k)) for k in ks)
    return out


def render_features(x_mm: np.ndarray, features_mm: np.ndarray, amplitudes: np.ndarray,
                    filters: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Float64 reference of a patterned texture: the sum of untruncated ring-downs A_k h_k(t - t_k) (m/s^2)."""
    import scipy.signal

    y = np.zeros(x_mm.size)
    for t, k in feature_crossings(x_mm, features_mm):
        x = np.zeros(x_mm.size - t)
        x[0] = amplitudes[k]
        y[t:] += scipy.signal.lfilter(filters[k][0], filters[k][1], x)
    return y


def pole_decay_s(radius: float, rate_hz: float) -> float:
    """Decay time (s) of a pole of the given radius at ``rate_hz``: r = exp(-1 / (decay_s rate_hz))."""
    return -1.0 / (rate_hz * float(np.log(radius)))


def parallel(filters: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of filters in parallel (their impulse responses summed): b = sum_i b_i prod_{j != i} a_j, a = prod_j a_j."""
    a = np.array([1.0])
    for _, ai in filters:
        a = np.convolve(a, ai)
    terms = []
    for i, (bi, _) in enumerate(filters):
        term = np.asarray(bi, float)
        for j, (_, aj) in enumerate(filters):
            if j != i:
                term = np.convolve(term, aj)
        terms.append(term)
    b = np.zeros(max(t.size for t in terms))
    for term in terms:  # coefficients of z^0, z^-1, ...: aligned at index 0
        b[:term.size] += term
    return b, a


def patterned_recording(seconds: float = 4.0, speed_mm_s: float = 60.0, spacing_mm: float = 2.0, rate_hz: float = 1000.0,
                        freq_hz: float = 180.0, decay_s: float = 0.006, noise: float = 0.05, seed: int = 0,
                        amplitude: float = 10.0, spread: float = 0.5,
                        extra: tuple[tuple[float, float], ...] = ()) -> dict:
    """A recording over a regular grating; returns arrays ``accel`` (m/s^2), ``position`` (mm, (n, 3)), ``speed`` and the truth.

    Feature amplitudes are ``amplitude`` x U(1 - ``spread``, 1 + ``spread``)
    (m/s^2 per unit impulse); each feature is a resonance at ``freq_hz``
    decaying in ``decay_s``, plus one more in parallel per (freq_hz, decay_s)
    pair in ``extra`` (features with two resonances).
    """
    rng = np.random.default_rng(seed)
    n = int(round(seconds * rate_hz))
    x = 1.0 + speed_mm_s * np.arange(n) / rate_hz
    features = np.arange(spacing_mm, x[-1] + spacing_mm, spacing_mm)
    amplitudes = amplitude * rng.uniform(1.0 - spread, 1.0 + spread, features.size)
    filt = resonance(freq_hz, decay_s, rate_hz)
    if extra:
        filt = parallel([filt] + [resonance(f, d, rate_hz) for f, d in extra])
    clean = render_features(x, features, amplitudes, [filt] * features.size)
    accel = clean + noise * np.sqrt(np.mean(clean ** 2)) * rng.standard_normal(n)
    position = np.column_stack([x, np.full(n, 5.0), np.zeros(n)])
    return {"accel": accel, "position": position, "speed": np.full(n, speed_mm_s), "rate": rate_hz,
            "features_mm": features, "amplitudes": amplitudes, "filter": filt, "clean": clean}


def stroking_recording(k_c: float, seconds: float = 120.0, k_g: float = 0.5, a0: float = 0.3, rate_hz: float = 1000.0,
                       force_range: tuple[float, float] = (0.3, 3.0), sensor_noise: float = 0.02, stroke_jitter: float = 0.05,
                       seed: int = 0) -> dict:
    """Strokes (2-4 s, 0.5 s lift-offs) with slowly varying force; returns ``force`` (N), ``accel`` (m/s^2), ``contact``.

    Realistic noise: force sensor noise 0.01 N, accelerometer noise ``sensor_noise``
    m/s^2, and each stroke's vibration scaled by 1 + ``stroke_jitter`` N(0, 1) (the
    texture under the probe differs from stroke to stroke).
    """
    import scipy.signal

    rng = np.random.default_rng(seed)
    n = int(round(seconds * rate_hz))
    force = np.zeros(n)
    contact = np.zeros(n)
    jitter = np.ones(n)
    t = 0
    f_min, f_max = force_range
    while t < n:
        length = int(rng.uniform(2.0, 4.0) * rate_hz)
        stop = min(n, t + length)
        u = np.linspace(0.0, 1.0, stop - t)
        start, end = rng.uniform(f_min, f_max, 2)
        wobble = 0.5 * (f_max - f_min) * 0.3 * np.sin(2 * np.pi * rng.uniform(0.3, 0.8) * u * length / rate_hz + rng.uniform(0, 6.3))
        force[t:stop] = np.clip(start + (end - start) * u + wobble, f_min, f_max)
        contact[t:stop] = 1.0
        jitter[t:stop] = max(0.0, 1.0 + stroke_jitter * rng.standard_normal())
        t = stop + int(0.5 * rate_hz)
    sos = scipy.signal.butter(2, [50.0, 300.0], btype="bandpass", fs=rate_hz, output="sos")
    v = scipy.signal.sosfilt(sos, rng.standard_normal(n))
    v /= np.std(v)
    envelope = np.where(contact > 0, a0 + (k_c / k_g) * (force - f_min), 0.0)
    accel = envelope * jitter * v + sensor_noise * rng.standard_normal(n) + 9.81
    measured = force + 0.01 * rng.standard_normal(n) * (contact > 0)
    return {"force": measured, "accel": accel, "contact": contact, "rate": rate_hz, "k_c": k_c, "k_g": k_g}
