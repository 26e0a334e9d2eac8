"""Feedback loops carry the unit and shape of what they delay (issue 9 item 3).

The cycle error's advice (insert a 'delay') must work for an m/s^2 signal and
for a vector loop. Each loop is a leaky accumulator y[t] = x[t] + k * y[t-1],
checked against scipy.signal.lfilter([1], [1, -k]) (exact up to float rounding).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

import flowtex
from flowtex.errors import GraphError
from flowtex.graph.compiled import check_graph
from flowtex.node_api import PortSpec

LOOP = """
flowtex: 1
name: loop
rate: 1000
inputs:
  acc: {{shape: {shape}, unit: m/s^2}}
nodes:
  d: {{type: delay}}
  s: {{type: add}}
  g: {{type: gain, params: {{k: 0.5}}}}
edges:
  - {first} -> s.a
  - {second} -> s.b
  - s.y -> g.x
  - g.y -> d.x
outputs:
  y: s.y
  fed_back: d.y
"""


@pytest.mark.parametrize("shape", [[], [3]])
@pytest.mark.parametrize("delay_first", [False, True])
def test_loop_resolves_units_and_shape(write_graph, shape, delay_first):
    first, second = ("d.y", "acc") if delay_first else ("acc", "d.y")
    rg = check_graph(write_graph(LOOP.format(shape=shape, first=first, second=second)))
    for name in ("y", "fed_back"):
        assert rg.output_specs[name] == PortSpec(tuple(shape), "m/s^2")


def test_vector_loop_with_units_runs(write_graph):
    shape = [3]  # one compilation: a cyclic graph compiles slowly
    g = flowtex.load_graph(write_graph(LOOP.format(shape=shape, first="acc", second="d.y")))
    x = np.random.default_rng(5).standard_normal((400, *shape))
    out = g.run({"acc": x})
    ref = lfilter([1.0], [1.0, -0.5], x, axis=0)
    np.testing.assert_allclose(out["y"], ref, rtol=1e-12, atol=1e-12)  # rounding of a 2-term recursion
    np.testing.assert_allclose(out["fed_back"][1:], 0.5 * ref[:-1], rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(out["fed_back"][0], np.zeros(shape))


def test_loop_with_inconsistent_units_is_still_an_error(write_graph):
    text = LOOP.format(shape=[], first="acc", second="d.y").replace(
        "g: {type: gain, params: {k: 0.5}}", "g: {type: norm}").replace("inputs:\n", "inputs:\n  v: {shape: [2], unit: mm}\n")
    text = text.replace("s.y -> g.x", "v -> g.x")
    with pytest.raises(GraphError) as info:
        flowtex.load_graph(write_graph(text))
    assert "unit mismatch" in str(info.value) or "feedback into delay 'd'" in str(info.value)
