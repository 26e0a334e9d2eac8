"""The flowtex graphs that render ground-truth tap transients and friction forces.

Each is an ordinary flowtex graph (YAML text, compiled like any graph file),
so that a dataset's tap transients and friction forces come from exactly the
nodes a fitted surface is later rendered with: ``tap_player`` and
``coulomb_friction``. Values are given as overrides, a tap library as the
loaded object (``taps.library``), so nothing is written to disk; the rate is
formatted in. The texture's vibration is
rendered by the one texture graph, :func:`flowtex.fit.texture_graph.texture_builder`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["FRICTION_GRAPH", "TAP_GRAPH", "run_graph"]

TAP_GRAPH = """
flowtex: 1
name: dataset-taps
rate: {rate}
seed: 1
inputs:
  in_contact: {{}}
  incoming_speed: {{unit: mm/s}}
nodes:
  taps: {{type: tap_player, params: {{library: taps.json, mass: 1.0}}}}
edges:
  - in_contact -> taps.in_contact
  - incoming_speed -> taps.incoming_speed
outputs:
  accel: taps.force
"""
"""Tap transients: with mass 1 kg the player's force in N is the acceleration in m/s^2."""

FRICTION_GRAPH = """
flowtex: 1
name: dataset-friction
rate: {rate}
seed: 1
inputs:
  velocity: {{shape: [3], unit: mm/s}}
  normal_force: {{unit: N}}
nodes:
  friction: {{type: coulomb_friction, params: {{mu: 0.5, mode: hatt}}}}
edges:
  - velocity -> friction.velocity
  - normal_force -> friction.normal_force
outputs:
  friction_force: friction.force
"""
"""Kinetic friction (HaTT's rule: Coulomb above mu / 0.004 mm/s) on the true velocity."""


def run_graph(template: str, rate: float, overrides: Mapping[str, Any], inputs: Mapping[str, Any], seed: int) -> dict:
    """Compile ``template`` at ``rate`` Hz with ``overrides`` and run it over ``inputs``; returns its outputs."""
    from ..graph.compiled import Graph
    from ..graph.resolve import resolve_graph
    from ..graph.spec import parse_spec
    from ..registry import load_registry

    spec = parse_spec(template.format(rate=float(rate)), Path("<flowtex.datasets>"), dict(overrides))
    graph = Graph(resolve_graph(spec, load_registry(())))
    return graph.run(inputs, seed=seed)
