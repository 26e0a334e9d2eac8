"""The smallest graphs the command-line tests run: y = 2 x (one gain node, 1 kHz), and one the example device map binds."""

GAIN_GRAPH = """\
flowtex: 1
name: g
rate: 1000
inputs:
  x: {unit: N}
nodes:
  k: {type: gain, params: {k: 2}}
edges:
  - x -> k.x
outputs:
  y: k.y
"""

MAP_GRAPH = """\
flowtex: 1
name: mapped
rate: 1000
inputs:
  position: {shape: [3], unit: mm}
  normal_force: {unit: N}
nodes:
  k: {type: gain, params: {k: 0.01, unit: N}}
  v: {type: gain, params: {k: 0.25, unit: A}}
edges:
  - position -> k.x
  - normal_force -> v.x
outputs:
  force: k.y
  vibration: v.y
"""
"""The smallest graph graphs/devices/example_map.yaml binds (its inputs and outputs, two gain nodes): for tests of
what a replay or live session does with its inputs, where the graph's content is not the point."""
