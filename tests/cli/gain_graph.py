"""The smallest graph the command-line tests run: y = 2 x (one gain node, 1 kHz)."""

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
