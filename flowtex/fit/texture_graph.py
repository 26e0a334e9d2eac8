"""The graph a texture model set renders through: ``texture_lookup`` + ``arma_synth`` along (speed, force).

fit renders a surface with it (:func:`flowtex.fit.compare.render_along`) and
:mod:`flowtex.datasets` makes ground-truth recordings with it, so a fitted
surface is judged by exactly the nodes that render it. Both build it in Python
with the loaded model set (:func:`texture_builder`, nothing written to disk);
:data:`TEXTURE_GRAPH` is the same graph as YAML text (the model file given as an
override ``lookup.models=...``, the rate formatted in), kept equal to it by
tests/fit/test_texture_graph_builder.py.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..graph.builder import GraphBuilder
    from ..models.texture import TextureModelSet

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


def texture_builder(models: TextureModelSet | str | Path, rate: float, lookup: Mapping[str, Any] | None = None) -> GraphBuilder:
    """:data:`TEXTURE_GRAPH` built in Python (flowtex.graph.builder): ``models`` a loaded set or its file, ``rate`` in
    Hz, ``lookup`` more ``texture_lookup`` parameters; nothing is written to disk. Same nodes, edges and seed as the
    YAML (tests/fit/test_texture_graph_builder.py checks the two specs are equal)."""
    from ..graph.builder import GraphBuilder

    return (GraphBuilder("dataset-texture", rate=rate, seed=1)
            .input("speed", unit="mm/s").input("force", unit="N")
            .node("lookup", "texture_lookup", models=models, **dict(lookup or {}))
            .node("synth", "arma_synth")
            .edge("speed -> lookup.speed").edge("force -> lookup.force")
            .edge("lookup.ar -> synth.ar").edge("lookup.ma -> synth.ma")
            .edge("lookup.gain -> synth.gain").edge("lookup.variance -> synth.variance")
            .output("accel", "synth.y"))
