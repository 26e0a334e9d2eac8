"""How a texture model set renders: its rule, stated in the set, resolved in this one place.

A rule has two parts (docs/texture.md):

* ``interpolation`` -- how loudness is blended between the three models of a
  triangle: ``variance`` (HaTT's: the excitation variance, linearly),
  ``power`` (the models' output power, linearly, the variance then set so the
  blended filter has that power) or ``log_power`` (the output power,
  geometrically). The spectral shape is always blended by LSFs;
* ``outside`` -- what the set renders below its slowest and above its fastest
  measured models: ``fade`` (HaTT's), ``hold`` or ``trend``
  (flowtex.models.outside).

Where a rule comes from, first found wins: the ``texture_lookup`` node's
parameters, then the rule the model set records (a native JSON set written
by ``fit texture`` states one; ``models resample`` carries it over), then
HaTT's rule (:data:`HATT_RULE`), so a HaTT XML file and any set that states
nothing render exactly as HaTT does. :func:`resolve_rule` is that order and
:func:`texture_table` packs a set with it: the lookup node, the fit quality
figures, scene salience and the planner's graphs all go through them.
"""

from __future__ import annotations

import numpy as np

from .texture import HATT_RULE, INTERPOLATION_CHOICES, RenderRule, TextureModelSet

__all__ = ["FITTED_RULE", "HATT_RULE", "INTERPOLATION_CHOICES", "RenderRule", "resolve_rule", "texture_table"]

FITTED_RULE = RenderRule("power", "trend")
"""The rule ``fit texture`` records in the sets it writes (docs/fitting.md: why power and trend)."""


def resolve_rule(ms: TextureModelSet, interpolation: str | None = None, outside: str | None = None) -> RenderRule:
    """The rule ``ms`` renders with: each part from the arguments (node parameters) when given, else the set's, else HaTT's."""
    own = ms.rule or HATT_RULE
    return RenderRule(interpolation or own.interpolation, outside or own.outside)


def texture_table(ms: TextureModelSet, interpolation: str | None = None, outside: str | None = None, **clamp: float) -> np.ndarray:
    """The packed lookup table (flowtex.dsp.interp.pack_texture_table) of ``ms`` under :func:`resolve_rule`.

    ``clamp``: the clamping keywords of ``pack_texture_table`` (speed_margin, low_speed, ...).
    Raises ValueError for an unknown rule or a model without a usable filter.
    """
    from ..dsp.interp import pack_texture_table
    from .outside import TREND_CAP, nearest_measured, power_trend

    rule = resolve_rule(ms, interpolation, outside)
    trend = power_trend(ms) if rule.outside == "trend" else (1.0, 1.0)
    return pack_texture_table(ms.speeds, ms.forces, ms.triangles, ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, ms.max_speed,
                              ms.max_force, outside=rule.outside, src=nearest_measured(ms), trend=trend, trend_cap=TREND_CAP,
                              interpolation=rule.interpolation, **clamp)
