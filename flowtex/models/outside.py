"""What a texture model set renders outside its measured models: below the slowest and above the fastest fitted speed.

A set's measured models cover the speeds and forces its recording held long
enough to fit; its silent corner models (variance 0 at speed 0 and at force 0,
HaTT's convention) make the vibration vanish when the tool stops or lifts.
Between the slowest measured model and speed 0 (and between the lightest one
and force 0) the lookup's rule decides the loudness (``texture_lookup``'s
``outside`` parameter, docs/texture.md):

* ``trend``: the spectral shape of the nearest measured models, with
  the power following the set's own power law in speed and force,
  P ~ speed^ks force^kf, fitted by least squares to the measured models'
  output powers (log P on log speed and log force). Below the slowest speed
  the vibration still fades towards 0 at speed 0 (as speed^ks) and is silent
  at rest and without contact (below low_speed / low_force, for every
  exponent); above the fastest
  it keeps growing, up to ``TREND_CAP`` x the fastest speed (heaviest force).
  Exponents are clipped to [0, ``MAX_EXPONENT``] (a surface never gets louder
  as the tool slows or lightens); an axis without spread (all models at one
  force, say) gets exponent 1, the linear fade of HaTT's corners;
* ``hold``: the nearest measured models as they are (no fade, no growth),
  silent at rest and without contact (below low_speed / low_force);
* ``fade`` (HaTT's renderer, part of HaTT's rule): silent corners blended like any model, so the
  variance falls linearly from the slowest measured model to 0 at speed 0;
  above the fastest speed (heaviest force) the edge models are held.

Inside the triangles of measured models the three rules agree exactly.
"""

from __future__ import annotations

import numpy as np

from ..dsp.powerlaw import fit_power_law, power_law_design
from .texture import OUTSIDE_CHOICES, TextureModelSet

__all__ = ["MAX_EXPONENT", "OUTSIDE_CHOICES", "TREND_CAP", "model_powers", "nearest_measured", "power_trend"]

TREND_CAP = 4.0
"""``trend`` extrapolates the power law up to this many times the speed (force) of the models blended."""
MAX_EXPONENT = 3.0
"""Largest power-law exponent ``trend`` uses."""


def model_powers(ms: TextureModelSet) -> np.ndarray:
    """(M,) output power g^2 sigma^2 ||C/A||^2 of each model ((m/s^2)^2), from its LSFs as the lookup renders them."""
    from ..dsp.interp import model_output_powers

    return model_output_powers(ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain)


def nearest_measured(ms: TextureModelSet) -> np.ndarray:
    """(M,) index of the measured model (variance > 0) nearest to each model in units of (max speed, max force); itself if measured."""
    measured = np.flatnonzero(ms.variance > 0)
    if measured.size == 0:
        return np.arange(ms.num_models)
    pts = ms.points() / np.array([ms.max_speed, ms.max_force])
    d = np.sum((pts[:, None, :] - pts[None, measured, :]) ** 2, axis=2)
    src = measured[np.argmin(d, axis=1)]
    src[measured] = measured
    return src


def power_trend(ms: TextureModelSet) -> tuple[float, float]:
    """(ks, kf): exponents of P ~ speed^ks force^kf over the measured models (module docstring for clipping and defaults)."""
    power = model_powers(ms)
    use = (power > 0) & (ms.speeds > 0) & (ms.forces > 0)
    k = [1.0, 1.0]
    if np.count_nonzero(use) < 2:
        return k[0], k[1]
    full = power_law_design(ms.speeds[use], ms.forces[use])
    spread = [np.ptp(full[:, 1 + axis]) > 1e-6 for axis in range(2)]
    design = full[:, [0] + [1 + axis for axis in range(2) if spread[axis]]]
    if design.shape[1] == 1 or np.linalg.matrix_rank(design) < design.shape[1]:
        return k[0], k[1]
    coef = fit_power_law(design, power[use])[1:]
    it = iter(coef)
    for axis, ok in enumerate(spread):
        if ok:
            k[axis] = float(np.clip(next(it), 0.0, MAX_EXPONENT))
    return k[0], k[1]
