"""Node.processor(): a node's build and kernel on plain arrays, state kept between calls."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

import flowtex
from flowtex.errors import ParamError
from flowtex.registry import load_registry


def node_type(name: str):
    return load_registry().types[name]


def test_butterworth_processor_matches_scipy_sosfilt() -> None:
    """Reference: scipy.signal.butter + sosfilt in float64 (an independent implementation)."""
    x = np.random.default_rng(3).standard_normal(2000)
    proc = node_type("butterworth").processor(rate=1000.0, order=4, cutoff_hz=50.0)
    y = proc(x=x)["y"][:, 0]
    ref = scipy.signal.sosfilt(scipy.signal.butter(4, 50.0, fs=1000.0, output="sos"), x)
    np.testing.assert_allclose(y, ref, rtol=1e-9, atol=1e-12)  # float64 rounding of two biquad cascades


def test_state_is_kept_between_calls() -> None:
    """Chunks of any size give the one-pass output exactly (the kernel's state carries over)."""
    x = np.random.default_rng(4).standard_normal((700, 3))
    one = node_type("butterworth").processor(order=3, cutoff_hz=80.0)(x=x)["y"]
    proc = node_type("butterworth").processor(order=3, cutoff_hz=80.0)
    parts = [proc(x=x[a:b])["y"] for a, b in ((0, 1), (1, 250), (250, 251), (251, 700))]
    np.testing.assert_array_equal(np.vstack(parts), one)
    proc.reset()
    np.testing.assert_array_equal(proc(x=x)["y"], one)


GRAPH = """
flowtex: 1
name: synth-const
rate: 1000
seed: 7
inputs:
  ar: {shape: [5]}
  ma: {shape: [3]}
  gain: {}
  variance: {}
nodes:
  synth: {type: arma_synth}
edges:
  - ar -> synth.ar
  - ma -> synth.ma
  - gain -> synth.gain
  - variance -> synth.variance
outputs:
  y: synth.y
"""


def test_processor_named_like_the_graph_node_reproduces_it(write_graph) -> None:
    """Same build, kernel and seeding as a graph: the random synthesizer's output is bit-identical."""
    n = 1500
    ar = np.tile([1.0, -1.2, 0.9, -0.3, 0.1], (n, 1))
    ma = np.tile([1.0, 0.4, 0.2], (n, 1))
    gain, var = np.full(n, 0.8), np.full(n, 0.5)
    graph_y = flowtex.load_graph(write_graph(GRAPH)).run({"ar": ar, "ma": ma, "gain": gain, "variance": var})["y"]
    proc = node_type("arma_synth").processor(rate=1000.0, seed=7, name="synth")
    y = np.vstack([proc(ar=ar[:400], ma=ma[:400], gain=gain[:400], variance=var[:400])["y"],
                   proc(ar=ar[400:], ma=ma[400:], gain=gain[400:], variance=var[400:])["y"]])
    np.testing.assert_array_equal(y.ravel(), np.asarray(graph_y).ravel())
    assert np.std(y) > 0.1  # it really synthesized (variance 0.5 through a resonant AR(4))


def test_wrong_parameters_and_inputs_are_named() -> None:
    with pytest.raises(ParamError, match="unknown parameter 'ordr'.*order"):
        node_type("butterworth").processor(ordr=3, cutoff_hz=50.0)
    with pytest.raises(ParamError, match="missing required parameter 'order'"):
        node_type("butterworth").processor(cutoff_hz=50.0)
    with pytest.raises(ParamError, match="'order'"):
        node_type("butterworth").processor(order=99, cutoff_hz=50.0)
    proc = node_type("butterworth").processor(order=2, cutoff_hz=50.0)
    with pytest.raises(ValueError, match="no input 'xx'"):
        proc(xx=np.zeros(3))


@pytest.mark.parametrize("params", [{"ordr": 3, "cutoff_hz": 50.0}, {"cutoff_hz": 50.0}, {"order": 99, "cutoff_hz": 50.0},
                                    {"order": 2, "cutoff_hz": 50.0, "kind": "notch"}, {"order": 2.5, "cutoff_hz": 50.0}])
def test_a_graph_and_a_processor_refuse_a_parameter_with_one_message(params) -> None:
    # One owner (flowtex.node_params.checked_params) checks a node's parameters for both: the messages differ only
    # in how they name the node (a graph's node by its name and type, a processor by its type).
    from flowtex.errors import GraphError
    from flowtex.graph.builder import GraphBuilder

    with pytest.raises(ParamError) as proc_err:
        node_type("butterworth").processor(**params)
    builder = GraphBuilder("g").input("x").node("f", "butterworth", **params).edge("x -> f.x").output("y", "f.y")
    with pytest.raises(GraphError) as graph_err:
        builder.resolve()
    first = graph_err.value.diagnostics[0].message
    assert str(proc_err.value).removeprefix("node type 'butterworth': ") == first.removeprefix("node 'f' (butterworth): ")
    assert str(proc_err.value) != first  # both prefixes were there to remove
