"""Speed/force trajectories of free exploration (plateaus, sweeps) and the tool paths that produce them.

Units: speed mm/s, force N, position mm; ``n`` samples at ``rate`` Hz.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..limits import check_ticks, excerpt
from ..models.texture import TextureModelSet
from ..pyvalues import plain, positive_rate, whole_count

SIGNAL_VALUES_PER_TICK = 16
"""Values a generated recording holds per sample at most (signals, their 3-axis forms, the truth): what bounds its
length before anything is allocated."""


def recording_ticks(duration_s: Any, rate: Any, seed: Any, surface: Any = None) -> tuple[int, float]:
    """(samples, rate Hz) of a generated recording of ``duration_s`` seconds, its arguments checked first: a positive
    duration and rate, a seed >= 0, at least 2 samples and no more than a recording may hold, ``surface`` None or a
    :class:`TextureModelSet` at ``rate``; else one :class:`InputError` naming the argument (not numpy's error, or a memory error
    after allocating)."""
    rate = positive_rate("rate", rate)
    seconds = plain(duration_s)
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not (np.isfinite(seconds) and seconds > 0):
        raise InputError(f"duration_s must be a positive number of seconds, got {excerpt(duration_s)}")
    whole_count("seed", seed, 0)
    if surface is not None and not isinstance(surface, TextureModelSet):
        raise InputError(f"surface must be a TextureModelSet (flowtex.io.modelset.load_model_set(path) loads one), got "
                         f"{type(surface).__name__} {excerpt(surface)}")
    if surface is not None and abs(surface.sample_rate - rate) > 1e-9 * rate:
        raise InputError(f"surface {surface.material!r} is for {surface.sample_rate:g} Hz but rate is {rate:g} Hz; pass "
                         f"rate={surface.sample_rate:g} or resample it (flowtex.fit.resample.resample_model_set)")
    n = seconds * rate
    check_ticks("duration_s x rate: samples", int(min(n, 2**62)), SIGNAL_VALUES_PER_TICK, "generate a shorter recording")
    if round(n) < 2:
        raise InputError(f"duration_s={seconds:g} s at {rate:g} Hz gives {round(n)} sample(s); a recording needs at least 2")
    return int(round(n)), rate


@dataclass(frozen=True)
class Plateau:
    """One stationary stretch of a trajectory: samples ``start:stop`` at nominal ``speed`` (mm/s) and ``force`` (N)."""

    start: int
    stop: int
    speed: float
    force: float


def _smooth_noise(n: int, rate: float, rng: np.random.Generator, corner_hz: float = 2.0) -> np.ndarray:
    """Unit-RMS slow noise: white noise through a zero-phase 2nd-order low-pass at ``corner_hz``."""
    from scipy.signal import butter, sosfiltfilt

    if n < 20:
        return np.zeros(n)
    x = sosfiltfilt(butter(2, corner_hz, fs=rate, output="sos"), rng.standard_normal(n + 200))[100:100 + n]
    return x / (np.std(x) or 1.0)


def plateau_trajectory(n: int, rate: float, rng: np.random.Generator, speed_range: tuple[float, float],
                       force_range: tuple[float, float], plateau_s: tuple[float, float] = (1.0, 2.0),
                       fluctuation: float = 0.03, ramp_s: float = 0.1) -> tuple[np.ndarray, np.ndarray, list[Plateau]]:
    """Plateaus of random length in ``plateau_s`` at random (speed, force), joined by ``ramp_s`` linear ramps.

    Inside a plateau speed and force wobble by ``fluctuation`` (relative RMS,
    slow noise below ~2 Hz). Returns (speed, force, plateaus); a plateau's
    range excludes its ramps.
    """
    speed = np.empty(n)
    force = np.empty(n)
    plateaus = []
    ramp = int(round(ramp_s * rate))
    t = 0
    prev = None
    while t < n:
        length = int(round(rng.uniform(*plateau_s) * rate))
        s, f = rng.uniform(*speed_range), rng.uniform(*force_range)
        if prev is not None:
            r = min(ramp, n - t)
            u = np.arange(1, r + 1) / (ramp + 1)
            speed[t:t + r] = prev[0] + (s - prev[0]) * u
            force[t:t + r] = prev[1] + (f - prev[1]) * u
            t += r
        stop = min(n, t + length)
        speed[t:stop] = s
        force[t:stop] = f
        if stop - t > 0:
            plateaus.append(Plateau(t, stop, s, f))
        t = stop
        prev = (s, f)
    speed *= 1.0 + fluctuation * _smooth_noise(n, rate, rng)
    force *= 1.0 + fluctuation * _smooth_noise(n, rate, rng)
    return speed, force, plateaus


def sweep_trajectory(n: int, rate: float, rng: np.random.Generator, speed_range: tuple[float, float],
                     force_range: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Smooth sweeps: speed and force follow slow sinusoids (periods ~7 s and ~11 s) across their ranges."""
    t = np.arange(n) / rate
    ps, pf = rng.uniform(0, 2 * np.pi, 2)
    speed = speed_range[0] + (speed_range[1] - speed_range[0]) * 0.5 * (1 - np.cos(2 * np.pi * t / 7.0 + ps))
    force = force_range[0] + (force_range[1] - force_range[0]) * 0.5 * (1 - np.cos(2 * np.pi * t / 11.0 + pf))
    return speed, force


def circle_path(speed: np.ndarray, rate: float, radius_mm: float = 40.0) -> np.ndarray:
    """(n, 3) positions (mm) on a circle in the z = 0 plane travelled at ``speed`` (mm/s)."""
    angle = np.cumsum(np.asarray(speed, float)) / rate / radius_mm
    return np.column_stack([radius_mm * np.cos(angle), radius_mm * np.sin(angle), np.zeros_like(angle)])
