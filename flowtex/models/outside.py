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
  the vibration still fades to 0 at speed 0 (as speed^ks); above the fastest
  it keeps growing, up to ``TREND_CAP`` x the fastest speed (heaviest force).
  Exponents are clipped to [0, ``MAX_EXPONENT``] (a surface never gets louder
  as the tool slows or lightens); an axis without spread (all models at one
  force, say) gets exponent 1, the linear fade of HaTT's corners;
* ``hold``: the nearest measured models as they are (no fade, no growth):
  silence when the tool stops must then come from elsewhere (the example
  graphs multiply by the contact state, and the speed estimator's gate);
* ``fade`` (default: HaTT's renderer, so HaTT files render as HaTT does): silent corners blended like any model, so the
  variance falls linearly from the slowest measured model to 0 at speed 0;
  above the fastest speed (heaviest force) the edge models are held.

Inside the triangles of measured models the three rules agree exactly.
"""

from __future__ import annotations

import numpy as np

from .texture import TextureModelSet

OUTSIDE_CHOICES = ("fade", "hold", "trend")
"""Values of ``texture_lookup``'s ``outside`` parameter; the first is the default."""
TREND_CAP = 4.0
"""``trend`` extrapolates the power law up to this many times the speed (force) of the models blended."""
MAX_EXPONENT = 3.0
"""Largest power-law exponent ``trend`` uses."""
POWER_GRID = 1 << 14
"""Points on the unit circle for a model's output power (mean of |C/A|^2; exact to rounding for poles inside 0.9995)."""


def model_powers(ms: TextureModelSet) -> np.ndarray:
    """(M,) output power g^2 sigma^2 ||C/A||^2 of each model ((m/s^2)^2), from its LSFs as the lookup renders them."""
    from ..dsp.lsf import lsf_to_poly_new

    out = np.zeros(ms.num_models)
    for m in range(ms.num_models):
        if ms.variance[m] <= 0.0:
            continue
        h2 = np.abs(np.fft.rfft(lsf_to_poly_new(ms.ma_lsf[m]), POWER_GRID) / np.fft.rfft(lsf_to_poly_new(ms.ar_lsf[m]), POWER_GRID)) ** 2
        unit = (h2[0] + h2[-1] + 2.0 * np.sum(h2[1:-1])) / POWER_GRID     # mean over the whole circle
        out[m] = ms.gain[m] ** 2 * ms.variance[m] * unit
    return out


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
    cols = [np.log(ms.speeds[use]), np.log(ms.forces[use])]
    spread = [np.ptp(c) > 1e-6 for c in cols]
    design = np.column_stack([np.ones(np.count_nonzero(use))] + [c for c, ok in zip(cols, spread, strict=True) if ok])
    if design.shape[1] == 1 or np.linalg.matrix_rank(design) < design.shape[1]:
        return k[0], k[1]
    coef = np.linalg.lstsq(design, np.log(power[use]), rcond=None)[0][1:]
    it = iter(coef)
    for axis, ok in enumerate(spread):
        if ok:
            k[axis] = float(np.clip(next(it), 0.0, MAX_EXPONENT))
    return k[0], k[1]


def texture_table(ms: TextureModelSet, outside: str = OUTSIDE_CHOICES[0], **clamp: float) -> np.ndarray:
    """The packed lookup table (flowtex.dsp.interp.pack_texture_table) of ``ms`` with the rule ``outside``.

    ``clamp``: the clamping keywords of ``pack_texture_table`` (speed_margin, low_speed, ...).
    """
    from ..dsp.interp import pack_texture_table

    if outside not in OUTSIDE_CHOICES:
        raise ValueError(f"outside must be one of {', '.join(OUTSIDE_CHOICES)}, got {outside!r}")
    trend = power_trend(ms) if outside == "trend" else (1.0, 1.0)
    return pack_texture_table(ms.speeds, ms.forces, ms.triangles, ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, ms.max_speed,
                              ms.max_force, outside=outside, src=nearest_measured(ms), trend=trend, trend_cap=TREND_CAP,
                              **clamp)
