"""Non-finite recording samples: refused by default, or held / zeroed on request (issue 9 item 2)."""

from __future__ import annotations

import numpy as np
import pytest

import flowtex
from flowtex.cli import main
from flowtex.dsp.nonfinite import fill_nonfinite, find_nonfinite
from flowtex.errors import DataError
from flowtex.io.recordings import load_recording, save_recording

# A recursive filter: one NaN would poison its state for every later tick.
GRAPH = """
flowtex: 1
name: nf
rate: 1000
inputs:
  acc: {unit: m/s^2}
  pos: {shape: [2], unit: mm}
nodes:
  lp: {type: first_order_lowpass, params: {cutoff_hz: 30}}
  g: {type: gain, params: {k: 1}}
edges:
  - acc -> lp.x
  - pos -> g.x
outputs:
  smooth: lp.y
  p: g.y
"""


def _hold_reference(a: np.ndarray) -> np.ndarray:
    """Loop version of 'hold': last finite value per channel, 0 before any."""
    flat = a.reshape(a.shape[0], -1)
    out = np.zeros_like(flat)
    for c in range(flat.shape[1]):
        last = 0.0
        for t in range(flat.shape[0]):
            if np.isfinite(flat[t, c]):
                last = flat[t, c]
            out[t, c] = last
    return out.reshape(a.shape)


def test_find_and_fill_nonfinite():
    a = np.array([[np.nan, 1.0], [2.0, np.inf], [3.0, 4.0], [-np.inf, np.nan]])
    found = find_nonfinite(a)
    assert (found.count, found.first_index) == (3, 0) and np.isnan(found.first_value)
    assert find_nonfinite(np.ones((4, 2))) is None
    np.testing.assert_array_equal(fill_nonfinite(a, "hold"), _hold_reference(a))
    np.testing.assert_array_equal(fill_nonfinite(a, "hold"), [[0, 1], [2, 1], [3, 4], [3, 4]])
    np.testing.assert_array_equal(fill_nonfinite(a, "zero"), [[0, 1], [2, 0], [3, 4], [0, 0]])
    assert np.isnan(a[0, 0])  # the input is not modified


def _recording(n=8000):
    rng = np.random.default_rng(1)
    acc = rng.standard_normal(n)
    acc[100] = np.nan
    pos = rng.standard_normal((n, 2))
    pos[[7, 9], 1] = np.inf
    return {"acc": acc, "pos": pos}


def test_graph_run_policies(write_graph):
    g = flowtex.load_graph(write_graph(GRAPH))
    rec = _recording(600)
    with pytest.raises(DataError, match=r"input 'acc' has 1 non-finite sample\(s\), the first \(nan\) at index 100"):
        g.run(rec)
    held = g.run(rec, nonfinite="hold")
    assert all(np.isfinite(v).all() for v in held.values())
    clean = {k: fill_nonfinite(v, "hold") for k, v in rec.items()}
    ref = g.run(clean)
    for k in ref:
        np.testing.assert_array_equal(held[k], ref[k])
    zeroed = g.run(rec, nonfinite="zero")
    np.testing.assert_array_equal(zeroed["p"][7], [rec["pos"][7, 0], 0.0])
    with pytest.raises(flowtex.errors.FlowtexError, match="unknown non-finite policy"):
        g.run(rec, nonfinite="ignore")


def test_cli_run_refuses_nan_recording_and_names_it(write_graph, tmp_path, capsys):
    graph = write_graph(GRAPH)
    src = tmp_path / "rec.npz"
    save_recording(src, _recording(), rate=1000)
    out = tmp_path / "out.npz"
    assert main(["run", str(graph), "-i", str(src), "-o", str(out), "--no-plugins"]) == 1
    err = capsys.readouterr().err.strip()
    assert err == (f"{src}: input 'acc' has 1 non-finite sample(s), the first (nan) at index 100; clean the recording "
                   "or pass --nonfinite hold (last finite value) or --nonfinite zero")
    assert not out.exists()
    assert main(["run", str(graph), "-i", str(src), "-o", str(out), "--nonfinite", "hold"]) == 0
    result = load_recording(out).arrays
    assert np.isfinite(result["smooth"]).all() and np.isfinite(result["p"]).all()
    np.testing.assert_array_equal(result["p"][9], [_recording()["pos"][9, 0], _recording()["pos"][8, 1]])
