"""Built-in nodes against independent references (scipy.signal, numpy)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

import flowtex

RATE = 1000.0


def one_node_graph(write_graph, node_yaml: str, inputs: str = "x: {}", edges: str = "- x -> n.x", out: str = "n.y") -> flowtex.Graph:
    path = write_graph(f"""
    flowtex: 1
    name: one
    rate: {RATE}
    inputs:
      {inputs}
    nodes:
      n: {node_yaml}
    edges:
      {edges}
    outputs:
      y: {out}
    """)
    return flowtex.load_graph(path)


def rel_err(a: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(a - ref)) / np.max(np.abs(ref)))


@pytest.fixture(scope="module")
def noise():
    return np.random.default_rng(1).standard_normal(20_000)


@pytest.mark.parametrize("kind, order, cutoff", [
    ("lowpass", 2, 50.0),
    ("lowpass", 5, 120.0),
    ("highpass", 4, 10.0),
    ("bandpass", 3, [20.0, 300.0]),
    ("bandstop", 2, [45.0, 55.0]),
    ("lowpass", 4, 2.0),        # poles at radius 0.991: near the unit circle
    ("highpass", 2, 0.5),       # poles at radius 0.998
    ("lowpass", 8, 450.0),      # close to Nyquist
])
def test_butterworth_matches_scipy_sosfilt(write_graph, noise, kind, order, cutoff):
    g = one_node_graph(write_graph, f"{{type: butterworth, params: {{kind: {kind}, order: {order}, cutoff_hz: {cutoff}}}}}")
    sos = signal.butter(order, cutoff, btype=kind, fs=RATE, output="sos")
    ref = signal.sosfilt(sos, noise)
    assert rel_err(g.run({"x": noise})["y"], ref) <= 1e-12


def test_butterworth_filters_vector_components_independently(write_graph, noise):
    x = np.stack([noise, noise[::-1].copy(), 3 * noise], axis=1)
    g = one_node_graph(write_graph, "{type: butterworth, params: {order: 3, cutoff_hz: 40}}", inputs="x: {shape: [3]}")
    sos = signal.butter(3, 40, fs=RATE, output="sos")
    y = g.run({"x": x})["y"]
    assert y.shape == x.shape
    for c in range(3):
        assert rel_err(y[:, c], signal.sosfilt(sos, x[:, c])) <= 1e-12


def test_biquad_matches_lfilter(write_graph, noise):
    b, a = [0.2, 0.3, -0.1], [1.0, -1.6, 0.81]
    g = one_node_graph(write_graph, f"{{type: biquad, params: {{b: {b}, a: {a}}}}}")
    assert rel_err(g.run({"x": noise})["y"], signal.lfilter(b, a, noise)) <= 1e-12


def test_biquad_with_unnormalised_a0(write_graph, noise):
    b, a = [0.4, 0.6, -0.2], [2.0, -3.2, 1.62]
    g = one_node_graph(write_graph, f"{{type: biquad, params: {{b: {b}, a: {a}}}}}")
    assert rel_err(g.run({"x": noise})["y"], signal.lfilter(b, a, noise)) <= 1e-12


def test_unstable_biquad_is_refused(write_graph):
    with pytest.raises(flowtex.errors.GraphError, match="unstable"):
        one_node_graph(write_graph, "{type: biquad, params: {b: [1, 0, 0], a: [1, -2.0, 1.01]}}")


def test_first_order_lowpass_matches_lfilter(write_graph, noise):
    g = one_node_graph(write_graph, "{type: first_order_lowpass, params: {cutoff_hz: 20}}")
    alpha = 1 - np.exp(-2 * np.pi * 20 / RATE)
    ref = signal.lfilter([alpha], [1, -(1 - alpha)], noise)
    assert rel_err(g.run({"x": noise})["y"], ref) <= 1e-12


def test_differentiator_is_backward_difference_per_second(write_graph, noise):
    g = one_node_graph(write_graph, "{type: differentiator}", inputs="x: {unit: mm}")
    y = g.run({"x": noise})["y"]
    assert y[0] == 0.0
    np.testing.assert_allclose(y[1:], np.diff(noise) * RATE, rtol=1e-13, atol=1e-10)
    assert g.outputs["y"].unit == "mm/s"


def test_gain_add_subtract_multiply(write_graph, noise):
    path = write_graph("""
    flowtex: 1
    name: arith
    rate: 1000
    inputs:
      a: {shape: [2]}
      b: {shape: [2]}
      s: {}
    nodes:
      g: {type: gain, params: {k: -2.5}}
      add: {type: add}
      sub: {type: subtract}
      mul: {type: multiply}
      scale: {type: multiply}
    edges:
      - a -> g.x
      - a -> add.a
      - b -> add.b
      - a -> sub.a
      - b -> sub.b
      - a -> mul.a
      - b -> mul.b
      - a -> scale.a
      - s -> scale.b
    outputs:
      g: g.y
      add: add.y
      sub: sub.y
      mul: mul.y
      scale: scale.y
    """)
    a = noise[:2000].reshape(1000, 2)
    b = noise[2000:4000].reshape(1000, 2)
    s = noise[4000:5000]
    out = flowtex.load_graph(path).run({"a": a, "b": b, "s": s})
    np.testing.assert_array_equal(out["g"], -2.5 * a)
    np.testing.assert_array_equal(out["add"], a + b)
    np.testing.assert_array_equal(out["sub"], a - b)
    np.testing.assert_array_equal(out["mul"], a * b)
    np.testing.assert_array_equal(out["scale"], a * s[:, None])


def test_clip_limits_and_replaces_nan(write_graph):
    g = one_node_graph(write_graph, "{type: clip, params: {low: -1, high: 2, nan: 0.5}}")
    x = np.array([-5.0, -1.0, 0.3, 2.0, 7.0, np.nan, np.inf, -np.inf])
    np.testing.assert_array_equal(g.run({"x": x}, nonfinite="pass")["y"], [-1.0, -1.0, 0.3, 2.0, 2.0, 0.5, 2.0, -1.0])


def test_norm_and_select(write_graph, noise):
    x = noise[:3000].reshape(1000, 3)
    g = one_node_graph(write_graph, "{type: norm}", inputs="x: {shape: [3], unit: mm}")
    np.testing.assert_allclose(g.run({"x": x})["y"], np.linalg.norm(x, axis=1), rtol=1e-15)
    g = one_node_graph(write_graph, "{type: select, params: {index: 2}}", inputs="x: {shape: [3]}")
    np.testing.assert_array_equal(g.run({"x": x})["y"], x[:, 2])


def test_select_index_out_of_range_is_an_error(write_graph):
    with pytest.raises(flowtex.errors.GraphError, match=r"index 3 is out of range for a 3-vector"):
        one_node_graph(write_graph, "{type: select, params: {index: 3}}", inputs="x: {shape: [3]}")


def test_constant_scalar_and_vector(write_graph):
    g = one_node_graph(write_graph, "{type: constant, params: {value: [1.5, -2, 3]}}", inputs="x: {}", edges="[]")
    out = g.run_ticks(5)["y"]
    np.testing.assert_array_equal(out, np.tile([1.5, -2.0, 3.0], (5, 1)))


def test_delay_shifts_by_whole_ticks(write_graph, noise):
    g = one_node_graph(write_graph, "{type: delay, params: {samples: 7}}")
    y = g.run({"x": noise})["y"]
    np.testing.assert_array_equal(y[:7], 0.0)
    np.testing.assert_array_equal(y[7:], noise[:-7])


def test_white_noise_statistics_and_seed(write_graph):
    g = one_node_graph(write_graph, "{type: white_noise, params: {variance: 2.0}}", inputs="x: {}", edges="[]")
    n = 200_000
    y = g.run_ticks(n, seed=3)["y"]
    # Standard error of the sample variance is sqrt(2/n) relative: 0.32 %; allow 5 sigma.
    assert abs(y.var() / 2.0 - 1) < 5 * np.sqrt(2 / n)
    assert abs(y.mean()) < 5 * np.sqrt(2.0 / n)
    lag1 = np.corrcoef(y[:-1], y[1:])[0, 1]
    assert abs(lag1) < 5 / np.sqrt(n)
    kurt = np.mean((y / y.std()) ** 4)
    assert abs(kurt - 3) < 5 * np.sqrt(24 / n)
    np.testing.assert_array_equal(g.run_ticks(1000, seed=3)["y"], y[:1000])
    assert not np.array_equal(g.run_ticks(1000, seed=4)["y"], y[:1000])


def test_white_noise_variance_input_and_zero_variance(write_graph):
    g = one_node_graph(write_graph, "{type: white_noise}", inputs="v: {}", edges="- v -> n.variance")
    v = np.concatenate([np.zeros(1000), np.full(100_000, 0.25)])
    y = g.run({"v": v})["y"]
    np.testing.assert_array_equal(y[:1000], 0.0)
    assert abs(y[1000:].var() / 0.25 - 1) < 5 * np.sqrt(2 / 100_000)


def test_unseeded_generator_does_not_hang():
    from flowtex.dsp.rng import next_normal

    si, sf = np.zeros(5, np.int64), np.zeros(1)  # never seeded: xoshiro stays at zero
    assert next_normal(si, sf) == 0.0


def test_warm_leaves_the_state_alone(write_graph):
    g = one_node_graph(write_graph, "{type: white_noise, params: {variance: 1.0}}", inputs="x: {}", edges="[]")
    g.reset()
    before = g.f.copy(), g.i.copy()
    g.warm()
    g.warm()
    np.testing.assert_array_equal(g.f, before[0])
    np.testing.assert_array_equal(g.i, before[1])
