"""The delay node z^-k, the only way to close a feedback loop."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..node_api import Node, NodeState, Param, Port


@njit(cache=True)
def _delay(p, s, si, x, y):
    # s: ring of k rows x w values; si[0]: index of the oldest row.
    w = x.shape[1]
    k = s.shape[0] // w
    pos = si[0]
    for t in range(x.shape[0]):
        base = pos * w
        for c in range(w):
            y[t, c] = s[base + c]
            s[base + c] = x[t, c]
        pos += 1
        if pos == k:
            pos = 0
    si[0] = pos


@njit(cache=True)
def _emit(p, s, si, y):
    w = y.shape[1]
    base = si[0] * w
    for c in range(w):
        y[0, c] = s[base + c]


@njit(cache=True)
def _absorb(p, s, si, x):
    w = x.shape[1]
    k = s.shape[0] // w
    base = si[0] * w
    for c in range(w):
        s[base + c] = x[0, c]
    pos = si[0] + 1
    si[0] = 0 if pos == k else pos


MAX_SAMPLES = 10_000_000
"""Longest delay in ticks (80 MB of state per component; 2.8 hours at 1 kHz)."""


class Delay(Node):
    """Delay by a whole number of ticks: y[t] = x[t - samples] (zeros before the start)."""

    type_name = "delay"
    breaks_cycles = True
    params = {"samples": Param("int", default=1, doc="delay in ticks of this node", min=1, max=MAX_SAMPLES)}
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "delayed signal")}
    kernel = _delay
    emit_kernel = _emit
    absorb_kernel = _absorb

    def build(self, inputs, outputs):
        return NodeState(state=np.zeros(self.p["samples"] * inputs["x"].width), istate=np.zeros(1, np.int64))
