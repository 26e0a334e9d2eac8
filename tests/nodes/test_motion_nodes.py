"""speed_estimator and contact nodes in real graphs built from YAML."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import butter, lfilter

import flowtex
from flowtex.errors import GraphError

FS = 1000.0


def graph(tmp_path, body, name="g.yaml"):
    path = tmp_path / name
    path.write_text("flowtex: 1\nname: test\nrate: 1000\n" + body)
    return flowtex.load_graph(path)


SPEED_GRAPH = """\
inputs:
  position: {{shape: [3], unit: mm}}
nodes:
  est: {{type: speed_estimator, params: {params}}}
edges:
  - position -> est.position
outputs:
  speed: est.speed
  velocity: est.velocity
"""


def path3(n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    return np.stack([30 * np.sin(2 * np.pi * 1.1 * t), 20 * np.sin(2 * np.pi * 0.6 * t + 1), 5 * t], 1) + rng.normal(0, 0.005, (n, 3))


def backward_difference(pos):
    v = np.zeros_like(pos)
    v[1:] = np.diff(pos, axis=0) * FS
    return v


def test_lowpass_graph_matches_lfilter_and_chunks(tmp_path):
    g = graph(tmp_path, SPEED_GRAPH.format(params="{cutoff_hz: 15, stationary_mm: 0}"))
    pos = path3(2500)
    out = g.run({"position": pos})
    alpha = 1 - math.exp(-2 * math.pi * 15 / FS)
    ref = lfilter([alpha], [1, alpha - 1], backward_difference(pos), axis=0)
    ref[:, 2] = 0.0  # default normal [0, 0, 1]
    np.testing.assert_allclose(out["velocity"], ref, rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(out["speed"], np.linalg.norm(ref, axis=1), rtol=1e-10, atol=1e-9)
    g.reset()
    a = g.process({"position": pos[:1234]})
    b = g.process({"position": pos[1234:]})
    np.testing.assert_array_equal(np.concatenate([a["speed"], b["speed"]]), out["speed"])
    np.testing.assert_array_equal(np.concatenate([a["velocity"], b["velocity"]]), out["velocity"])


def test_hatt_graph_matches_butterworth_and_live_steps(tmp_path):
    g = graph(tmp_path, SPEED_GRAPH.format(params="{method: hatt, stationary_mm: 0}"))
    pos = path3(800, seed=2)
    out = g.run({"position": pos})
    b, a = butter(2, 125 / (2 * np.pi), fs=FS)
    ref = lfilter(b, a, backward_difference(pos), axis=0)
    ref[:, 2] = 0.0
    np.testing.assert_allclose(out["velocity"], ref, rtol=1e-9, atol=1e-8)
    g.reset()
    live = np.array([g.step({"position": row})["speed"] for row in pos])
    np.testing.assert_array_equal(live, out["speed"])


def test_normal_as_input_and_stationary_default(tmp_path):
    body = """\
inputs:
  position: {shape: [3], unit: mm}
  normal: {shape: [3]}
nodes:
  est: {type: speed_estimator}
edges:
  - position -> est.position
  - normal -> est.normal
outputs:
  speed: est.speed
"""
    g = graph(tmp_path, body)
    n = 1000
    t = np.arange(n) / FS
    normal = np.tile([0.6, 0.0, 0.8], (n, 1))
    pos = np.outer(40 * t, normal[0])  # moving along the normal only
    assert np.max(g.run({"position": pos, "normal": normal})["speed"]) < 1e-9
    jitter = np.random.default_rng(1).uniform(-0.02, 0.02, (n, 3))
    assert np.all(g.run({"position": jitter, "normal": normal})["speed"] == 0.0)  # 0.06 mm gate by default
    slide = np.outer(40 * t, [0.8, 0.0, -0.6]) + jitter
    assert np.mean(g.run({"position": slide, "normal": normal})["speed"][500:]) == pytest.approx(40.0, rel=0.03)


def test_zero_normal_parameter_is_refused_with_location(tmp_path):
    with pytest.raises(GraphError) as err:
        graph(tmp_path, SPEED_GRAPH.format(params="{normal: [0, 0, 0]}"))
    text = str(err.value)
    assert "g.yaml:" in text and "normal" in text and "zero length" in text


CONTACT_GRAPH = """\
inputs:
  position: {shape: [3], unit: mm}
  normal_force: {unit: N}
nodes:
  c: {type: contact, params: {on_n: 0.2, off_n: 0.1}}
edges:
  - position -> c.position
  - normal_force -> c.normal_force
outputs:
  in_contact: c.in_contact
  incoming: c.incoming_speed
  onset: c.onset
"""


def test_contact_graph_hysteresis_incoming_speed_and_chunks(tmp_path):
    g = graph(tmp_path, CONTACT_GRAPH)
    n = 400
    t = np.arange(n) / FS
    z = np.where(t < 0.1, 5 - 30 * t, 2 + 0 * t)  # approach at 30 mm/s, then rest
    z = np.where((t >= 0.2) & (t < 0.3), 2 + 50 * (t - 0.2), z)
    z = np.where(t >= 0.3, 7 - 60 * (t - 0.3), z)
    pos = np.stack([np.zeros(n), np.zeros(n), z], 1)
    force = np.zeros(n)
    force[[50, 51, 52]] = [0.15, 0.2, 0.3]       # onset at 51 (>= 0.2)
    force[53:150] = 0.15                          # stays in contact (>= 0.1)
    force[150] = 0.05                             # released
    force[360:] = 0.5                             # second onset at 360
    out = g.run({"position": pos, "normal_force": force})
    onsets = np.flatnonzero(out["onset"])
    np.testing.assert_array_equal(onsets, [51, 360])
    np.testing.assert_array_equal(np.flatnonzero(out["in_contact"]), np.r_[51:150, 360:400])
    assert out["incoming"][51:150] == pytest.approx(np.full(99, 30.0), rel=1e-9)
    assert out["incoming"][360:] == pytest.approx(np.full(40, 60.0), rel=1e-9)
    assert np.all(out["incoming"][150:360] == 0.0)
    g.reset()
    a = g.process({"position": pos[:51], "normal_force": force[:51]})
    b = g.process({"position": pos[51:], "normal_force": force[51:]})
    for key in out:
        np.testing.assert_array_equal(np.concatenate([a[key], b[key]]), out[key])


def test_contact_off_above_on_is_refused(tmp_path):
    with pytest.raises(GraphError, match="off_n"):
        graph(tmp_path, CONTACT_GRAPH.replace("off_n: 0.1", "off_n: 0.3"))


def test_default_cutoff_is_20_hz_and_hatt_refuses_a_cutoff(tmp_path):
    g = graph(tmp_path, SPEED_GRAPH.format(params="{stationary_mm: 0}"))
    pos = path3(300, seed=4)
    alpha = 1 - math.exp(-2 * math.pi * 20 / FS)
    ref = lfilter([alpha], [1, alpha - 1], backward_difference(pos), axis=0)
    ref[:, 2] = 0.0
    np.testing.assert_allclose(g.run({"position": pos})["velocity"], ref, rtol=1e-10, atol=1e-9)
    with pytest.raises(GraphError, match="fixed 125 rad/s"):
        graph(tmp_path, SPEED_GRAPH.format(params="{method: hatt, cutoff_hz: 30}"), name="h.yaml")
