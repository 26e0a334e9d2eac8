"""More first-plugin mistakes, one node type each (tests/test_plugin_mistakes_more.py runs plugin check over them)."""

import numpy as np
from numba import njit

from flowtex.node_api import Field, Layout, Memory, Node, NodeState, Param, Port, PortSpec

ZERO = Memory(params=Layout("float", [Field("gain", 1)]), state=Layout("float", [Field("hist", "taps")], sizes=("taps",)))
ZERO_GAIN = ZERO.params.const("gain")


@njit(cache=True)
def zero_kernel(p, s, si, x, y):
    n = s.shape[0]
    for t in range(x.shape[0]):
        for k in range(n - 1, 0, -1):
            s[k] = s[k - 1]
        s[0] = x[t, 0]
        acc = 0.0
        for k in range(n):
            acc += s[k]
        y[t, 0] = p[ZERO_GAIN] * acc / max(n, 1)


class ZeroTaps(Node):
    """Moving sum of the last taps samples; its declaration allows taps=0, a state of no element."""
    type_name = "zero_taps_pc"
    params = {"taps": Param("int", default=4, min=0, max=64)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = zero_kernel
    memory = ZERO

    def build(self, inputs, outputs):
        return self.pack_state({"taps": self.p["taps"]}, params={"gain": 1.0})


@njit(cache=True)
def inplace_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        x[t, 0] = 2.0 * x[t, 0]
        y[t, 0] = x[t, 0]


class InPlace(Node):
    """Doubles its input in place: the producer's buffer, which other nodes read too."""
    type_name = "in_place_pc"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = inplace_kernel


@njit(cache=True)
def two_kernel(p, s, si, x, y, z):
    for t in range(x.shape[0]):
        y[t, 0] = x[t, 0]
        z[t, 0] = -x[t, 0]


class ForgetsAnOutput(Node):
    """Its resolve() returns a spec for y only."""
    type_name = "forgets_output_pc"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x"), "z": Port((), "=x")}
    kernel = two_kernel

    def resolve(self, inputs):
        return {"y": inputs["x"]}


@njit(cache=True)
def copy_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = p[0] * x[t, 0]


class Gain(Node):
    """Named like flowtex's own gain node; its parameter rate is also Node.processor's own keyword."""
    type_name = "gain"
    params = {"rate": Param("float", default=1.0, min=-10.0, max=10.0)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = copy_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["rate"]]))


class TicksInput(Node):
    """Its input is named ticks, a processor call's own keyword (the number of ticks to run)."""
    type_name = "ticks_input_pc"
    inputs = {"ticks": Port((), "*")}
    outputs = {"y": Port((), "=ticks")}
    kernel = copy_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([1.0]))


@njit(cache=True)
def noise_kernel(p, s, si, y):
    for t in range(y.shape[0]):
        y[t, 0] = s[0]


class SeedlessNoise(Node):
    """Says it has random state, but defines no seed_state."""
    type_name = "seedless_pc"
    uses_seed = True
    outputs = {"y": Port((), "")}
    kernel = noise_kernel

    def build(self, inputs, outputs):
        return NodeState(state=np.zeros(1))


class HalfLatency(Node):
    """Says its latency is -2.5 ticks."""
    type_name = "half_latency_pc"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = copy_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.ones(1))

    def latency_samples(self):
        return -2.5


class NeverRuns(HalfLatency):
    """Its own_every() returns 0 ticks between runs."""
    type_name = "never_runs_pc"

    def latency_samples(self):
        return 0

    @classmethod
    def own_every(cls, params, rate, input_every):
        return 0


EULER = Memory(params=Layout("float", [Field("a", 1)]), state=Layout("float", [Field("y", 1)]))
EULER_A = EULER.params.const("a")
EULER_Y = EULER.state.const("y")


@njit(cache=True)
def euler_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        s[EULER_Y] += p[EULER_A] * (x[t, 0] - s[EULER_Y])
        y[t, 0] = s[EULER_Y]


class EulerSmoother(Node):
    """One-pole smoother with the forward-Euler coefficient a = 2 pi fc / fs: stable only while a < 2 (fc < fs / pi),
    yet its declaration allows cutoffs up to the Nyquist frequency (at 500 Hz: a pole at 1 - pi, |y| ~ 2.1**t)."""
    type_name = "euler_smoother_pc"
    params = {"cutoff_hz": Param("float", default=10.0, unit="Hz", min=0.0, min_exclusive=True, max=500.0)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = euler_kernel
    memory = EULER

    def build(self, inputs, outputs):
        return self.pack_state({}, params={"a": 2.0 * np.pi * self.p["cutoff_hz"] / self.context.node_rate})


@njit(cache=True)
def jitter_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = x[t, 0] + 0.01 * np.random.randn()


class Jitter(Node):
    """Adds noise from numba's global np.random: no run repeats, no session replays."""
    type_name = "jitter_pc"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = jitter_kernel

    def build(self, inputs, outputs):
        return NodeState()


@njit(cache=True)
def previous_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = 0.5 * (y[t - 1, 0] + x[t, 0])


class ReadsItsOutput(Node):
    """Averages with its last output read back from y: at t = 0 that is the block's last row, not the last output."""
    type_name = "reads_output_pc"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = previous_kernel

    def build(self, inputs, outputs):
        return NodeState()


_ = PortSpec  # resolve() of a correct node returns PortSpec values
