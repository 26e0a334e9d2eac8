"""Issue 9 item 10: --set did-you-mean, step()/run() input errors, units in output files, filter initial state."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.signal import butter, sosfilt, sosfilt_zi

import flowtex
from flowtex.cli import main
from flowtex.errors import FlowtexError
from flowtex.io.recordings import load_recording, save_recording

GRAPH = """
flowtex: 1
name: small
rate: 1000
inputs:
  acc: {shape: [3], unit: m/s^2}
  f: {unit: N}
nodes:
  hp: {type: butterworth, params: {kind: highpass, order: 3, cutoff_hz: 20, init: steady}}
  lp: {type: first_order_lowpass, params: {cutoff_hz: 10, init: steady}}
  lp0: {type: first_order_lowpass, params: {cutoff_hz: 10}}
edges:
  - acc -> hp.x
  - f -> lp.x
  - f -> lp0.x
outputs:
  vib: hp.y
  force: lp.y
  force0: lp0.y
"""


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    path = tmp_path_factory.mktemp("small") / "g.yaml"
    path.write_text(GRAPH.lstrip())
    return path, flowtex.load_graph(path)


def _inputs(n=500):
    rng = np.random.default_rng(4)
    acc = 0.1 * rng.standard_normal((n, 3)) + [0.0, 0.0, -9.81]  # gravity from the first sample
    return {"acc": acc, "f": 2.0 + 0.1 * rng.standard_normal(n)}


def test_steady_init_matches_sosfilt_zi(graph):
    _, g = graph
    x = _inputs()
    out = g.run(x)
    sos = butter(3, 20, "highpass", fs=1000, output="sos")
    for c in range(3):
        ref = sosfilt(sos, x["acc"][:, c], zi=sosfilt_zi(sos) * x["acc"][0, c])[0]
        # Different state layouts (DF-I here, DF-II transposed in scipy): rounding of ~10 ops on 10 m/s^2 values.
        np.testing.assert_allclose(out["vib"][:, c], ref, rtol=0, atol=1e-12)
    assert abs(out["vib"][0, 2]) < 0.5  # no -9.81 m/s^2 spike on the first sample
    alpha = 1 - np.exp(-2 * np.pi * 10 / 1000)
    ref = sosfilt([[alpha, 0, 0, 1, alpha - 1, 0]], x["f"], zi=[[x["f"][0] * (1 - alpha), 0]])[0]  # y[-1] = x[0]
    np.testing.assert_allclose(out["force"], ref, rtol=1e-13, atol=0)
    assert out["force0"][0] == pytest.approx(alpha * x["f"][0], rel=1e-15)  # default init stays at rest
    g.reset()  # steady init applies again after a reset, and chunked runs equal one pass
    parts = [g.process({k: v[a:b] for k, v in x.items()}) for a, b in ((0, 1), (1, 200), (200, 500))]
    np.testing.assert_array_equal(np.concatenate([p["vib"] for p in parts]), out["vib"])


def test_step_wrong_shape_and_run_unknown_key(graph):
    _, g = graph
    with pytest.raises(FlowtexError, match=r"^input 'acc' has shape \(3,\) \(3 numbers\); step\(\) got shape \(2,\)$"):
        g.step({"acc": [1.0, 2.0]})
    x = _inputs(10)
    with pytest.raises(FlowtexError, match=r"^graph 'small' has no input\(s\) 'acc_z' \(did you mean 'acc'\?\); its inputs are: acc, f$"):
        g.run({**x, "acc_z": x["f"]})


def test_set_with_wrong_node_gets_did_you_mean(graph, capsys):
    path, _ = graph
    assert main(["validate", str(path), "--set", "hq.cutoff_hz=30"]) == 1
    err = capsys.readouterr().err.strip()
    assert err == "--set hq.cutoff_hz: no node 'hq' in the graph (did you mean 'hp.cutoff_hz' or 'lp.cutoff_hz' or " \
                  "'lp0.cutoff_hz'?); nodes are: hp, lp, lp0"
    assert main(["validate", str(path), "--set", "hp.cutof_hz=30"]) == 1
    assert "unknown parameter 'cutof_hz' (did you mean 'cutoff_hz'?)" in capsys.readouterr().err


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".h5"])
def test_outputs_carry_units_and_still_load(graph, tmp_path, suffix, capsys):
    path, _ = graph
    src = tmp_path / "in.npz"
    save_recording(src, _inputs(50), rate=1000)
    dst = tmp_path / f"out{suffix}"
    assert main(["run", str(path), "-i", str(src), "-o", str(dst)]) == 0
    capsys.readouterr()
    rec = load_recording(dst)
    assert rec.units == {"vib": "m/s^2", "force": "N", "force0": "N"}
    assert sorted(rec.arrays) == ["force", "force0", "vib"] and rec.rate == 1000
    if suffix == ".csv":
        assert dst.read_text().splitlines()[1] == "# units: " + json.dumps({"vib": "m/s^2", "force": "N", "force0": "N"})
