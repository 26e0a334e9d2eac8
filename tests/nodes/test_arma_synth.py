"""arma_synth inside real graphs built from YAML: wiring, seeding, chunking, live stepping."""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

import flowtex
from flowtex.dsp.rng import next_normal, seed_rng
from flowtex.errors import FlowtexError

A = [1.0, -1.2, 0.9, -0.3, 0.1]  # stable AR(4)
C = [1.0, 0.4, 0.2]  # MA(2)
GAIN = 0.8
VAR = 0.5


def write(tmp_path: Path, text: str, name: str = "g.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


CONST_GRAPH = f"""
flowtex: 1
name: synth-const
rate: 1000
seed: 7
nodes:
  ar: {{type: constant, params: {{value: {A}}}}}
  ma: {{type: constant, params: {{value: {C}}}}}
  gain: {{type: constant, params: {{value: {GAIN}}}}}
  variance: {{type: constant, params: {{value: {VAR}}}}}
  synth: {{type: arma_synth}}
edges:
  - ar.y -> synth.ar
  - ma.y -> synth.ma
  - gain.y -> synth.gain
  - variance.y -> synth.variance
outputs:
  accel: synth.y
"""

INPUT_GRAPH = """
flowtex: 1
name: synth-inputs
rate: 1000
seed: 3
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
  accel: synth.y
"""


def node_normals(graph_seed: int, node_name: str, n: int) -> np.ndarray:
    """The excitation a node named ``node_name`` draws, seeded as the graph documents (seed, crc32(name))."""
    si = np.zeros(5, np.int64)
    sf = np.zeros(1)
    seed_rng(si, sf, np.random.SeedSequence([graph_seed, zlib.crc32(node_name.encode())]))
    return np.array([next_normal(si, sf) for _ in range(n)])


def test_constant_model_graph_matches_lfilter(tmp_path: Path) -> None:
    graph = flowtex.load_graph(write(tmp_path, CONST_GRAPH))
    assert graph.outputs["accel"].unit == "m/s^2"
    n = 2000
    y = graph.run_ticks(n)["accel"]
    assert y.shape == (n,)
    ref = scipy.signal.lfilter(GAIN * np.array(C), np.array(A), np.sqrt(VAR) * node_normals(7, "synth", n))
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_seeds(tmp_path: Path) -> None:
    graph = flowtex.load_graph(write(tmp_path, CONST_GRAPH))
    y1 = graph.run_ticks(500, seed=1)["accel"]
    y1b = graph.run_ticks(500, seed=1)["accel"]
    y2 = graph.run_ticks(500, seed=2)["accel"]
    np.testing.assert_array_equal(y1, y1b)
    assert not np.allclose(y1, y2)
    # a second graph object from the same file gives the same numbers
    np.testing.assert_array_equal(flowtex.load_graph(write(tmp_path, CONST_GRAPH, "h.yaml")).run_ticks(500, seed=1)["accel"], y1)


def per_tick_models(n: int) -> dict[str, np.ndarray]:
    """Models changing every few ticks, with an invalid (NaN) stretch in the middle."""
    rng = np.random.default_rng(0)
    ar = np.tile(A, (n, 1))
    ma = np.tile(C, (n, 1))
    alt_a = np.real(np.poly([0.95 * np.exp(0.3j), 0.95 * np.exp(-0.3j), 0.9 * np.exp(2.5j), 0.9 * np.exp(-2.5j)]))
    switch = (np.arange(n) // 3) % 2 == 1
    ar[switch] = alt_a
    gain = np.where(switch, 1.5, GAIN)
    variance = rng.uniform(0.1, 1.0, n)
    ar[n // 2:n // 2 + 10, 1] = np.nan
    return {"ar": ar, "ma": ma, "gain": gain, "variance": variance}


def test_chunked_equals_one_pass_and_step_equals_run(tmp_path: Path) -> None:
    graph = flowtex.load_graph(write(tmp_path, INPUT_GRAPH))
    n = 3000
    inputs = per_tick_models(n)
    full = graph.run(inputs, nonfinite="pass")["accel"]
    assert np.all(np.isfinite(full))
    graph.reset()
    parts = []
    for lo, hi in ((0, 1), (1, 7), (7, 1500), (1500, 1501), (1501, n)):
        parts.append(graph.process({k: v[lo:hi] for k, v in inputs.items()}, nonfinite="pass")["accel"])
    np.testing.assert_array_equal(np.concatenate(parts), full)
    graph.reset()
    stepped = np.array([graph.step({k: v[t] for k, v in inputs.items()})["accel"] for t in range(n)])
    np.testing.assert_array_equal(stepped, full)


def test_fixed_model_from_inputs_matches_lfilter(tmp_path: Path) -> None:
    graph = flowtex.load_graph(write(tmp_path, INPUT_GRAPH))
    n = 1000
    inputs = {"ar": np.tile(A, (n, 1)), "ma": np.tile(C, (n, 1)), "gain": np.full(n, GAIN), "variance": np.full(n, VAR)}
    y = graph.run(inputs, seed=11)["accel"]
    ref = scipy.signal.lfilter(GAIN * np.array(C), np.array(A), np.sqrt(VAR) * node_normals(11, "synth", n))
    np.testing.assert_allclose(y, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_zero_orders(tmp_path: Path) -> None:
    """p = q = 0: y = g sqrt(var) e (one-value polynomials come from 'vector: true' constants)."""
    text = """
flowtex: 1
name: white
rate: 1000
seed: 5
nodes:
  one: {type: constant, params: {value: [1.0], vector: true}}
  gain: {type: constant, params: {value: 2.0}}
  variance: {type: constant, params: {value: 0.25}}
  synth: {type: arma_synth}
edges:
  - one.y -> synth.ar
  - one.y -> synth.ma
  - gain.y -> synth.gain
  - variance.y -> synth.variance
outputs:
  accel: synth.y
"""
    y = flowtex.load_graph(write(tmp_path, text)).run_ticks(300)["accel"]
    np.testing.assert_allclose(y, 2.0 * 0.5 * node_normals(5, "synth", 300), rtol=1e-15)


def test_scalar_ar_is_refused_with_a_clear_message(tmp_path: Path) -> None:
    text = CONST_GRAPH.replace(f"ar: {{type: constant, params: {{value: {A}}}}}", "ar: {type: constant, params: {value: 1.0}}")
    with pytest.raises(FlowtexError, match="vector"):
        flowtex.load_graph(write(tmp_path, text))
