"""Ground-truth recordings: known surfaces rendered along known trajectories (docs/fitting.md, "Ground truth").

Every function returns a :class:`SyntheticRecording`: the signals a sensor
would record (``accel`` in m/s^2, ``position`` in mm, ``normal`` (unit
vector), ``normal_force`` in N, plus ``speed`` in mm/s and, for friction,
``tangential_force`` in N) at ``rate`` Hz, and the ``truth`` that made them.
The vibration, tap transients and friction forces are rendered through
flowtex's own graphs (:mod:`flowtex.datasets.graphs`), so a fit can be
compared with the exact models the nodes render. ``save(path)`` writes the
recording with its rate (``flowtex.io.recordings``).

* :func:`free_exploration`: plateaus of 1-2 s at random (speed, force) with
  small fluctuations (HaTT-style free exploration), or smooth sweeps;
* :func:`tap_session`: taps at known incoming speeds;
* :func:`friction_session`: tangential = mu normal (+ offset) with 10 %
  noise, stiction spikes and samples out of contact;
* sensor noise (white, relative to the signal's RMS) and outliers (isolated
  spikes) on the acceleration.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ..io.recordings import save_recording
from ..limits import excerpt
from ..models.taps import TapLibrary
from ..models.texture import TextureModelSet
from ..pyvalues import plain
from .graphs import FRICTION_GRAPH, TAP_GRAPH, run_graph
from .model_sets import synthetic_model_set
from .taps import synthetic_tap_library
from .trajectories import Plateau, circle_path, plateau_trajectory, recording_ticks, sweep_trajectory

__all__ = ["Plateau", "SyntheticRecording", "default_surface", "free_exploration", "friction_session", "render_texture",
           "tap_session"]


SIGNAL_UNITS = {"accel": "m/s^2", "position": "mm", "speed": "mm/s", "velocity": "mm/s", "normal_force": "N",
                "tangential_force": "N", "force": "N"}
"""The unit of each signal the generators record, stated in the files they save (``normal`` is a unit vector, and
states none): flowtex checks a stated unit against the graph input or the fit option that takes the signal."""


@dataclass
class SyntheticRecording:
    """Signals (time first) at ``rate`` Hz and the ground truth that made them."""

    arrays: dict[str, np.ndarray]
    rate: float
    truth: dict[str, Any] = field(default_factory=dict)

    def save(self, path: str | Path) -> Path:
        """Write the recording (.npz, .csv or .h5) with its rate and its signals' units (:data:`SIGNAL_UNITS`), as a
        real rig's files state them; returns the path."""
        save_recording(path, self.arrays, rate=self.rate,
                       units={name: SIGNAL_UNITS[name] for name in self.arrays if name in SIGNAL_UNITS})
        return Path(path)


def default_surface(ar_order: int = 6, ma_order: int = 4, sample_rate: float = 1000.0) -> TextureModelSet:
    """A known surface: stable ARMA models on a 4 x 4 grid (40..320 mm/s, 0.4..3 N) with silent corners.

    Models change smoothly with speed and force (flowtex.datasets.model_sets);
    variances are scaled so that the vibration is about 1 m/s^2 RMS.
    """
    ms = synthetic_model_set(np.linspace(40.0, 320.0, 4), np.linspace(0.4, 3.0, 4), ar_order, ma_order,
                             sample_rate=sample_rate, material="ground-truth")
    ms.variance = ms.variance * 1e3
    return ms.validate()


def render_texture(ms: TextureModelSet, speed: np.ndarray, force: np.ndarray, rate: float, seed: int = 0) -> np.ndarray:
    """Vibration (m/s^2) of ``ms`` along a (speed mm/s, force N) trajectory: texture_lookup + arma_synth."""
    from ..fit.texture_graph import texture_builder

    out = texture_builder(ms, rate).build().run({"speed": np.asarray(speed, float), "force": np.asarray(force, float)}, seed=seed)
    return np.asarray(out["accel"], dtype=np.float64).reshape(-1)


def _sensor(accel: np.ndarray, rng: np.random.Generator, noise: float, outliers: int) -> tuple[np.ndarray, np.ndarray]:
    """Add white noise (``noise`` x RMS) and ``outliers`` isolated spikes of 20 x RMS; returns (signal, spike indices)."""
    rms = float(np.sqrt(np.mean(accel ** 2))) or 1.0
    out = accel + noise * rms * rng.standard_normal(accel.shape)
    where = np.sort(rng.choice(accel.shape[0], size=outliers, replace=False)) if outliers else np.zeros(0, np.int64)
    out[where] += 20.0 * rms * rng.choice([-1.0, 1.0], size=where.size)
    return out, where


def _three_axes(accel: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Spread a 1-D vibration over three axes along a fixed unit direction (DFT321 gives it back up to sign)."""
    direction = np.array([0.48, 0.6, 0.64])
    return accel[:, None] * direction[None, :]


def free_exploration(duration_s: float = 60.0, rate: float = 1000.0, surface: TextureModelSet | None = None, seed: int = 0,
                     plateau_s: tuple[float, float] = (1.0, 2.0), fluctuation: float = 0.03, sweep: bool = False,
                     noise: float = 0.01, outliers: int = 0, axes: int = 1, lift_s: float = 0.0) -> SyntheticRecording:
    """Free exploration of ``surface`` (default :func:`default_surface`): plateaus (or ``sweep``) of speed and force.

    ``fluctuation`` is the relative RMS of the slow speed/force wobble inside
    a plateau; ``noise`` the sensor noise relative to the vibration's RMS;
    ``outliers`` the number of 20 x RMS spikes; ``axes`` 1 or 3 (a 3-axis
    ``accel``); ``lift_s`` > 0 lifts the tool (force 0) for that long at the
    start. ``truth``: ``surface``, ``plateaus`` (list of :class:`Plateau`,
    sample ranges and nominal speed/force), ``outliers`` (indices), ``clean``
    (the noise-free vibration).
    """
    n, rate = recording_ticks(duration_s, rate, seed, surface)
    if axes not in (1, 3):
        raise InputError(f"axes must be 1 (accel of shape (n,)) or 3 (accel of shape (n, 3)), got {excerpt(axes)}")
    ms = surface if surface is not None else default_surface(sample_rate=rate)
    rng = np.random.default_rng(seed)
    lim_s = (0.15 * ms.max_speed, 0.95 * ms.max_speed)
    lim_f = (0.15 * ms.max_force, 0.95 * ms.max_force)
    if sweep:
        speed, force = sweep_trajectory(n, rate, rng, lim_s, lim_f)
        plateaus: list[Plateau] = []
    else:
        speed, force, plateaus = plateau_trajectory(n, rate, rng, lim_s, lim_f, plateau_s, fluctuation)
    lift = int(round(lift_s * rate))
    if lift:
        force[:lift] = 0.0
        plateaus = [p for p in plateaus if p.start >= lift]
    accel = render_texture(ms, speed, force, rate, seed)
    measured, spikes = _sensor(accel, rng, noise, outliers)
    arrays = {"accel": _three_axes(measured, rng) if axes == 3 else measured,
              "position": circle_path(speed, rate), "normal": np.tile([0.0, 0.0, 1.0], (n, 1)),
              "normal_force": force, "speed": speed}
    return SyntheticRecording(arrays, rate, {"surface": ms, "plateaus": plateaus, "outliers": spikes, "clean": accel})


def tap_session(speeds: tuple[float, ...] = (30.0, 55.0, 70.0, 90.0, 120.0, 160.0), rate: float = 1000.0,
                library: TapLibrary | None = None, seed: int = 0, noise: float = 0.005, gap_s: float = 0.6,
                contact_s: float = 0.3) -> SyntheticRecording:
    """Taps at known incoming ``speeds`` (mm/s), rendered by ``tap_player`` from ``library``.

    The tool approaches along -z at the incoming speed, touches z = 0 (force
    rises as 0.5 N/mm of penetration, capped at 1 N), stays ``contact_s`` and
    lifts off; taps are ``gap_s`` + ``contact_s`` apart. ``truth``:
    ``library``, ``onsets`` (first sample with force above 0.1 N), ``speeds``.
    """
    try:
        values = np.asarray(plain(speeds), dtype=float)
    except (TypeError, ValueError):  # text, ragged lists: refused below as no list of speeds
        values = np.zeros(0)
    if values.ndim != 1 or not values.size or not np.all(np.isfinite(values) & (values > 0)):
        raise InputError(f"speeds must be a non-empty list of incoming speeds > 0 mm/s, got {excerpt(speeds)}")
    recording_ticks(gap_s + contact_s, rate, seed)
    lib = library if library is not None else synthetic_tap_library(sample_rate_hz=rate)
    rng = np.random.default_rng(seed)
    period = int(round((gap_s + contact_s) * rate))
    contact = int(round(contact_s * rate))
    n = period * len(speeds) + period // 2
    z = np.full(n, 5.0)
    in_contact = np.zeros(n)
    incoming = np.zeros(n)
    onsets = []
    for k, v in enumerate(speeds):
        t0 = period // 2 + k * period
        approach = np.arange(-int(0.2 * rate), 0)
        z[t0 + approach] = -v * approach / rate          # mm above the surface, reaching 0 at t0
        depth = np.minimum(v * np.arange(contact) / rate, 2.0)
        z[t0:t0 + contact] = -depth
        z[t0 + contact:t0 + contact + int(0.2 * rate)] = np.linspace(-depth[-1], 5.0, int(0.2 * rate))
        in_contact[t0 + 1:t0 + contact] = 1.0
        incoming[t0 + 1:t0 + contact] = v
        onsets.append(t0 + 1)
    force = np.minimum(np.maximum(-z, 0.0) * 0.5 + 0.0, 1.0)
    out = run_graph(TAP_GRAPH, rate, {"taps.library": lib}, {"in_contact": in_contact, "incoming_speed": incoming}, seed)
    accel = np.asarray(out["accel"], float).reshape(-1)
    accel = accel + noise * float(np.max(np.abs(accel))) * rng.standard_normal(n)
    force = force + 0.005 * rng.standard_normal(n)
    position = np.column_stack([np.zeros(n), np.zeros(n), z])
    arrays = {"accel": accel, "normal_force": force, "position": position, "normal": np.tile([0.0, 0.0, 1.0], (n, 1))}
    return SyntheticRecording(arrays, rate, {"library": lib, "onsets": np.array(onsets), "speeds": np.array(speeds, float)})


def friction_session(mu: float = 0.4, duration_s: float = 20.0, rate: float = 1000.0, seed: int = 0, noise: float = 0.1,
                     offset: float = 0.0, spikes: int = 20, lifts: int = 4) -> SyntheticRecording:
    """Dragging at 150 mm/s with a varying normal force (0.3..3 N); friction from ``coulomb_friction`` (mu).

    Measured tangential force = |friction| + ``offset`` (N), with ``noise``
    relative Gaussian noise (and 0.01 N sensor noise on both forces: noise on
    the normal force as large as 10 % would bias any slope low, errors in
    variables); ``spikes`` stiction spikes (50 ms
    at 2.5 x the kinetic force, at motion restarts after ``lifts`` lift-offs
    and at random times); ``lifts`` lift-offs of 0.5 s (normal force ~ 0, the
    tangential force sensor noise only). ``force`` is the (n, 3)
    measured force vector: tangential along x, normal along +z.
    """
    n, rate = recording_ticks(duration_s, rate, seed)
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate
    fn = 1.65 + 1.35 * np.sin(2 * np.pi * 0.23 * t) * np.cos(2 * np.pi * 0.07 * t + 0.5)
    velocity = np.column_stack([np.full(n, 150.0), np.zeros(n), np.zeros(n)])
    lift_len = int(0.5 * rate)
    starts = np.sort(rng.choice(np.arange(lift_len, n - 2 * lift_len), size=lifts, replace=False)) if lifts else np.zeros(0, int)
    for s in starts:
        fn[s:s + lift_len] = 0.0
        velocity[s:s + lift_len] = 0.0
    out = run_graph(FRICTION_GRAPH, rate, {"friction.mu": float(mu)}, {"velocity": velocity, "normal_force": fn}, seed)
    ft = np.linalg.norm(np.asarray(out["friction_force"], float), axis=1)
    spike_at = list(starts + lift_len) + list(rng.integers(0, n - 60, size=max(0, spikes - len(starts))))
    spike_len = int(0.05 * rate)
    for s in spike_at:
        ft[s:s + spike_len] *= 2.5
    in_contact = fn > 0
    ft = ft + offset * in_contact
    fn_meas = fn + 0.01 * rng.standard_normal(n)
    ft_meas = ft * (1 + noise * rng.standard_normal(n)) + 0.01 * rng.standard_normal(n)
    force = np.column_stack([ft_meas, np.zeros(n), fn_meas])
    arrays = {"normal_force": fn_meas, "tangential_force": ft_meas, "force": force, "normal": np.tile([0.0, 0.0, 1.0], (n, 1)),
              "velocity": velocity}
    return SyntheticRecording(arrays, rate, {"mu": float(mu), "offset": float(offset), "spikes": np.array(spike_at),
                                             "lifts": starts})
