"""Patterned textures with known truth: features every 2 mm at 60 mm/s, 1 kHz, 5 % noise (issue 12; 004 ch. 4)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flowtex
from flowtex.cli import main
from flowtex.datasets.patterns import patterned_recording, render_features
from flowtex.dsp.spectral import welch_psd
from flowtex.errors import GraphError
from flowtex.fit.pattern import fit_pattern
from flowtex.io.patternfile import read_pattern, write_pattern
from flowtex.io.recordings import save_recording

GRAPH = """\
flowtex: 1
name: pattern
rate: 1000
inputs:
  position: {{shape: [3], unit: mm}}
nodes:
  tex: {{type: patterned_texture, params: {{pattern: {pattern}{extra}}}}}
edges:
  - position -> tex.position
outputs:
  y: tex.y
"""


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    rec = patterned_recording(seconds=2.0, seed=1)  # 60 features, 2 s keeps the fit ~2-4 s
    pat = fit_pattern(rec["accel"], rec["position"], rec["rate"], orders=range(2, 7))
    folder = tmp_path_factory.mktemp("pattern")
    write_pattern(folder / "p.json", pat)
    return rec, pat, folder


def _render(folder, position, extra=""):
    (folder / "g.yaml").write_text(GRAPH.format(pattern="p.json", extra=extra))
    return flowtex.load_graph(folder / "g.yaml").run({"position": position})["y"]


def test_fitted_spacing_within_2_percent(fitted):
    rec, pat, _ = fitted
    assert abs(pat.metadata["mean_spacing_mm"] / 2.0 - 1.0) < 0.02
    truth = rec["features_mm"][rec["features_mm"] <= rec["position"][-1, 0]]
    assert abs(pat.positions_mm.size - truth.size) <= 1  # one feature per true feature, no over-segmentation


def test_rendered_along_the_recorded_path_matches_the_psd(fitted):
    rec, pat, folder = fitted
    y = _render(folder, rec["position"])
    f, p_rec = welch_psd(rec["accel"], 1000.0, 256)
    _, p_out = welch_psd(y, 1000.0, 256)
    db_rec, db_out = 10 * np.log10(p_rec), 10 * np.log10(p_out)
    band = db_rec > db_rec.max() - 30.0  # frequencies within 30 dB of the peak
    lsd = np.sqrt(np.mean((db_rec - db_out)[band] ** 2))
    assert lsd < 1.5, lsd
    # SAD in 004 Table 1's sense (mean |fit - segment|), reported in the pattern's metadata; bounded by the 5 % noise
    noise_mad = 0.05 * np.sqrt(np.mean(rec["clean"] ** 2)) * np.sqrt(2 / np.pi)  # mean |N(0, s)| = s sqrt(2/pi)
    assert pat.metadata["mean_sad"] < 1.5 * noise_mad


def test_node_equals_the_sum_of_untruncated_ring_downs(fitted):
    _, pat, folder = fitted
    filters = list(zip(pat.b, pat.a, strict=True))
    for speed in (30.0, 60.0, 120.0):  # half, recorded, double speed
        n = int(80.0 / speed * 1000)
        x = 2.5 + speed * np.arange(n) / 1000.0
        pos = np.column_stack([x, np.full(n, 5.0), np.zeros(n)])
        y = _render(folder, pos)
        ref = render_features((pos - pat.origin) @ pat.axis, pat.positions_mm, pat.amplitudes, filters)
        # float64 reference: full-length scipy lfilter per crossing, summed; the node stops a ring-down below 1e-6 of its peak
        np.testing.assert_allclose(y, ref, atol=1e-4 * pat.amplitudes.max())
    # half speed: features recur every 2 mm, i.e. every 66.7 ticks (period doubled); autocorrelation peak there
    n = 4000
    pos = np.column_stack([2.5 + 30.0 * np.arange(n) / 1000.0, np.full(n, 5.0), np.zeros(n)])
    y = _render(folder, pos)
    ac = np.correlate(y, y, "full")[n - 1:]
    lag = 40 + int(np.argmax(ac[40:100]))
    assert abs(lag - 2.0 / 30.0 * 1000) <= 2


def test_backward_crossings_and_double_speed_overlap(fitted):
    _, pat, folder = fitted
    filters = list(zip(pat.b, pat.a, strict=True))
    x = np.concatenate([np.linspace(3.0, 20.0, 300), np.linspace(20.0, 3.0, 300)])  # there and back
    pos = np.column_stack([x, np.full(x.size, 5.0), np.zeros(x.size)])
    y = _render(folder, pos, extra=", max_active: 64")
    ref = render_features((pos - pat.origin) @ pat.axis, pat.positions_mm, pat.amplitudes, filters)
    np.testing.assert_allclose(y, ref, atol=1e-4 * pat.amplitudes.max())
    assert np.abs(y[320:]).max() > 0.1 * pat.amplitudes.min()  # the way back excites too
    # at double speed a feature comes every 16.7 ticks; the ring-downs last longer, so several sound at once and add
    from flowtex.dsp.patterns import RING_DECAY
    from flowtex.dsp.prony import ring_length

    assert np.median([ring_length(b, a, RING_DECAY) for b, a in filters]) > 2.0 / 120.0 * 1000


def test_bounded_active_ring_downs(fitted):
    _, pat, folder = fitted
    x = 2.5 + 120.0 * np.arange(1000) / 1000.0
    pos = np.column_stack([x, np.full(x.size, 5.0), np.zeros(x.size)])
    y1 = _render(folder, pos, extra=", max_active: 1")
    filters = list(zip(pat.b, pat.a, strict=True))
    # with one slot each new feature replaces the previous ring-down: equal to truncated superposition
    xs = (pos - pat.origin) @ pat.axis
    from flowtex.datasets.patterns import feature_crossings
    from flowtex.dsp.prony import impulse_response

    ref = np.zeros(x.size)
    cross = feature_crossings(xs, pat.positions_mm)
    for i, (t, k) in enumerate(cross):
        stop = cross[i + 1][0] if i + 1 < len(cross) else x.size
        ref[t:stop] = pat.amplitudes[k] * impulse_response(filters[k][0], filters[k][1], stop - t)
    np.testing.assert_allclose(y1, ref, atol=1e-4 * pat.amplitudes.max())


def test_cli_and_bad_pattern_files(tmp_path, capsys):
    rec = patterned_recording(seconds=1.0, seed=2)
    save_recording(tmp_path / "r.npz", {"a": rec["accel"], "p": rec["position"], "v": rec["speed"]}, rate=1000.0)
    assert main(["fit", "pattern", str(tmp_path / "r.npz"), "--accel", "a", "--position", "p", "--speed", "v", "--max-order", "4",
                 "-o", str(tmp_path / "pat.json")]) == 0
    assert "features" in capsys.readouterr().out
    pat = read_pattern(tmp_path / "pat.json")
    assert pat.metadata["mean_speed_mm_s"] == pytest.approx(60.0)
    doc = json.loads((tmp_path / "pat.json").read_text())
    doc["features"][3]["a"] = [1.0, -2.5, 1.5]  # poles 1.5 and 1: unstable
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    (tmp_path / "g.yaml").write_text(GRAPH.format(pattern="bad.json", extra=""))
    with pytest.raises(GraphError, match=r"bad.json: features\[3\]: the filter is unstable"):
        flowtex.load_graph(tmp_path / "g.yaml")
    doc["version"] = 7
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(GraphError, match="version 7 is not supported"):
        flowtex.load_graph(tmp_path / "g.yaml")
    assert main(["fit", "pattern", str(tmp_path / "r.npz"), "--accel", "a", "--position", "a", "-o", str(tmp_path / "x.json")]) == 1
    err = capsys.readouterr().err
    assert "signal 'a' (--position) has shape (" in err and "; expected (n, 3)" in err and not (tmp_path / "x.json").exists()
    save_recording(tmp_path / "flat.npz", {"a": np.zeros(500), "p": rec["position"][:500]}, rate=1000.0)
    assert main(["fit", "pattern", str(tmp_path / "flat.npz"), "--accel", "a", "--position", "p", "-o", str(tmp_path / "x.json")]) == 1
    assert "constant: there is no texture" in capsys.readouterr().err
    save_recording(tmp_path / "short.npz", {"a": rec["accel"][:20], "p": rec["position"][:20]}, rate=1000.0)
    assert main(["fit", "pattern", str(tmp_path / "short.npz"), "--accel", "a", "--position", "p", "-o", str(tmp_path / "x.json")]) == 1
    assert "needs at least 256" in capsys.readouterr().err and not (tmp_path / "x.json").exists()


def test_chunked_and_live_runs_equal_one_pass(fitted):
    rec, _, folder = fitted
    pos = rec["position"][:400]
    (folder / "g.yaml").write_text(GRAPH.format(pattern="p.json", extra=", max_active: 4"))
    g = flowtex.load_graph(folder / "g.yaml")
    whole = g.run({"position": pos})["y"]
    g.reset()
    parts = [g.process({"position": pos[a:b]})["y"] for a, b in [(0, 1), (1, 37), (37, 400)]]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    g.reset()
    live = [g.step({"position": p})["y"] for p in pos[:50]]
    np.testing.assert_array_equal(np.asarray(live, float), whole[:50])
