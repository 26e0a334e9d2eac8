"""coulomb_friction and dahl_friction nodes in real graphs built from YAML."""

from __future__ import annotations

import math

import numpy as np
import pytest

import flowtex
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.errors import GraphError
from flowtex.io.modelset import save_model_set


def graph(tmp_path, body, name="g.yaml"):
    path = tmp_path / name
    path.write_text("flowtex: 1\nname: test\nrate: 1000\n" + body)
    return flowtex.load_graph(path)


COULOMB = """\
inputs:
  velocity: {{shape: [3], unit: mm/s}}
  normal_force: {{unit: N}}
nodes:
  f: {{type: coulomb_friction, params: {params}}}
edges:
  - velocity -> f.velocity
  - normal_force -> f.normal_force
outputs:
  force: f.force
"""


def expected_coulomb(vel, fn, mu, vth):
    out = np.zeros_like(vel)
    for i, (v, f) in enumerate(zip(vel, fn, strict=True)):
        speed = math.sqrt(v @ v)
        f = max(f, 0.0)
        out[i] = -mu * f * 0.004 * v if speed < vth else -mu * f * v / speed
    return out


@pytest.mark.parametrize("mode,vth", [("hatt", 0.5 / 0.004), ("continuous", 250.0)])
def test_coulomb_graph_matches_rule_and_chunks(tmp_path, mode, vth):
    g = graph(tmp_path, COULOMB.format(params=f"{{mu: 0.5, mode: {mode}}}"))
    rng = np.random.default_rng(0)
    direction = rng.normal(size=(600, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    speeds = rng.uniform(0, 400, 600)
    speeds[:6] = [0.0, vth, np.nextafter(vth, 0), vth * 1.0001, 250.0, 124.99]
    vel = direction * speeds[:, None]
    fn = rng.uniform(-0.2, 3.0, 600)
    out = g.run({"velocity": vel, "normal_force": fn})["force"]
    np.testing.assert_allclose(out, expected_coulomb(vel, fn, 0.5, vth), rtol=1e-12, atol=1e-15)
    g.reset()
    a = g.process({"velocity": vel[:99], "normal_force": fn[:99]})["force"]
    b = g.process({"velocity": vel[99:], "normal_force": fn[99:]})["force"]
    np.testing.assert_array_equal(np.concatenate([a, b]), out)


def test_coulomb_mu_from_a_model_set(tmp_path):
    ms = synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2, mu=0.37)
    save_model_set(ms, tmp_path / "surface.json")
    g = graph(tmp_path, COULOMB.format(params="{models: surface.json, mode: hatt}"))
    out = g.run({"velocity": np.array([[200.0, 0.0, 0.0]]), "normal_force": np.array([2.0])})["force"]
    np.testing.assert_allclose(out[0], [-0.37 * 2.0, 0.0, 0.0], rtol=1e-14)
    ms_none = synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2, mu=None)
    save_model_set(ms_none, tmp_path / "nomu.json")
    with pytest.raises(GraphError, match="no usable friction coefficient"):
        graph(tmp_path, COULOMB.format(params="{models: nomu.json}"))


def test_coulomb_param_errors_point_at_the_file(tmp_path):
    with pytest.raises(GraphError) as err:
        graph(tmp_path, COULOMB.format(params="{mode: hatt}"))
    assert "g.yaml:" in str(err.value) and "mu" in str(err.value)
    with pytest.raises(GraphError, match="either mu or models"):
        graph(tmp_path, COULOMB.format(params="{mu: 0.2, models: x.json}"))
    with pytest.raises(GraphError, match="x.json"):
        graph(tmp_path, COULOMB.format(params="{models: x.json}"))


DAHL = """\
inputs:
  position: {{shape: [3], unit: mm}}
  normal_force: {{unit: N}}
nodes:
  f: {{type: dahl_friction, params: {params}}}
edges:
  - position -> f.position
  - normal_force -> f.normal_force
outputs:
  force: f.force
"""


def published_dahl_1d(x, fn, mu, zmax):
    """002 eqs. (1)-(2) transcribed literally."""
    w = x[0]
    forces = [0.0]
    for i in range(1, len(x)):
        if abs(x[i] - w) > zmax:
            w = x[i] - math.copysign(1.0, x[i] - x[i - 1]) * zmax
        forces.append(-mu * fn[i] * (x[i] - w) / zmax)
    return np.array(forces)


def test_dahl_graph_default_zmax_is_4mm_mu_and_chunks(tmp_path):
    g = graph(tmp_path, DAHL.format(params="{mu: 0.3}"))
    rng = np.random.default_rng(4)
    x = np.cumsum(rng.normal(0, 0.1, 2000))
    pos = np.column_stack([x, np.zeros((2000, 2))])
    fn = np.full(2000, 0.9)
    out = g.run({"position": pos, "normal_force": fn})["force"]
    np.testing.assert_allclose(out[:, 0], published_dahl_1d(x, fn, 0.3, 1.2), rtol=1e-12, atol=1e-13)
    g.reset()
    a = g.process({"position": pos[:1500], "normal_force": fn[:1500]})["force"]
    b = g.process({"position": pos[1500:], "normal_force": fn[1500:]})["force"]
    np.testing.assert_array_equal(np.concatenate([a, b]), out)


def test_dahl_graph_explicit_zmax_and_normal_input(tmp_path):
    body = DAHL.format(params="{mu: 0.5, z_max: 0.5}").replace(
        "  normal_force: {unit: N}\n", "  normal_force: {unit: N}\n  normal: {shape: [3]}\n").replace(
        "  - normal_force -> f.normal_force\n", "  - normal_force -> f.normal_force\n  - normal -> f.normal\n")
    g = graph(tmp_path, body)
    ramp = np.linspace(0, 2, 21)
    normal = np.tile([1.0, 0.0, 0.0], (21, 1))
    pos = np.column_stack([np.zeros(21), ramp, ramp])  # tangential to x-normal: y and z both count
    out = g.run({"position": pos, "normal_force": np.full(21, 2.0), "normal": normal})["force"]
    stretch = np.minimum(ramp * math.sqrt(2), 0.5)
    np.testing.assert_allclose(out[:, 1], -0.5 * 2.0 * stretch / 0.5 / math.sqrt(2), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(out[:, 2], out[:, 1], rtol=1e-12, atol=1e-14)
    assert np.all(out[:, 0] == 0.0)


def test_coulomb_hatt_mode_with_mu_zero_renders_no_force(tmp_path):
    """mu = 0 in hatt mode puts the threshold at 0 mm/s; at rest that divided 0 by 0 (ZeroDivisionError)."""
    g = graph(tmp_path, COULOMB.format(params="{mu: 0.0, mode: hatt}"))
    vel = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]])
    out = g.run({"velocity": vel, "normal_force": np.array([1.0, 1.0])})["force"]
    np.testing.assert_array_equal(out, np.zeros((2, 3)))
