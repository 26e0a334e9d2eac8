"""Node.processor() runs a node as its graph does: ``ticks=`` for a node without input arrays, ``every``/``own_every``
and input rates, and ``params={...}`` beside the processor's own settings.

The reference is always the same node in a graph (flowtex.graph.builder), run in one pass: a processor named, seeded
and scheduled like the graph's node must give its output bit for bit, in one call and in chunks.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from flowtex.errors import InputError, ParamError
from flowtex.graph.builder import GraphBuilder
from flowtex.node_api import Node, NodeState, Param, Port
from flowtex.registry import load_registry


def node_type(name: str):
    return load_registry().types[name]


def _cuts(n: int):
    return st.lists(st.integers(0, n), max_size=6).map(lambda c: [0, *sorted(c), n])


# --- ticks= ---------------------------------------------------------------------------------------------------------

@settings(max_examples=15, deadline=None)
@given(cuts=_cuts(300))
def test_a_generator_runs_the_ticks_asked_for_and_equals_its_graph_node(cuts) -> None:
    # A node without input arrays ran one tick per call: 300 samples of noise took 300 calls.
    graph = GraphBuilder("n", seed=5).node("w", "white_noise", variance=2.0).output("y", "w.y").build()
    want = graph.run_ticks(300)["y"]
    proc = node_type("white_noise").processor(seed=5, name="w", variance=2.0)
    got = np.vstack([proc(ticks=b - a)["y"] for a, b in itertools.pairwise(cuts)])
    np.testing.assert_array_equal(got[:, 0], want)
    assert np.var(want) > 1.0  # it is noise of variance 2 (300 samples: the variance's spread is ~0.16)
    proc.reset()
    assert proc()["y"].shape == (1, 1) and proc()["y"][0, 0] == want[1]  # no ticks=: one tick, as before


@pytest.mark.parametrize("ticks", [-1, 2.5, "10", True, [3]])
def test_a_bad_tick_count_is_one_line_naming_ticks(ticks) -> None:
    proc = node_type("constant").processor(value=[1.0])
    with pytest.raises(InputError) as err:
        proc(ticks=ticks)
    assert str(err.value).startswith("node type 'constant': ticks (the number of ticks to run) must be an integer >= 0, got ")
    assert "\n" not in str(err.value)
    assert proc(ticks=np.int64(0))["y"].shape == (0, 1)


def test_more_ticks_than_a_recording_holds_are_refused_before_allocating() -> None:
    # ticks=10**12 asked numpy for 8 TB ("Unable to allocate"); the limit is flowtex.limits.MAX_RECORDING_VALUES
    proc = node_type("white_noise").processor()
    with pytest.raises(InputError, match=r"^node type 'white_noise': ticks=1,000,000,000,000 would fill 2,000,000,000,000 values, more than a "
                                         r"recording may hold \(100,000,000\); run fewer ticks per call"):
        proc(ticks=10**12)
    assert proc(ticks=3)["y"].shape == (3, 1)


def test_ticks_beside_input_arrays_must_agree_with_them() -> None:
    proc = node_type("gain").processor(k=2.0)
    np.testing.assert_array_equal(proc(x=np.ones(4), ticks=4)["y"][:, 0], np.full(4, 2.0))
    with pytest.raises(InputError, match=r"ticks=3, but the inputs have 4 rows; drop ticks="):
        proc(x=np.ones(4), ticks=3)


# --- every / own_every / input rates ----------------------------------------------------------------------------

def _graph_and_processor_agree(builder: GraphBuilder, inputs: dict, graph_out: str, proc, proc_inputs, cuts) -> None:
    """``proc`` fed ``proc_inputs(graph outputs)`` gives the graph's ``graph_out`` bit for bit, in one call and chunked."""
    outs = builder.build().run(inputs)
    want = np.asarray(outs[graph_out]).reshape(len(cuts) and cuts[-1], -1)
    fed = proc_inputs(outs)
    one = proc(**fed)["y"]
    np.testing.assert_array_equal(one, want)
    proc.reset()
    chunked = np.vstack([proc(**{k: a[lo:hi] for k, a in fed.items()})["y"] for lo, hi in itertools.pairwise(cuts)])
    np.testing.assert_array_equal(chunked, want)


@settings(max_examples=12, deadline=None)
@given(every=st.integers(2, 7), cuts=_cuts(240), seed=st.integers(0, 2**32 - 1))
def test_a_node_run_every_k_ticks_equals_its_graph_node(every, cuts, seed) -> None:
    # The processor ran the kernel on every row: a filter meant for 1000 / k Hz saw k times the samples.
    x = np.random.default_rng(seed).standard_normal(240)
    builder = (GraphBuilder("e").input("x").node("f", "butterworth", every=every, order=2, cutoff_hz=40.0)
               .edge("x -> f.x").output("y", "f.y"))
    proc = node_type("butterworth").processor(every=every, order=2, cutoff_hz=40.0)
    _graph_and_processor_agree(builder, {"x": x}, "y", proc, lambda outs: {"x": x}, cuts)


@pytest.mark.parametrize(("producer_every", "to_hz"), [(2, 250.0), (4, 1000.0), (1, 250.0)])
@settings(max_examples=6, deadline=None)
@given(cuts=_cuts(400))
def test_a_resampler_at_its_input_rate_equals_its_graph_node(producer_every, to_hz, cuts) -> None:
    # 500 Hz -> 250 Hz runs every 2 ticks (own_every); 250 Hz -> 1000 Hz every tick with up = 4: a processor could
    # express neither (it took every input as arriving at the base rate: "remove the resample node").
    x = np.sin(np.arange(400) * 0.05) + np.random.default_rng(3).standard_normal(400) * 0.1
    builder = (GraphBuilder("r").input("x").node("f", "butterworth", every=producer_every, order=2, cutoff_hz=100.0)
               .node("r", "resample", to_hz=to_hz).edge("x -> f.x").edge("f.y -> r.x")
               .output("fy", "f.y").output("y", "r.y"))
    proc = node_type("resample").processor(input_every={"x": producer_every}, to_hz=to_hz)
    assert proc.every == min(producer_every, round(1000.0 / to_hz))  # the node's own schedule, as the graph's
    _graph_and_processor_agree(builder, {"x": x}, "y", proc, lambda outs: {"x": outs["fy"]}, cuts)


def test_a_random_node_every_k_ticks_equals_its_graph_node() -> None:
    graph = (GraphBuilder("n", seed=9).node("w", "white_noise", every=3).output("y", "w.y").build())
    want = graph.run_ticks(100)["y"]
    proc = node_type("white_noise").processor(seed=9, name="w", every=3)
    got = np.vstack([proc(ticks=40)["y"], proc(ticks=1)["y"], proc(ticks=59)["y"]])[:, 0]
    np.testing.assert_array_equal(got, want)
    assert np.all(want[1::3] == want[0::3][:33]) and len(set(want[0::3])) == 34  # held between runs, new at each


@pytest.mark.parametrize(("kwargs", "param", "words"), [
    ({"every": 0}, "every", "node 'resample': every must be a positive integer up to 1,000,000 (run every k ticks), got 0"),
    ({"every": 2.5}, "every", "got 2.5"),
    ({"input_every": {"x": 0}}, "input_every", "input_every['x']: must be >= 1, got 0"),
    ({"input_every": {"y": 2}}, "input_every", "node type 'resample' has no input 'y'; its inputs are: x"),
    ({"input_every": [2]}, "input_every", "input_every must map input names to their producer's every"),
    ({"input_every": {"x": 4}, "to_hz": 125.0, "every": 3}, "every",
     "its parameters make it run every 4 ticks, but every=3 was given; drop every="),
    ({"input_every": {"x": 4}}, "to_hz", "the input already arrives at 250 Hz; remove the resample node"),
])
def test_a_schedule_a_graph_would_refuse_is_refused_in_one_line(kwargs, param, words) -> None:
    with pytest.raises(ParamError) as err:
        node_type("resample").processor(**{"to_hz": 250.0, **kwargs})
    assert err.value.param == param and words in str(err.value) and "\n" not in str(err.value)


# --- params={...} -------------------------------------------------------------------------------------------------

@njit(cache=True)
def _scale_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = p[0] * x[t, 0]


class _RateScale(Node):
    """Scales x by its parameter ``rate`` (named like a processor setting, as a plugin may name one)."""

    type_name = "rate_scale_test"
    params = {"rate": Param("float", default=1.0, min=-10.0, max=10.0)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = _scale_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["rate"]]))


def test_params_reach_a_parameter_named_like_a_setting() -> None:
    # rate=3.0 set the processor's tick rate; the node's own 'rate' could not be set at all
    proc = _RateScale.processor(rate=2000.0, params={"rate": 3.0})
    np.testing.assert_array_equal(proc(x=np.arange(4.0))["y"][:, 0], 3.0 * np.arange(4.0))
    assert proc.context.rate == 2000.0
    np.testing.assert_array_equal(_RateScale.processor(rate=3.0)(x=np.ones(2))["y"][:, 0], [1.0, 1.0])


def test_params_and_keywords_build_the_same_node() -> None:
    x = np.random.default_rng(6).standard_normal(200)
    want = node_type("butterworth").processor(order=3, cutoff_hz=60.0)(x=x)["y"]
    for proc in (node_type("butterworth").processor(params={"order": 3, "cutoff_hz": 60.0}),
                 node_type("butterworth").processor(params={"order": 3}, cutoff_hz=60.0)):
        np.testing.assert_array_equal(proc(x=x)["y"], want)


@pytest.mark.parametrize(("call", "param", "words"), [
    (lambda cls: cls.processor(params={"order": 3, "cutoff_hz": 60.0}, order=3), "order",
     "parameter 'order' is given twice, as a keyword and in params=; give it once"),
    (lambda cls: cls.processor(params=[("order", 3)]), "params", "params must be a mapping of parameter name to value"),
    (lambda cls: cls.processor(params={"ordr": 3, "cutoff_hz": 60.0}), "ordr", "unknown parameter 'ordr'"),
])
def test_wrong_params_are_named(call, param, words) -> None:
    with pytest.raises(ParamError) as err:
        call(node_type("butterworth"))
    assert err.value.param == param and words in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("every", [2, 1000])
def test_a_decimated_call_holds_no_more_than_its_outputs(every) -> None:
    """A call of n ticks of a node run every k ticks allocates the outputs' n rows and O(n / k) more, as every=1 does:
    limits.check_ticks bounds n by the outputs' and inputs' values, and the schedule's index arrays (an int64 a tick,
    several of them: three times the output of a one-output node) went past that bound."""
    from tests.memory import peak_bytes

    proc = load_registry().types["constant"].processor(value=2.0, every=every)
    proc(ticks=3)  # built: the kernel compiled, the state allocated
    n = 1_000_000
    out = {}
    peak = peak_bytes(lambda: out.update(proc(ticks=n)))
    # the (n, 1) output, and per run its row, its index, its span and two copies of its row (stacked, repeated): every=1
    # measures 1.00 n * 8, and the old schedule 3.0 n * 8 at k = 1000, 4.5 n * 8 at k = 2
    assert peak < (n + 5 * n // every) * 8 + 2**16
    assert out["y"].shape == (n, 1) and np.all(out["y"] == 2.0)  # held from tick 0's run, then each run's


def test_ticks_of_a_node_without_ports_are_bounded_too() -> None:
    """A node with neither inputs nor outputs holds no values a tick, so check_ticks let any count through; run every k
    ticks, the schedule's runs (n / k of them) were numpy's 'Unable to allocate 7.28 TiB' for ticks=10**15."""

    @njit
    def kernel(p, s, si):
        pass

    class NoPorts(Node):
        """No ports."""

        type_name = "no_ports_sched"
        inputs = {}
        outputs = {}

    NoPorts.kernel = kernel
    proc = NoPorts.processor(every=1000)
    assert proc(ticks=10) == {}
    with pytest.raises(InputError, match="ticks=1,000,000,000,000,000 would fill"):
        proc(ticks=10**15)
