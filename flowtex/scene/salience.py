"""Physical figures that say how much a surface component matters (Culbertson & Kuchenbecker 2017 sec. 5-6,).

* texture: mean vibration power, (m/s^2)^2, of the interpolated texture model
  over a grid of (speed, force) points -- the model the ``texture_lookup`` node
  would render at each point (the same packed table,
  flowtex.models.rendering.texture_table: the set's own rule, clamping and LSF
  blending), its stationary output variance from
  :func:`flowtex.dsp.arma.arma_output_variance`;
* friction: the kinetic friction coefficient itself (no computation);
* taps: the tap spectral centroid, :func:`flowtex.models.taps.spectral_centroid`.

Also the representative speed/force ranges of a recorded trajectory.
"""

from __future__ import annotations

import numpy as np

from ..dsp.arma import arma_output_variance
from ..dsp.contact import CONTACT_ON_N
from ..dsp.interp import S_AR, S_GAIN, S_VAR, initial_state, lookup_model
from ..models.rendering import texture_table
from ..models.texture import TextureModelSet

GRID_POINTS = 9
"""Grid size per axis for texture salience (9 x 9)."""


def texture_power_grid(ms: TextureModelSet, speeds_mm_s: np.ndarray, forces_n: np.ndarray) -> np.ndarray:
    """Vibration power (m/s^2)^2 of the looked-up model at every (speed, force) pair: shape (len(speeds), len(forces)).

    The set renders with its own rule, as the planner's graphs (which give ``texture_lookup`` only the file) render it.
    """
    tab = texture_table(ms)
    p, q = ms.ar_order, ms.ma_order
    s, si = initial_state(p, q)
    out = np.empty((len(speeds_mm_s), len(forces_n)))
    for i, v in enumerate(np.asarray(speeds_mm_s, dtype=np.float64)):
        for j, f in enumerate(np.asarray(forces_n, dtype=np.float64)):
            lookup_model(tab, s, si, float(v), float(f))
            ar = s[S_AR:S_AR + p + 1].copy()
            ma = s[S_AR + p + 1:S_AR + p + q + 2].copy()
            out[i, j] = arma_output_variance(ar, ma, s[S_GAIN], s[S_VAR]) if s[S_VAR] > 0 else 0.0
    return out


def mean_texture_power(ms: TextureModelSet, speed_range_mm_s: tuple[float, float], force_range_n: tuple[float, float],
                       points: int = GRID_POINTS) -> float:
    """Mean of :func:`texture_power_grid` over a ``points`` x ``points`` grid spanning the ranges, in (m/s^2)^2."""
    speeds = np.linspace(speed_range_mm_s[0], speed_range_mm_s[1], points)
    forces = np.linspace(force_range_n[0], force_range_n[1], points)
    return float(texture_power_grid(ms, speeds, forces).mean())


def trajectory_ranges(position_mm: np.ndarray, normal_force_n: np.ndarray, rate_hz: float, normal: np.ndarray | None = None,
                      contact_n: float = CONTACT_ON_N,
                      quantiles: tuple[float, float] = (0.05, 0.95)) -> tuple[tuple[float, float], tuple[float, float]]:
    """(speed range mm/s, force range N) of a recorded stroke: the 5th-95th percentiles while in contact.

    Speed is the finite-difference speed of ``position_mm`` (n, 3) with the
    component along ``normal`` (n, 3) removed when given. Samples with normal
    force below ``contact_n`` are out of contact and ignored. Raises
    ValueError when fewer than 10 samples are in contact.
    """
    pos = np.asarray(position_mm, dtype=np.float64).reshape(-1, 3)
    force = np.asarray(normal_force_n, dtype=np.float64).ravel()
    vel = np.diff(pos, axis=0) * rate_hz
    if normal is not None:
        nrm = np.asarray(normal, dtype=np.float64).reshape(-1, 3)[1:]
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        unit = np.divide(nrm, length, out=np.zeros_like(nrm), where=length > 0)
        vel = vel - np.sum(vel * unit, axis=1, keepdims=True) * unit
    speed = np.linalg.norm(vel, axis=1)
    touching = force[1:] >= contact_n
    ok = touching & np.isfinite(speed) & np.isfinite(force[1:])
    if ok.sum() < 10:
        raise ValueError(f"fewer than 10 samples in contact (normal_force >= {contact_n:g} N)")
    s_lo, s_hi = np.quantile(speed[ok], quantiles)
    f_lo, f_hi = np.quantile(force[1:][ok], quantiles)
    return (float(s_lo), float(s_hi)), (float(f_lo), float(f_hi))
