"""Pieces pooled with their neighbours in (speed, force): the data each model of a free-exploration fit is fitted on.

Why: a piece of free exploration is a fraction of a second long, and real
surfaces wander in loudness from second to second at the same speed and
force, so a model fitted on one piece carries that piece's
loudness and its noise: fitted piece by piece, neighbouring models differ in
level by several dB where the surface does not, and the interpolated render
jumps between them. Each model is therefore fitted on its own piece together
with the pieces nearest to it in (ln speed, ln force), each axis scaled by the
pieces' spread on it (an axis that does not vary is left out).

Why the data and not only the level: scaling each piece's model to a smoothed
power (a local regression of log power over speed and force) boosts the
pieces that happened to be quiet, and their spectra carry the sensor's noise
floor at its absolute level, so the boost lifts a floor the recording does
not have (docs/fitting.md, "Pooling neighbouring pieces"). Fitting on the
pooled samples averages the spectra in power, as the recording does: loud
pieces weigh as much as their energy, the noise floor stays where it is, and
the level is an arithmetic mean of powers (no log-mean bias).

A group's mean power belongs to the group's centre, not to the piece it
models (at the edge of the explored range every neighbour lies inward):
:func:`trend_factors` moves it to the piece's own point along the pieces'
power law in speed and force.

The pooled pieces are joined end to end for the ARMA estimator. The recording
was high-passed whole before it was cut, so a joint makes no filter
transient; what it costs is one wrong prediction at each joint, which decays
within the resonances' time constant (tens of ms against 0.3 s pieces).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..dsp.powerlaw import fit_power_law, power_law_design


def neighbour_groups(speeds: Sequence[float], forces: Sequence[float], count: int) -> list[np.ndarray]:
    """For each point (speed mm/s, force N), the indices of the ``count`` points nearest to it (itself first),
    in (ln speed, ln force) scaled by the points' standard deviation on each axis. ``count`` <= 1: each alone.

    A KD-tree (scipy.spatial.cKDTree): memory and time grow as n log n with the number of pieces, not n^2.
    """
    from scipy.spatial import cKDTree

    n = len(speeds)
    k = max(1, min(int(count), n))
    if k == 1:
        return [np.array([i]) for i in range(n)]
    x = np.log(np.column_stack([np.asarray(speeds, float), np.asarray(forces, float)]))
    spread = x.std(axis=0)
    x = x[:, spread > 1e-12] / spread[spread > 1e-12]
    if x.shape[1] == 0:                                    # every piece at one point: all equally near
        x = np.zeros((n, 1))
    _dist, idx = cKDTree(x).query(x, k=k)
    out = []
    for i, row in enumerate(np.asarray(idx).reshape(n, k)):
        rest = [int(j) for j in row if j != i][:k - 1]     # itself first, even beside a duplicate point
        out.append(np.array([i, *rest]))
    return out


def pooled_data(data: Sequence[np.ndarray], group: np.ndarray) -> np.ndarray:
    """The samples of the pieces in ``group`` joined end to end, in recording order (module docstring)."""
    return np.concatenate([data[j] for j in sorted(int(j) for j in group)])


def trend_factors(speeds: Sequence[float], forces: Sequence[float], powers: Sequence[float], samples: Sequence[int],
                  groups: Sequence[np.ndarray]) -> np.ndarray:
    """Power factor per group that moves its pooled level from the group's pieces to its own piece's point.

    A model fitted on a group has the group's mean power, sum_j n_j P_j / sum_j n_j (``samples`` n_j, ``powers``
    P_j). Where the surface's power grows with speed and force, that mean belongs to the group's centre, not to
    the piece it models: at the edge of the explored range every neighbour lies inward and the model comes out too
    quiet (too loud where the power falls). A power law T = exp(b0 + b . (ln speed, ln force)), least squares in
    dB over the pieces weighted by their lengths, gives the factor T_i / (sum_j n_j T_j / sum_j n_j): a ratio of
    the trend alone, so neither the pieces' scatter nor the log-mean bias of a dB fit enters it.
    """
    w = np.asarray(samples, float)
    a = power_law_design(np.asarray(speeds, float), np.asarray(forces, float))
    coef = fit_power_law(a, powers, w)
    trend = np.exp(a @ coef - np.max(a @ coef))
    return np.array([trend[i] * np.sum(w[g]) / np.sum(w[g] * trend[g]) for i, g in enumerate(groups)])
