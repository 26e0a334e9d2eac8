"""Friction recordings that behave like real tool-surface drags: noise that grows with force, heavy tails, stiction.

:func:`flowtex.datasets.friction_session` drags at one speed with lift-offs;
:func:`stiction_drag` records what a hand dragging a tool does (the speeds and
forces of six real tool-surface recordings, docs/fitting.md): speed
130-320 mm/s and normal force 0.3-4.3 N drifting slowly
(:func:`flowtex.datasets.resonant.bounded_path`), in contact throughout. The
kinetic friction comes from the ``coulomb_friction`` node (HaTT's rule,
Coulomb above mu / 0.004 mm/s, below the slowest speed for mu <= 0.52). On it:

* **noise that grows with the normal force**: standard deviation
  sqrt(``floor``^2 + (``relative`` mu N)^2) N, a sensor floor joining noise
  proportional to the friction force (heteroscedastic, as real tangential
  forces are);
* **heavy tails**: that noise is Student t with ``tail_dof`` degrees of
  freedom scaled to the standard deviation above (``inf``: Gaussian);
* **slow drift**: the kinetic force wanders by ``drift`` (relative RMS, low-pass
  at 1 Hz), as the friction of the other generated recordings does;
* **stiction spikes**: ``spikes`` stick-slip events at random times, each
  ``spike_s`` long (drawn uniformly) at ``spike_gain`` times the kinetic force
  (drawn uniformly), never overlapping.

Truth: ``mu``, ``spike_mask`` (bool per sample: inside a spike), ``spike_starts``,
``noise_sd`` (the noise's standard deviation per sample, N), ``tail_dof``, ``drift``.
Units: speed mm/s, force N.
"""

from __future__ import annotations

import numpy as np

from . import SyntheticRecording
from .graphs import FRICTION_GRAPH, run_graph
from .realistic import wander
from .resonant import FORCE_RANGE, SPEED_RANGE, bounded_path
from .trajectories import recording_ticks


def student_noise(n: int, rng: np.random.Generator, tail_dof: float) -> np.ndarray:
    """Unit-variance white noise: Student t with ``tail_dof`` (> 2) degrees of freedom, or Gaussian for inf."""
    if not np.isfinite(tail_dof):
        return rng.standard_normal(n)
    if tail_dof <= 2.0:
        raise ValueError(f"tail_dof {tail_dof:g}: a unit variance needs more than 2 degrees of freedom")
    return rng.standard_t(tail_dof, n) / np.sqrt(tail_dof / (tail_dof - 2.0))


def spike_starts(n: int, rng: np.random.Generator, count: int, lengths: np.ndarray) -> np.ndarray:
    """``count`` start samples for spikes of ``lengths`` samples inside 0..n, starts at least two of the longest
    spikes apart (so a spike is followed by at least one spike length of kinetic friction)."""
    starts: list[int] = []
    gap = 2 * int(lengths.max())
    for length in lengths[:count]:
        for _ in range(1000):
            s = int(rng.integers(0, n - int(length)))
            if all(abs(s - a) >= gap for a in starts):
                starts.append(s)
                break
        else:
            raise ValueError(f"{count} spikes do not fit into {n} samples")
    return np.array(starts, dtype=np.int64)


def stiction_drag(mu: float = 0.4, duration_s: float = 20.0, rate: float = 1000.0, seed: int = 0,
                  relative: float = 0.1, floor: float = 0.01, tail_dof: float = 5.0, drift: float = 0.05,
                  spikes: int = 20, spike_s: tuple[float, float] = (0.02, 0.08), spike_gain: tuple[float, float] = (2.0, 3.0),
                  speed_range: tuple[float, float] = SPEED_RANGE,
                  force_range: tuple[float, float] = FORCE_RANGE) -> SyntheticRecording:
    """A hand dragging a tool over a surface of friction ``mu``: see the module docstring.

    Signals: ``normal_force`` (N, with ``floor`` Gaussian sensor noise), ``tangential_force`` (N),
    ``force`` ((n, 3) N: tangential along x, normal along +z), ``normal`` (+z), ``velocity`` ((n, 3) mm/s, along x)
    and ``speed`` (mm/s).
    """
    n, rate = recording_ticks(duration_s, rate, seed)
    rng = np.random.default_rng(seed)
    speed, fn = bounded_path(n, rate, rng, speed_range, force_range)
    velocity = np.column_stack([speed, np.zeros(n), np.zeros(n)])
    out = run_graph(FRICTION_GRAPH, rate, {"friction.mu": float(mu)}, {"velocity": velocity, "normal_force": fn}, seed)
    kinetic = np.linalg.norm(np.asarray(out["friction_force"], float), axis=1)
    if drift:
        kinetic = kinetic * (1.0 + drift * wander(n, rate, rng, 1.0))
    lengths = np.round(rng.uniform(*spike_s, size=max(spikes, 1)) * rate).astype(np.int64)
    starts = spike_starts(n, rng, spikes, lengths) if spikes else np.zeros(0, np.int64)
    mask = np.zeros(n, bool)
    ft = kinetic.copy()
    for s, length in zip(starts, lengths[:spikes], strict=True):
        ft[s:s + length] *= rng.uniform(*spike_gain)
        mask[s:s + length] = True
    sd = np.sqrt(floor ** 2 + (relative * mu * fn) ** 2)
    ft_meas = ft + sd * student_noise(n, rng, tail_dof)
    fn_meas = fn + floor * rng.standard_normal(n)
    arrays = {"normal_force": fn_meas, "tangential_force": ft_meas, "force": np.column_stack([ft_meas, np.zeros(n), fn_meas]),
              "normal": np.tile([0.0, 0.0, 1.0], (n, 1)), "velocity": velocity, "speed": speed}
    truth = {"mu": float(mu), "spike_mask": mask, "spike_starts": np.sort(starts), "noise_sd": sd,
             "tail_dof": float(tail_dof), "drift": float(drift)}
    return SyntheticRecording(arrays, rate, truth)
