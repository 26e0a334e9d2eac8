"""Realistic recordings of known surfaces: loudness that varies as real surfaces' does, and a person's hand motion.

Where :func:`flowtex.datasets.free_exploration` holds plateaus of speed and
force (what a segmenter finds easily), :func:`human_exploration` records what
a person does with a tool on a surface (as real recordings at 1 kHz,
~20 s, do): contact from the first sample to the last, speed and force that drift
slowly and never settle, some time below the slowest and above the fastest
speed a fit will model, and a tangential (friction) force.

The surface (:func:`loud_surface`) is a grid of known ARMA models whose
output power grows with speed and force by ``range_db`` (default 15 dB) from
the slowest, lightest model to the fastest, heaviest one, as the per-piece
models of real recordings do: power(s, f) in dB = range_db x (2/3 u_s + 1/3 u_f),
u_s = log(s / s_min) / log(s_max / s_min) (u_f likewise for force), so a power
law in speed (about P ~ s^0.8 on the default grid) and in force. Silent corner
models (variance 0) at speed 0 and force 0, as every HaTT and flowtex set has.

Units: speed mm/s, force N, acceleration m/s^2.
"""

from __future__ import annotations

import numpy as np

from ..dsp.arma import arma_output_variance
from ..models.texture import TextureModelSet
from .model_sets import lsf_to_poly_reference, synthetic_model_set
from .trajectories import _smooth_noise

EDGE_PERIODS = 4.0
"""Drift noise is filtered on this many periods of its corner frequency beyond each end, then cut (no edge transients)."""

SPEED_SHARE = 2.0 / 3.0
"""Share of the surface's power range due to speed (the rest is due to force)."""


def loud_surface(speeds: tuple[float, ...] = (15.0, 40.0, 90.0, 180.0, 320.0), forces: tuple[float, ...] = (0.3, 0.9, 1.8, 3.5, 5.0),
                 ar_order: int = 6, ma_order: int = 4, range_db: float = 15.0, peak_rms: float = 8.0,
                 sample_rate: float = 1000.0) -> TextureModelSet:
    """A known surface: ARMA models on the ``speeds`` x ``forces`` grid whose power spans ``range_db`` dB (module docstring).

    The fastest, heaviest model has an RMS of ``peak_rms`` m/s^2. Spectral
    shapes move with speed and force (flowtex.datasets.model_sets).
    """
    ms = synthetic_model_set(np.asarray(speeds, float), np.asarray(forces, float), ar_order, ma_order, grid=True,
                             sample_rate=sample_rate, material="loud-truth")
    s_lo, s_hi = min(speeds), max(speeds)
    f_lo, f_hi = min(forces), max(forces)
    for m in range(ms.num_models):
        if ms.variance[m] == 0.0:
            continue
        u_s = np.log(ms.speeds[m] / s_lo) / np.log(s_hi / s_lo)
        u_f = np.log(ms.forces[m] / f_lo) / np.log(f_hi / f_lo)
        power = peak_rms ** 2 * 10.0 ** (range_db * (SPEED_SHARE * u_s + (1.0 - SPEED_SHARE) * u_f - 1.0) / 10.0)
        unit = arma_output_variance(lsf_to_poly_reference(ms.ar_lsf[m]), lsf_to_poly_reference(ms.ma_lsf[m]), ms.gain[m], 1.0)
        ms.variance[m] = power / unit
    ms.metadata["range_db"] = float(range_db)
    return ms.validate()


def drift_noise(n: int, rate: float, rng: np.random.Generator, corner_hz: float) -> np.ndarray:
    """Unit-RMS slow noise: white noise through a zero-phase 2nd-order Butterworth low-pass at ``corner_hz``.

    Filtered over :data:`EDGE_PERIODS` periods more at each end, which are then
    dropped, so that the ends drift like the middle (``sosfiltfilt``'s edge
    handling would otherwise swing them far out).
    """
    from scipy.signal import butter, sosfiltfilt

    pad = int(round(EDGE_PERIODS * rate / corner_hz))
    x = sosfiltfilt(butter(2, corner_hz, fs=rate, output="sos"), rng.standard_normal(n + 2 * pad))[pad:pad + n]
    return (x - np.mean(x)) / (np.std(x) or 1.0)


def wander(n: int, rate: float, rng: np.random.Generator, corner_hz: float) -> np.ndarray:
    """Unit-variance slow noise whose mean over the n samples is random, as a recording's drift is.

    The middle n samples of :func:`drift_noise` over 3 n: :func:`drift_noise` itself removes the mean of what it
    returns, so a slope fitted through a drift made by it would come out right by construction (no end swing
    either, unlike :func:`flowtex.datasets.trajectories._smooth_noise`'s).
    """
    return drift_noise(3 * n, rate, rng, corner_hz)[n:2 * n]


def human_trajectory(n: int, rate: float, rng: np.random.Generator, speed_range: tuple[float, float] = (30.0, 240.0),
                     force_range: tuple[float, float] = (0.5, 2.8), drift_hz: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Speed (mm/s) and normal force (N) of a hand exploring a surface: slow log-normal drifts, never stationary.

    log speed and log force each follow slow noise (zero-phase low-pass at
    ``drift_hz``, :func:`drift_noise`, clipped at 3 standard deviations) plus a
    faster 3 % wobble (2 Hz); about 90 % of the time lies
    inside ``speed_range`` / ``force_range`` (their 5th and 95th percentiles
    for a long recording), the rest below and above: slower and faster, lighter
    and heavier than most of the recording. Force stays above 0.1 N (contact
    throughout).
    """
    z90 = 1.645                              # 5 % of a normal distribution lies above z90, 5 % below -z90

    def drift(lo: float, hi: float) -> np.ndarray:
        mid, half = 0.5 * (np.log(lo) + np.log(hi)), 0.5 * (np.log(hi) - np.log(lo))
        slow = np.clip(drift_noise(n, rate, rng, drift_hz), -3.0, 3.0)
        return np.exp(mid + half / z90 * slow + 0.03 * _smooth_noise(n, rate, rng, 2.0))

    speed = drift(*speed_range)
    force = np.maximum(drift(*force_range), 0.12)
    return speed, force


def human_exploration(duration_s: float = 20.0, rate: float = 1000.0, surface: TextureModelSet | None = None, seed: int = 0,
                      speed_range: tuple[float, float] = (30.0, 240.0), force_range: tuple[float, float] = (0.5, 2.8),
                      mu: float = 0.3, noise: float = 0.01):
    """A person's exploration of ``surface`` (default :func:`loud_surface`): see the module docstring.

    Signals: ``accel`` (1-D, m/s^2, with white sensor noise of ``noise`` x
    its RMS), ``speed`` (mm/s), ``normal_force`` (N), ``tangential_force``
    (N: ``mu`` x normal force with 5 % slow and 2 % white noise), ``position``
    (mm, a circle travelled at the speed) and ``normal``. ``truth``:
    ``surface``, ``clean`` (the noise-free vibration), ``mu``.
    """
    from . import SyntheticRecording, render_texture
    from .trajectories import circle_path, recording_ticks

    n, rate = recording_ticks(duration_s, rate, seed, surface)
    ms = surface if surface is not None else loud_surface(sample_rate=rate)
    rng = np.random.default_rng(seed)
    speed, force = human_trajectory(n, rate, rng, speed_range, force_range)
    accel = render_texture(ms, speed, force, rate, seed)
    rms = float(np.sqrt(np.mean(accel ** 2))) or 1.0
    measured = accel + noise * rms * rng.standard_normal(n)
    tangential = mu * force * (1.0 + 0.05 * wander(n, rate, rng, 1.0)) + 0.02 * mu * np.mean(force) * rng.standard_normal(n)
    arrays = {"accel": measured, "speed": speed, "normal_force": force, "tangential_force": tangential,
              "position": circle_path(speed, rate), "normal": np.tile([0.0, 0.0, 1.0], (n, 1))}
    return SyntheticRecording(arrays, rate, {"surface": ms, "clean": accel, "mu": float(mu)})
