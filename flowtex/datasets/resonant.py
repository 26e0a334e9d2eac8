"""Recordings that behave like real tool-surface recordings: moving resonances, heavy tails, loudness that wanders.

The generators of :mod:`flowtex.datasets.realistic` vary only the power of a
surface with speed and force. Real recordings (copper, fabric,
leather, paper, stone and wood, 19 s each at 1 kHz; docs/fitting.md) differ in four ways, and
each is built in here:

* **resonances that move**: every model is two resonances (AR order 4) and a
  zero pair (MA order 2); the first resonance's frequency grows with speed
  (f1 = ``f1_hz`` x (s / 130)^0.6 x (F / 0.3)^0.05 Hz) and its bandwidth with force and speed
  (B1 = ``b1_hz`` x (F / 0.3)^0.25 x (s / 130)^0.3 Hz), the second sits at
  3 x f1 with 6 x the bandwidth and a zero pair (radius 0.5) at 2 x f1 makes
  a shallow dip between them: 33-39 dB from the spectrum's peak to its floor
  above 12 Hz, as broadband real vibration has; along the default path the spectral
  centroid moves by some 25 Hz (a stone recording's moved from 50 to 77 Hz);
* **power that spans a range**: the output power of a model is
  ``peak_rms``^2 x (s / 320)^``speed_exp`` x (F / 4.3)^``force_exp``: about
  22 dB from (130 mm/s, 0.3 N) to (320 mm/s, 4.3 N);
* **loudness that wanders**: each second of the recording is louder or quieter
  than its speed and force explain, by a log-normal factor of ``loudness_db``
  dB (standard deviation; real recordings: 1.5-5.7 dB), joined by 50 ms
  raised-cosine fades;
* **heavy tails**: the excitation is white Gaussian noise times a slowly
  bursting scale (log-normal, ``burst`` natural-log standard deviation of the
  amplitude, low-pass at ``burst_hz``: bursts of some 10 ms), a Gaussian scale mixture: still white, so the expected
  spectrum is the model's, but its kurtosis is 4-12 after the resonances, as
  real vibration's is.

The recording is rendered by flowtex's own nodes (``texture_lookup`` +
``arma_synth``, :func:`flowtex.fit.texture_graph.texture_builder` with ``scaled=True``): the two
wandering factors multiply the excitation variance, tick by tick, and the
whole recording is then scaled so that its power equals the power of the true
surface's own render along the same path (``truth["clean"]``, the same
excitation without the factors). The true surface (``truth["surface"]``) is
therefore the surface a perfect fit would find: render it along the recorded
path and it is as loud as the recording, with the recording's expected
spectrum at every instant.

Units: speed mm/s, force N, acceleration m/s^2, frequencies Hz.
"""

from __future__ import annotations

import math

import numpy as np

from ..dsp.arma import arma_output_variance
from ..models.texture import TextureModelSet
from .model_sets import poly_from_roots, poly_to_lsf_reference
from .realistic import drift_noise, wander

SPEED_RANGE = (130.0, 320.0)
"""Speeds (mm/s) of the default path: those of six real tool-surface recordings (docs/fitting.md)."""
FORCE_RANGE = (0.3, 4.3)
"""Normal forces (N) of the default path: those of six real tool-surface recordings (docs/fitting.md)."""
FADE_S = 0.05
"""Raised-cosine fade (s) between two seconds' loudness factors."""


def resonant_model(speed: float, force: float, rate: float = 1000.0, f1_hz: float = 38.0,
                   b1_hz: float = 9.0) -> tuple[np.ndarray, np.ndarray]:
    """(A, C): the true spectral shape at (speed mm/s, force N), AR order 4 and MA order 2 (module docstring)."""
    s = max(speed, 1.0) / SPEED_RANGE[0]
    f = max(force, 0.01) / FORCE_RANGE[0]
    f1 = f1_hz * s ** 0.6 * f ** 0.05
    b1 = b1_hz * f ** 0.25 * s ** 0.3
    freqs = np.array([f1, 3.0 * f1])
    widths = np.array([b1, 6.0 * b1])
    a = poly_from_roots(np.exp(-math.pi * widths / rate), 2.0 * math.pi * freqs / rate)
    c = poly_from_roots(np.array([0.5]), np.array([2.0 * math.pi * 2.0 * f1 / rate]))   # a shallow dip between the two
    return a, c


def resonant_surface(speeds: tuple[float, ...] = (90.0, 130.0, 170.0, 220.0, 280.0, 350.0, 420.0),
                     forces: tuple[float, ...] = (0.15, 0.3, 0.6, 1.1, 2.0, 3.2, 4.3, 5.5), peak_rms: float = 6.0,
                     speed_exp: float = 2.0, force_exp: float = 1.0, sample_rate: float = 1000.0) -> TextureModelSet:
    """The true surface: :func:`resonant_model` on the ``speeds`` x ``forces`` grid, powers by the module's power law.

    Silent corner models (variance 0, the shape of the nearest grid model) at
    speed 0 for every force, at force 0 for every speed and at (0, 0), as in
    every HaTT and flowtex set. ``peak_rms`` (m/s^2) is the RMS at (320 mm/s, 4.3 N).
    """
    from scipy.spatial import Delaunay

    grid = [(s, f) for s in speeds for f in forces]
    corners = [(0.0, f) for f in forces] + [(s, 0.0) for s in speeds] + [(0.0, 0.0)]
    pts = np.array(grid + corners, dtype=np.float64)
    scale = np.array([max(speeds), max(forces)])
    ar, ma, var = [], [], []
    for m, pt in enumerate(pts):
        src = m if m < len(grid) else int(np.argmin(np.sum(((np.array(grid) - pt) / scale) ** 2, axis=1)))
        s, f = grid[src]
        a, c = resonant_model(s, f, sample_rate)
        ar.append(poly_to_lsf_reference(a))
        ma.append(poly_to_lsf_reference(c))
        power = peak_rms ** 2 * (s / SPEED_RANGE[1]) ** speed_exp * (f / FORCE_RANGE[1]) ** force_exp
        var.append(0.0 if m >= len(grid) else power / arma_output_variance(a, c, 1.0, 1.0))
    ms = TextureModelSet(material="resonant-truth", sample_rate=float(sample_rate), speeds=pts[:, 0].copy(),
                         forces=pts[:, 1].copy(), triangles=Delaunay(pts).simplices.astype(np.int64),
                         ar_lsf=np.array(ar), ma_lsf=np.array(ma), variance=np.array(var), gain=np.ones(len(pts)),
                         max_speed=float(max(speeds)), max_force=float(max(forces)),
                         metadata={"generator": "flowtex.datasets.resonant.resonant_surface"})
    return ms.validate()


def bounded_path(n: int, rate: float, rng: np.random.Generator, speed_range: tuple[float, float] = SPEED_RANGE,
                 force_range: tuple[float, float] = FORCE_RANGE, drift_hz: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Speed (mm/s) and force (N) of a hand that never settles, strictly inside the given ranges.

    u = (1 + tanh(z)) / 2 of a unit slow noise z (:func:`flowtex.datasets.realistic.drift_noise` at ``drift_hz``)
    maps into the range geometrically: lo x (hi / lo)^u; in contact throughout.
    """
    def one(lo: float, hi: float) -> np.ndarray:
        u = 0.5 * (1.0 + np.tanh(1.2 * drift_noise(n, rate, rng, drift_hz)))
        return lo * (hi / lo) ** u

    return one(*speed_range), one(*force_range)


def wander_power(n: int, rate: float, rng: np.random.Generator, loudness_db: float, burst: float,
                 burst_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """(excitation power factor per sample, loudness in dB per second): the two wandering factors of the module docstring."""
    seconds = int(math.ceil(n / rate))
    level_db = loudness_db * rng.standard_normal(seconds)
    step = np.repeat(level_db, int(round(rate)))[:n]
    fade = max(2, int(round(FADE_S * rate)))
    window = np.hanning(fade)
    smooth = np.convolve(np.pad(step, (fade // 2, fade - fade // 2 - 1), mode="edge"), window / window.sum(), mode="valid")
    bursts = np.exp(2.0 * burst * drift_noise(n, rate, rng, burst_hz))      # variance factor = (amplitude factor)^2
    return 10.0 ** (smooth / 10.0) * bursts, level_db


def textured_exploration(duration_s: float = 20.0, rate: float = 1000.0, surface: TextureModelSet | None = None,
                         seed: int = 0, loudness_db: float = 2.0, burst: float = 0.8, burst_hz: float = 15.0,
                         speed_range: tuple[float, float] = SPEED_RANGE, force_range: tuple[float, float] = FORCE_RANGE,
                         mu: float = 0.3, noise: float = 0.01):
    """A recording of ``surface`` (default :func:`resonant_surface`) that behaves like a real one (module docstring).

    Signals: ``accel`` (m/s^2, with white sensor noise of ``noise`` x its RMS), ``speed`` (mm/s),
    ``normal_force`` (N), ``tangential_force`` (N, ``mu`` x the normal force with 5 % slow noise),
    ``position`` (mm, a circle travelled at the speed) and ``normal``. ``truth``: ``surface`` (the true
    model set), ``clean`` (its own render along the path, the same excitation without the wandering
    factors), ``power_factor`` (the excitation variance factor per sample, after the final scaling),
    ``loudness_db`` (the drawn level of each second), ``mu``.
    """
    from ..fit.texture_graph import texture_builder
    from . import SyntheticRecording
    from .trajectories import circle_path, recording_ticks

    n, rate = recording_ticks(duration_s, rate, seed, surface)
    ms = surface if surface is not None else resonant_surface(sample_rate=rate)
    rng = np.random.default_rng(seed)
    speed, force = bounded_path(n, rate, rng, speed_range, force_range)
    factor, level_db = wander_power(n, rate, rng, loudness_db, burst, burst_hz)
    graph = texture_builder(ms, rate, scaled=True).build()
    inputs = {"speed": speed, "force": force}
    wild = np.asarray(graph.run(inputs | {"power_factor": factor}, seed=seed)["accel"], float)
    clean = np.asarray(graph.run(inputs | {"power_factor": np.ones(n)}, seed=seed)["accel"], float)
    wild, clean = wild.reshape(-1), clean.reshape(-1)
    gain = math.sqrt(float(np.sum(clean ** 2)) / float(np.sum(wild ** 2)))
    accel = gain * wild
    rms = float(np.sqrt(np.mean(accel ** 2))) or 1.0
    measured = accel + noise * rms * rng.standard_normal(n)
    tangential = mu * force * (1.0 + 0.05 * wander(n, rate, rng, 1.0))
    arrays = {"accel": measured, "speed": speed, "normal_force": force, "tangential_force": tangential,
              "position": circle_path(speed, rate), "normal": np.tile([0.0, 0.0, 1.0], (n, 1))}
    truth = {"surface": ms, "clean": clean, "power_factor": gain ** 2 * factor, "loudness_db": level_db, "mu": float(mu)}
    return SyntheticRecording(arrays, rate, truth)
