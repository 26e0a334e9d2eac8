"""ARMA texture-vibration synthesis node: arma_synth."""

from __future__ import annotations

from numba import njit

from ..dsp.arma import ISTATE, STATE, arma_lattice_block, new_state
from ..dsp.rng import seed_rng
from ..node_api import Memory, Node, NodeState, Port, PortSpec, check


@njit(cache=True)
def _arma_synth(p, s, si, ar, ma, gain, variance, y):
    arma_lattice_block(s, si, ar, ma, gain, variance, y)


class ArmaSynth(Node):
    """ARMA vibration synthesis y = g C(z)/A(z) e, e ~ N(0, variance), with a per-tick model (normalized lattice-ladder).

    Each tick takes the model on its inputs (HaTT's convention: ``ar`` = [1, a1..ap]
    of A(z), ``ma`` = [1, c1..cq] of C(z), MA ``gain`` g, excitation ``variance``)
    and outputs one sample of y_n = -sum a_i y_{n-i} + g (e_n + sum c_j e_{n-j}) in
    m/s^2. The model is used on the tick it arrives (no smoothing); the Gray-Markel
    normalized lattice keeps the output bounded for any sequence of valid models,
    where a direct-form filter can burst when models change every tick.
    An invalid model (NaN/inf anywhere, not minimum phase, |reflection coefficient|
    > 1 - 1e-12, negative variance) is ignored and the last valid model is held;
    the output is 0 until the first valid model arrives. The orders p and q come
    from the shapes of the connected ``ar`` and ``ma`` (e.g. a texture_lookup).
    Random: seeded per graph and node.
    """

    type_name = "arma_synth"
    uses_seed = True
    inputs = {
        "ar": Port(None, "", "AR polynomial [1, a1, ..., ap] of A(z) (vector of p+1)"),
        "ma": Port(None, "", "MA polynomial [1, c1, ..., cq] of C(z) (vector of q+1)"),
        "gain": Port((), "", "MA gain g"),
        "variance": Port((), "", "variance of the white Gaussian excitation (>= 0)"),
    }
    outputs = {"y": Port((), "m/s^2", "synthesized vibration (acceleration)")}
    kernel = _arma_synth
    memory = Memory(state=STATE, istate=ISTATE)

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        for name in ("ar", "ma"):
            shape = inputs[name].shape
            check(len(shape) == 1 and shape[0] >= 1, None,
                  f"input {name} must be a vector [1, x1, ..., xn] of at least one value, got shape {shape or 'scalar'}"
                  f" (a one-value polynomial from a constant needs 'vector: true')")
        return {"y": PortSpec((), "m/s^2")}

    def build(self, inputs: dict[str, PortSpec], outputs: dict[str, PortSpec]) -> NodeState:
        p = inputs["ar"].shape[0] - 1
        q = inputs["ma"].shape[0] - 1
        s, si = new_state(p, q)
        return self.pack_state({"p": p, "q": q}, state=s, istate=si)

    def seed_state(self, state, istate, seed) -> None:
        seed_rng(istate[ISTATE.bind()["rng"]], state[STATE.bind(p=0, q=0)["rng"]], seed)
