"""tap_player in real graphs: contact -> tap_player, library paths, rate checks, malformed libraries."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flowtex
from flowtex.datasets.taps import synthetic_tap_library
from flowtex.errors import GraphError
from flowtex.io.taplib import write_tap_library

TAPS = {"format": "flowtex-tap-library", "version": 1, "name": "hand", "sample_rate_hz": 1000,
        "taps": [{"speed": 100, "acceleration": [-7, 0, 7, 1, -1]},
                 {"speed": 20, "acceleration": [1, -2, 3, -4, 5]},
                 {"speed": 50, "acceleration": [10, 20, -30, 40]}]}
T20 = np.array([1.0, -2, 3, -4, 5])
T50 = np.array([10.0, 20, -30, 40, 0])
T100 = np.array([-7.0, 0, 7, 1, -1])

GRAPH = """\
flowtex: 1
name: taps
rate: {rate}
inputs:
  position: {{shape: [3], unit: mm}}
  normal_force: {{unit: N}}
nodes:
  c: {{type: contact, params: {{on_n: 0.2, off_n: 0.1}}}}
  tap:
    type: tap_player
    params: {{library: {library}{extra}}}
edges:
  - position -> c.position
  - normal_force -> c.normal_force
  - c.in_contact -> tap.in_contact
  - c.incoming_speed -> tap.incoming_speed
outputs:
  force: tap.force
  onset: c.onset
"""


def make(tmp_path, library="libs/hand.json", rate=1000, extra="", doc=TAPS):
    folder = tmp_path / "graphs"
    (folder / "libs").mkdir(parents=True, exist_ok=True)
    (folder / "libs" / "hand.json").write_text(json.dumps(doc))
    path = folder / "g.yaml"
    path.write_text(GRAPH.format(rate=rate, library=library, extra=extra))
    return path


def taps_recording(speeds, starts, n=120):
    """Tool rests at z = 0, each tap approaches along -z at the given speed for 3 ticks before its start."""
    z = np.zeros(n)
    force = np.zeros(n)
    for v, start in zip(speeds, starts, strict=True):
        z[start - 3:start + 1] = v / 1000.0 * np.arange(3, -1, -1)  # moving down at v mm/s, reaching 0 at start
        force[start:start + 8] = 1.0
    pos = np.column_stack([np.zeros(n), np.zeros(n), z])
    return {"position": pos, "normal_force": force}


def test_contact_then_taps_for_every_branch(tmp_path):
    g = flowtex.load_graph(make(tmp_path, extra=", mass: 0.1"))
    speeds = [10.0, 35.0, 80.0, 300.0]
    starts = [10, 30, 50, 70]
    out = g.run(taps_recording(speeds, starts))
    np.testing.assert_array_equal(np.flatnonzero(out["onset"]), starts)
    expected = np.zeros(120)
    expected[10:15] = 0.1 * 0.5 * T20
    expected[30:35] = 0.1 * (0.5 * T20 + 0.5 * T50)
    expected[50:55] = 0.1 * (0.4 * T50 + 0.6 * T100)
    expected[70:75] = 0.1 * T100
    np.testing.assert_allclose(out["force"], expected, rtol=1e-9, atol=1e-12)


def test_chunked_run_equals_one_pass(tmp_path):
    g = flowtex.load_graph(make(tmp_path))
    n = 60
    z = np.zeros(n)
    z[19] = 0.04  # 40 mm/s approach into the onset at 20
    z[22] = 0.09  # 90 mm/s approach into the onset at 23
    force = np.zeros(n)
    force[20:22] = 1.0  # released at 22, while the first transient still plays
    force[23:30] = 1.0
    rec = {"position": np.column_stack([np.zeros((n, 2)), z]), "normal_force": force}
    whole = g.run(rec)["force"]
    expected = np.zeros(n)
    expected[20:23] = 0.05 * (1 / 3 * T20 + 2 / 3 * T50)[:3]  # 40 mm/s: u = (40-20)/(50-20) = 2/3 on T50
    expected[23:28] = 0.05 * (0.2 * T50 + 0.8 * T100)  # restarted at 90 mm/s
    np.testing.assert_allclose(whole, expected, rtol=1e-9, atol=1e-12)
    g.reset()
    a = g.process({k: v[:23] for k, v in rec.items()})["force"]
    b = g.process({k: v[23:] for k, v in rec.items()})["force"]
    np.testing.assert_array_equal(np.concatenate([a, b]), whole)


def test_synthetic_library_written_and_played(tmp_path):
    lib = synthetic_tap_library()
    folder = tmp_path / "graphs"
    path = make(tmp_path, library="synth.json")
    write_tap_library(folder / "synth.json", lib)
    out = flowtex.load_graph(path).run(taps_recording([100.0], [10], n=150))["force"]
    np.testing.assert_allclose(out[10:110], 0.05 * lib.transients[2], rtol=1e-12, atol=1e-15)
    assert np.all(out[110:] == 0.0) and np.all(out[:10] == 0.0)


def test_rate_mismatch_is_refused_with_both_rates(tmp_path):
    with pytest.raises(GraphError) as err:
        flowtex.load_graph(make(tmp_path, rate=2000))
    text = str(err.value)
    assert "g.yaml:" in text and "hand.json" in text and "1000 Hz" in text and "2000 Hz" in text


def test_missing_and_malformed_libraries_name_file_and_field(tmp_path):
    with pytest.raises(GraphError, match="nope.json: tap library file not found"):
        flowtex.load_graph(make(tmp_path, library="nope.json"))
    bad = json.loads(json.dumps(TAPS))
    bad["taps"][2]["speed"] = "fast"
    with pytest.raises(GraphError) as err:
        flowtex.load_graph(make(tmp_path, doc=bad))
    assert "hand.json" in str(err.value) and "taps[2].speed" in str(err.value)
