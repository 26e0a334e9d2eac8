"""White Gaussian noise, seeded per graph and node."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..dsp.rng import STATE_FLOATS, STATE_INTS, next_normal, seed_rng
from ..node_api import Field, Layout, Memory, Node, Param, Port, PortSpec

NOISE = Memory(state=Layout("float", [Field("rng", STATE_FLOATS, "cached normal of the random generator")]),
               istate=Layout("int", [Field("rng", STATE_INTS, "random generator words (flowtex.dsp.rng)")]))
"""next_normal reads s and si whole: the generator is their only field."""


@njit(cache=True)
def _white_noise(p, s, si, variance, y):
    for t in range(y.shape[0]):
        var = variance[t, 0]
        z = next_normal(si, s)
        y[t, 0] = np.sqrt(var) * z if var > 0.0 else 0.0


class WhiteNoise(Node):
    """Seeded white Gaussian noise with the given variance (parameter, or input when connected)."""

    type_name = "white_noise"
    uses_seed = True
    params = {
        "variance": Param("float", default=1.0, min=0.0, doc="variance when the variance input is not connected"),
        "unit": Param("str", default="-", doc="unit of y ('-' for dimensionless)"),
    }
    inputs = {"variance": Port((), "*", "variance per tick; overrides the parameter when connected", optional=True)}
    outputs = {"y": Port((), "", "noise sample", unit_doc="the 'unit' parameter")}
    kernel = _white_noise
    memory = NOISE

    def resolve(self, inputs):
        return {"y": PortSpec((), "" if self.p["unit"] == "-" else self.p["unit"])}

    def input_default(self, name, spec):
        return np.full(spec.width, self.p["variance"])

    def seed_state(self, state, istate, seed):
        seed_rng(istate, state, seed)
