"""The graph a texture model set renders through: ``texture_lookup`` + ``arma_synth`` along (speed, force).

fit renders a surface with it (:func:`flowtex.fit.compare.render_along`) and
:mod:`flowtex.datasets` makes ground-truth recordings with it, so a fitted
surface is judged by exactly the nodes that render it. The model file is given
as an override (``lookup.models=...``); the rate is formatted in.
"""

from __future__ import annotations

TEXTURE_GRAPH = """
flowtex: 1
name: dataset-texture
rate: {rate}
seed: 1
inputs:
  speed: {{unit: mm/s}}
  force: {{unit: N}}
nodes:
  lookup: {{type: texture_lookup, params: {{models: set.json}}}}
  synth: {{type: arma_synth}}
edges:
  - speed -> lookup.speed
  - force -> lookup.force
  - lookup.ar -> synth.ar
  - lookup.ma -> synth.ma
  - lookup.gain -> synth.gain
  - lookup.variance -> synth.variance
outputs:
  accel: synth.y
"""
"""Vibration (m/s^2) of a model set along a (speed, force) trajectory."""
