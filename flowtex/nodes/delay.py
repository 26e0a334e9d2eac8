"""The delay node z^-k, the only way to close a feedback loop."""

from __future__ import annotations

from numba import njit

from ..node_api import Field, Layout, Memory, Node, Param, Port

DELAY = Memory(state=Layout("float", [Field("ring", "k * w", "k rows of w values, oldest at row pos")], sizes=("k", "w")),
               istate=Layout("int", [Field("pos", 1, "row of the oldest value"),
                                     Field("rows", 1, "k: rows of the ring (the delay in ticks)")]))
S_RING = DELAY.state.const("ring")
SI_POS = DELAY.istate.const("pos")
SI_ROWS = DELAY.istate.const("rows")


@njit(cache=True)
def _delay(p, s, si, x, y):
    w = x.shape[1]
    k = si[SI_ROWS]
    pos = si[SI_POS]
    for t in range(x.shape[0]):
        base = S_RING + pos * w
        for c in range(w):
            y[t, c] = s[base + c]
            s[base + c] = x[t, c]
        pos += 1
        if pos == k:
            pos = 0
    si[SI_POS] = pos


@njit(cache=True)
def _emit(p, s, si, y):
    w = y.shape[1]
    base = S_RING + si[SI_POS] * w
    for c in range(w):
        y[0, c] = s[base + c]


@njit(cache=True)
def _absorb(p, s, si, x):
    w = x.shape[1]
    k = si[SI_ROWS]
    base = S_RING + si[SI_POS] * w
    for c in range(w):
        s[base + c] = x[0, c]
    pos = si[SI_POS] + 1
    si[SI_POS] = 0 if pos == k else pos


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
    memory = DELAY

    def build(self, inputs, outputs):
        return self.pack_state({"k": self.p["samples"], "w": inputs["x"].width}, istate={"rows": self.p["samples"]})
