"""The compiled graph: block splits, stepping, multi-rate, feedback, pruning, caching."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

import flowtex
from flowtex.graph.compiled import Graph
from flowtex.graph.resolve import resolve_graph
from flowtex.graph.spec import load_spec
from flowtex.registry import load_registry

CHAIN = """
flowtex: 1
name: chain
rate: 1000
seed: 5
inputs:
  x: {shape: [2], unit: N}
nodes:
  lp: {type: butterworth, params: {kind: lowpass, order: 3, cutoff_hz: 60}}
  mag: {type: norm}
  d: {type: delay, params: {samples: 3}}
  noise: {type: white_noise, params: {variance: 0.1}}
  sum: {type: add}
  unused: {type: gain, params: {k: 3}}
edges:
  - x -> lp.x
  - lp.y -> mag.x
  - mag.y -> d.x
  - d.y -> sum.a
  - noise.y -> sum.b
  - x -> unused.x
outputs:
  y: sum.y
  filtered: lp.y
"""


@pytest.fixture
def chain(write_graph):
    return write_graph(CHAIN.replace("unit: N", "unit: ''"))


@pytest.fixture(scope="module")
def x():
    return np.random.default_rng(0).standard_normal((5000, 2))


def test_time_is_first_axis(chain, x):
    out = flowtex.load_graph(chain).run({"x": x})
    assert out["y"].shape == (5000,)
    assert out["filtered"].shape == (5000, 2)


def test_chunked_runs_equal_one_pass(chain, x):
    g = flowtex.load_graph(chain)
    whole = g.run({"x": x})
    g.reset()
    parts = [g.process({"x": x[a:b]}) for a, b in [(0, 1), (1, 700), (700, 2048), (2048, 2049), (2049, 5000)]]
    for name in whole:
        np.testing.assert_array_equal(np.concatenate([p[name] for p in parts]), whole[name])


def test_reset_restores_the_arenas_as_loaded(chain, x):
    """A loaded graph's arenas are as placed and seeded; after a run, reset() writes exactly those values back
    (the float arena is rebuilt from the layout's initial pieces, not from a copy of the whole arena)."""
    g = flowtex.load_graph(chain)
    f0, i0 = g.f.copy(), g.i.copy()
    g.run({"x": x[:500]})
    assert not np.array_equal(g.f, f0)
    g.reset()
    np.testing.assert_array_equal(g.f, f0)
    np.testing.assert_array_equal(g.i, i0)
    fresh = Graph(resolve_graph(load_spec(chain), load_registry()))
    np.testing.assert_array_equal(fresh.f, f0)


def test_block_size_does_not_change_numbers(chain, x):
    spec = load_spec(chain)
    a = Graph(resolve_graph(spec, load_registry()), block_rows=7).run({"x": x})
    b = Graph(resolve_graph(spec, load_registry()), block_rows=1024).run({"x": x})
    for name in a:
        np.testing.assert_array_equal(a[name], b[name])


def test_step_equals_run(chain, x):
    g = flowtex.load_graph(chain)
    whole = g.run({"x": x[:300]})
    g.reset()
    stepped = [g.step({"x": row}) for row in x[:300]]
    np.testing.assert_array_equal([s["y"] for s in stepped], whole["y"])
    np.testing.assert_array_equal(np.array([s["filtered"] for s in stepped]), whole["filtered"])
    assert isinstance(stepped[0]["y"], float)


def test_reset_and_seed(chain, x):
    g = flowtex.load_graph(chain)
    a = g.run({"x": x})["y"]
    np.testing.assert_array_equal(g.run({"x": x})["y"], a)
    np.testing.assert_array_equal(g.run({"x": x}, seed=5)["y"], a)  # the graph's seed is 5
    assert not np.array_equal(g.run({"x": x}, seed=6)["y"], a)


def test_results_match_an_independent_computation(chain, x):
    g = flowtex.load_graph(chain)
    out = g.run({"x": x})
    sos = signal.butter(3, 60, fs=1000, output="sos")
    filtered = signal.sosfilt(sos, x, axis=0)
    assert np.max(np.abs(out["filtered"] - filtered)) <= 1e-12 * np.max(np.abs(filtered))
    noise_only = g.run({"x": np.zeros_like(x)})["y"]  # delay output is zero: y is the noise itself
    mag = np.linalg.norm(filtered, axis=1)
    expected = np.concatenate([np.zeros(3), mag[:-3]]) + noise_only
    np.testing.assert_allclose(out["y"], expected, rtol=1e-12, atol=1e-12)


def test_unused_nodes_are_pruned(chain):
    g = flowtex.load_graph(chain)
    assert g.resolved.dropped == ["unused"]
    assert "unused" not in g.source and "unused" not in g.resolved.nodes


def test_every_k_runs_on_multiples_of_k_and_holds(write_graph):
    path = write_graph("""
    flowtex: 1
    name: mr
    rate: 1000
    inputs: {x: {}}
    nodes:
      slow: {type: gain, every: 4, params: {k: 2}}
      fast: {type: gain, params: {k: 1}}
    edges:
      - x -> slow.x
      - slow.y -> fast.x
    outputs: {y: fast.y}
    """)
    g = flowtex.load_graph(path)
    x = np.arange(1, 23, dtype=float)
    expected = 2 * x[(np.arange(22) // 4) * 4]
    np.testing.assert_array_equal(g.run({"x": x})["y"], expected)
    g.reset()
    stepped = [g.step({"x": v})["y"] for v in x]
    np.testing.assert_array_equal(stepped, expected)
    g.reset()
    chunks = np.concatenate([g.process({"x": x[:5]})["y"], g.process({"x": x[5:]})["y"]])
    np.testing.assert_array_equal(chunks, expected)


def test_feedback_loop_through_delay(write_graph):
    path = write_graph("""
    flowtex: 1
    name: echo
    rate: 1000
    inputs: {x: {}}
    nodes:
      s: {type: add}
      d: {type: delay, params: {samples: 3}}
      g: {type: gain, params: {k: 0.5}}
    edges:
      - x -> s.a
      - g.y -> s.b
      - s.y -> d.x
      - d.y -> g.x
    outputs: {y: s.y}
    """)
    g = flowtex.load_graph(path)
    assert g.resolved.cyclic
    x = np.random.default_rng(2).standard_normal(400)
    ref = signal.lfilter([1.0], [1.0, 0, 0, -0.5], x)  # y[t] = x[t] + 0.5 y[t-3]
    np.testing.assert_allclose(g.run({"x": x})["y"], ref, rtol=1e-13, atol=1e-13)
    g.reset()
    np.testing.assert_allclose([g.step({"x": v})["y"] for v in x], ref, rtol=1e-13, atol=1e-13)


def test_graph_differing_only_in_parameters_reuses_compiled_code(write_graph):
    text = CHAIN.replace("unit: N", "unit: ''")
    a = flowtex.load_graph(write_graph(text, "a.yaml"))
    b = flowtex.load_graph(write_graph(text.replace("cutoff_hz: 60", "cutoff_hz: 90").replace("samples: 3", "samples: 9"), "b.yaml"))
    assert a.source == b.source
    assert a.block_function is b.block_function  # the same compiled function (offsets and parameters are data)


def test_nan_input_does_not_crash_and_stays_local(write_graph):
    path = write_graph("""
    flowtex: 1
    name: nan
    rate: 1000
    inputs: {x: {}}
    nodes:
      g: {type: gain, params: {k: 2}}
    edges: [x -> g.x]
    outputs: {y: g.y}
    """)
    g = flowtex.load_graph(path)
    y = [g.step({"x": v})["y"] for v in (1.0, np.nan, 3.0)]  # step() does not check; kernels must not crash
    assert y[0] == 2.0 and np.isnan(y[1]) and y[2] == 6.0
    with pytest.raises(flowtex.errors.DataError, match="non-finite"):  # run() refuses by default (issue 9)
        g.run({"x": np.array([1.0, np.nan, 3.0])})


def test_wrong_input_shape_is_a_clear_error(chain):
    g = flowtex.load_graph(chain)
    with pytest.raises(flowtex.errors.FlowtexError, match=r"input 'x': expected shape \(n, 2\)"):
        g.run({"x": np.zeros((10, 3))})
    with pytest.raises(flowtex.errors.FlowtexError, match="lacks input"):
        g.run({})
    with pytest.raises(flowtex.errors.FlowtexError, match="has no input 'z'"):
        g.step({"z": 1.0})


def test_resolved_types_still_import_from_resolve(chain):
    """ResolvedGraph and ResolvedNode moved to flowtex.graph.resolved (resolve.py's checks to wiring.py and ports.py);
    flowtex.graph.resolve still gives the same classes, and resolve_graph returns them."""
    import flowtex.graph.resolve as resolve
    import flowtex.graph.resolved as resolved

    assert resolve.ResolvedGraph is resolved.ResolvedGraph and resolve.ResolvedNode is resolved.ResolvedNode
    rg = resolve_graph(load_spec(chain), load_registry())
    assert isinstance(rg, resolve.ResolvedGraph) and rg.nodes
    assert all(isinstance(rn, resolve.ResolvedNode) for rn in rg.nodes.values())
