"""Example plugin: a smooth saturation for actuator commands.

Put a file like this in a folder a graph names (its own plugins/ folder, its
`plugins:` key, --plugins DIR or $FLOWTEX_PLUGINS) and its node types appear in
graphs and in `flowtex nodes --plugins DIR`.
It uses exactly the API the built-in nodes use: declared params and ports,
build-time Python, and a numba kernel that loops over a block of ticks.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from flowtex.node_api import Node, NodeState, Param, Port


@njit(cache=True)
def soft_clip_kernel(p, s, si, x, y):
    limit = p[0]
    for t in range(x.shape[0]):
        for c in range(x.shape[1]):
            y[t, c] = limit * np.tanh(x[t, c] / limit)


class SoftClip(Node):
    """Smooth saturation y = limit * tanh(x / limit): linear for small x, never beyond ±limit."""

    type_name = "soft_clip"
    params = {"limit": Param("float", doc="output magnitude never exceeded (unit of x)", min=0.0, min_exclusive=True)}
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "saturated signal")}
    kernel = soft_clip_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["limit"]]))
