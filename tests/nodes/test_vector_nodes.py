"""cross, dot and normalize nodes in real graphs built from YAML, checked against numpy."""

from __future__ import annotations

import numpy as np
import pytest

import flowtex
from flowtex.errors import GraphError


def graph(tmp_path, body, name="g.yaml"):
    path = tmp_path / name
    path.write_text("flowtex: 1\nname: test\nrate: 1000\n" + body)
    return flowtex.load_graph(path)


TWO = """\
inputs:
  a: {{shape: [{na}], unit: {ua}}}
  b: {{shape: [{nb}], unit: {ub}}}
nodes:
  op: {{type: {op}}}
edges:
  - a -> op.a
  - b -> op.b
outputs:
  y: op.y
"""

NORMALIZE = """\
inputs:
  x: {{shape: [{n}], unit: mm/s}}
nodes:
  unit: {{type: normalize{params}}}
  back: {{type: multiply}}
edges:
  - x -> unit.x
  - unit.y -> back.a
  - x -> back.b
outputs:
  y: unit.y
"""


def test_cross_matches_numpy_and_chunks(tmp_path):
    g = graph(tmp_path, TWO.format(na=3, nb=3, ua="mm/s", ub='""', op="cross"))
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(500, 3)) * 100, rng.normal(size=(500, 3))
    a[:3] = [[1, 0, 0], [0, 1, 0], [2, 0, 0]]
    b[:3] = [[0, 1, 0], [0, 0, 1], [4, 0, 0]]  # e_x x e_y = e_z, e_y x e_z = e_x, parallel -> 0
    y = g.run({"a": a, "b": b})["y"]
    np.testing.assert_allclose(y, np.cross(a, b), rtol=1e-13, atol=1e-12)
    np.testing.assert_array_equal(y[:3], [[0, 0, 1], [1, 0, 0], [0, 0, 0]])
    # perpendicular to both factors (an independent property)
    assert np.max(np.abs(np.einsum("ij,ij->i", y, a))) < 1e-9 * np.max(np.abs(a)) ** 2
    g.reset()
    parts = [g.process({"a": a[i:j], "b": b[i:j]})["y"] for i, j in [(0, 1), (1, 77), (77, 500)]]
    np.testing.assert_array_equal(np.concatenate(parts), y)
    assert g.outputs["y"].unit == "mm/s" and g.outputs["y"].shape == (3,)


def test_cross_unit_is_the_product(tmp_path):
    # unit of the product reaches the output: a gain that keeps its unit and an output declared elsewhere
    body = """\
inputs:
  a: {shape: [3], unit: mm/s}
  b: {shape: [3], unit: N}
nodes:
  op: {type: cross}
  s: {type: subtract}
  f: {type: constant, params: {value: [0, 0, 0], unit: N}}
edges:
  - a -> op.a
  - b -> op.b
  - op.y -> s.a
  - f.y -> s.b
outputs:
  y: s.y
"""
    with pytest.raises(GraphError) as err:
        graph(tmp_path, body)
    text = str(err.value)
    assert "mm*N/s" in text and "g.yaml:" in text


@pytest.mark.parametrize("shape", [2, 4])
def test_cross_refuses_other_shapes(tmp_path, shape):
    with pytest.raises(GraphError) as err:
        graph(tmp_path, TWO.format(na=shape, nb=3, ua="mm", ub="mm", op="cross"))
    assert "g.yaml:" in str(err.value)


def test_dot_matches_numpy(tmp_path):
    g = graph(tmp_path, TWO.format(na=4, nb=4, ua="N", ub="mm", op="dot"))
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(300, 4)), rng.normal(size=(300, 4))
    y = g.run({"a": a, "b": b})["y"]
    np.testing.assert_allclose(y, np.einsum("ij,ij->i", a, b), rtol=1e-13, atol=1e-14)
    with pytest.raises(GraphError):
        graph(tmp_path, TWO.format(na=4, nb=3, ua="N", ub="mm", op="dot"), "h.yaml")


def test_normalize_unit_length_and_direction(tmp_path):
    g = graph(tmp_path, NORMALIZE.format(n=3, params=""))
    rng = np.random.default_rng(3)
    x = rng.normal(size=(400, 3)) * rng.uniform(1e-6, 1e3, (400, 1))
    x[0] = [3.0, 4.0, 0.0]
    x[1] = [0.0, 0.0, -1e150]  # |x|^2 = 1e300 is still finite
    y = g.run({"x": x})["y"]
    np.testing.assert_allclose(np.linalg.norm(y, axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(y, x / np.linalg.norm(x, axis=1, keepdims=True), rtol=1e-14, atol=1e-16)
    np.testing.assert_array_equal(y[0], [0.6, 0.8, 0.0])
    np.testing.assert_array_equal(y[1], [0.0, 0.0, -1.0])


def test_normalize_zero_nan_inf_and_threshold_give_zero(tmp_path):
    g = graph(tmp_path, NORMALIZE.format(n=3, params=", params: {min_norm: 0.5}"))
    x = np.array([
        [0.0, 0.0, 0.0],
        [0.3, 0.4, 0.0],           # |x| = 0.5: at the threshold -> zero
        [0.3, 0.4, 0.0001],        # just above -> unit
        [np.nan, 1.0, 0.0],
        [np.inf, 0.0, 0.0],
        [-np.inf, np.inf, 1.0],
        [1e200, 0.0, 0.0],         # finite but |x| overflows -> no direction -> zero
        [0.0, -2.0, 0.0],
    ])
    y = g.run({"x": x}, nonfinite="pass")["y"]
    expected = np.zeros_like(x)
    expected[2] = x[2] / np.linalg.norm(x[2])
    expected[7] = [0.0, -1.0, 0.0]
    np.testing.assert_allclose(y, expected, rtol=1e-15, atol=0)
    assert np.all(np.isfinite(y))


def test_normalize_default_threshold_and_refusals(tmp_path):
    g = graph(tmp_path, NORMALIZE.format(n=2, params=""))
    y = g.run({"x": np.array([[1e-9, 0.0], [2e-9, 0.0], [1e-300, 1e-300]])})["y"]
    np.testing.assert_array_equal(y, [[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    with pytest.raises(GraphError) as err:
        graph(tmp_path, NORMALIZE.format(n=3, params=", params: {min_norm: -1}"), "neg.yaml")
    assert "min_norm" in str(err.value) and "neg.yaml:" in str(err.value)
