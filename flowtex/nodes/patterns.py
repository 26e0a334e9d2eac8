"""patterned_texture: a sum of IIR ring-downs excited as the tool crosses recorded surface features (Guruswamy thesis ch. 4)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..dsp.patterns import ISTATE, PARAMS, RING_DECAY, STATE, pattern_block, pattern_params, pattern_state
from ..dsp.prony import ring_length
from ..errors import ParamError
from ..models.patterns import Pattern
from ..node_api import Memory, Node, Param, Port


@njit(cache=True)
def _pattern(p, s, si, position, in_contact, y):
    pattern_block(p, s, si, position, in_contact, y)


class PatternedTexture(Node):
    """Patterned texture vibration (m/s^2): crossing feature k, either way, excites filter k with amplitude A_k; ring-downs add.

    Amplitude does not depend on speed (Guruswamy thesis sec. 6.1 saw none): speed only sets how
    often features are crossed. A ring-down lasts until its slowest pole has
    decayed to 1e-6; at most ``max_active`` play at once (the oldest is replaced).
    docs/patterns.md.
    """

    type_name = "patterned_texture"
    params = {
        "pattern": Param("path", objects=(Pattern,), doc="pattern file (docs/pattern-format.md); relative to the graph file"),
        "max_active": Param("int", default=16, min=1, max=256, doc="most ring-downs playing at once"),
    }
    inputs = {
        "position": Port((3,), "mm", "tool position"),
        "in_contact": Port((), "", "contact state 0/1: features excite only in contact (unconnected: always)", optional=True, default=1.0),
    }
    outputs = {"y": Port((), "m/s^2", "texture vibration")}
    kernel = _pattern
    memory = Memory(params=PARAMS, state=STATE, istate=ISTATE)

    def build(self, inputs, outputs):
        pat: Pattern = self.p["pattern"]
        rate = self.context.node_rate
        if abs(pat.sample_rate_hz - rate) > 1e-9 * rate:
            where = self.context.files.get("pattern", "the pattern given in memory")
            raise ParamError("pattern", f"{where}: pattern filters are sampled at {pat.sample_rate_hz:g} Hz but this node runs at "
                             f"{rate:g} Hz; refit the pattern at {rate:g} Hz or run the node at the pattern's rate")
        b, a = pat.padded()
        lengths = [ring_length(bk, ak, RING_DECAY) for bk, ak in zip(pat.b, pat.a, strict=True)]
        slots = self.p["max_active"]
        s, si = pattern_state(b.shape[1] - 1, slots)
        params = pattern_params(pat.axis, pat.origin, pat.positions_mm, pat.amplitudes, np.asarray(lengths), b, a, slots)
        return self.pack_state({"k": b.shape[0], "order": b.shape[1] - 1, "slots": slots}, params=params, state=s, istate=si)
