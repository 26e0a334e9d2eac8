"""surface_switch: crossfade between two signals chosen by an index input (run-time surface selection)."""

from __future__ import annotations

from numba import njit

from ..dsp.switch import PARAMS, STATE, crossfade_block, switch_params
from ..node_api import Memory, Node, NodeState, Param, Port, PortSpec, check


@njit(cache=True)
def _switch(p, s, si, index, a, b, y):
    crossfade_block(p, s, index, a, b, y)


class SurfaceSwitch(Node):
    """y = b while round(index) == b_index, a while it is smaller; a change crossfades linearly over ``fade`` seconds.

    A chain of these picks one of N surfaces' outputs (``flowtex scene plan``
    writes one per surface after the first). Every surface's nodes keep running
    while inactive, so a newly chosen surface has current state (no stale
    friction spring, no filter start-up burst), and the crossfade is a convex
    mix: the output never exceeds the larger of its two inputs. An index above
    b_index (a later switch of the chain has that surface) holds the current
    mix, so a change between any two surfaces of a chain crossfades exactly
    those two (flowtex/dsp/switch.py). NaN or negative index keeps the current
    choice. Starts on ``a``.
    """

    type_name = "surface_switch"
    params = {
        "b_index": Param("int", min=0, doc="index value that selects input b"),
        "fade": Param("float", default=0.01, unit="s", min=0.0, doc="crossfade duration (0: switch on the tick)"),
    }
    inputs = {
        "index": Port((), "", "active surface index (file order in a scene)"),
        "a": Port(None, "*", "signal used when index != b_index"),
        "b": Port("=a", "=a", "signal used when index == b_index"),
    }
    outputs = {"y": Port("=a", "=a", "crossfaded selection")}
    kernel = _switch
    memory = Memory(params=PARAMS, state=STATE)

    def resolve(self, inputs):
        a, b = inputs["a"], inputs["b"]
        check(b.shape == a.shape, None, f"inputs a and b must have the same shape, got {a.shape} and {b.shape}")
        return {"y": PortSpec(a.shape, a.unit)}

    def build(self, inputs, outputs):
        return NodeState(params=switch_params(self.p["b_index"], self.p["fade"] * self.context.node_rate), state=STATE.zeros())
