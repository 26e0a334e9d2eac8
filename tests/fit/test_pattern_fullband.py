"""Issue 18 (8): patterns fitted over the whole band, order by BIC; issue's recordings: features every 2 mm, 60 mm/s, 1 kHz,
a 120 Hz resonance with pole radius 0.9 (plus, for two-resonance features, 300 Hz at radius 0.85), amplitude +-20 %, 5 % noise."""

from __future__ import annotations

import numpy as np
import pytest

import flowtex
from flowtex.cli import main
from flowtex.datasets.patterns import feature_crossings, patterned_recording, pole_decay_s
from flowtex.dsp.prony import impulse_response
from flowtex.dsp.spectral import welch_psd
from flowtex.fit.pattern import fit_pattern
from flowtex.io.patternfile import write_pattern
from flowtex.io.recordings import save_recording

RATE = 1000.0
GRAPH = """\
flowtex: 1
name: pattern
rate: 1000
inputs:
  position: {shape: [3], unit: mm}
nodes:
  tex: {type: patterned_texture, params: {pattern: p.json}}
edges:
  - position -> tex.position
outputs:
  y: tex.y
"""
CASES = {"one": (), "two": ((300.0, pole_decay_s(0.85, RATE)),)}


@pytest.fixture(scope="module", params=sorted(CASES))
def fitted(request, tmp_path_factory):
    rec = patterned_recording(seconds=2.0, freq_hz=120.0, decay_s=pole_decay_s(0.9, RATE), spread=0.2, noise=0.05, seed=4,
                              extra=CASES[request.param])
    pat = fit_pattern(rec["accel"], rec["position"], RATE)
    folder = tmp_path_factory.mktemp(request.param)
    write_pattern(folder / "p.json", pat)
    (folder / "g.yaml").write_text(GRAPH)
    y = flowtex.load_graph(folder / "g.yaml").run({"position": rec["position"]})["y"]
    return request.param, rec, pat, y


def test_rendered_psd_matches_over_the_whole_band(fitted):
    """LSD < 1.5 dB (the issue's bound) over every frequency within 30 dB of the peak, and no tilt at either end of the band."""
    _, rec, _, y = fitted
    f, p_rec = welch_psd(rec["accel"], RATE, 256)
    _, p_out = welch_psd(y, RATE, 256)
    diff = 10 * np.log10(p_rec) - 10 * np.log10(p_out)
    band = 10 * np.log10(p_rec) > 10 * np.log10(p_rec.max()) - 30.0
    assert np.sqrt(np.mean(diff[band] ** 2)) < 1.5
    for part in (band & (f < 100.0), band & (f > 200.0)):  # were 3-4 dB low below 100 Hz and 3-5 dB high above 200 Hz
        assert abs(np.mean(diff[part])) < 1.0


def test_one_feature_per_feature_and_each_amplitude_reproduced(fitted):
    """Each feature's ring-down energy within 8 % of its true one (measured: within 4 %, the 5 % noise's share)."""
    _, rec, pat, _ = fitted
    x = (rec["position"] - pat.origin) @ pat.axis
    truth = feature_crossings(x, rec["features_mm"] - pat.origin[0])
    assert len(truth) == pat.positions_mm.size
    ticks = np.array([t for t, _ in truth])
    fitted_ticks = np.searchsorted(x, pat.positions_mm)
    assert np.all(fitted_ticks == ticks)  # each feature excites on its own crossing tick
    b, a = rec["filter"]
    true_energy = np.array([rec["amplitudes"][k] for _, k in truth]) * np.linalg.norm(impulse_response(b, a, 400))
    energy = np.array([amp * np.linalg.norm(impulse_response(bk, ak, 400)) for amp, bk, ak in zip(pat.amplitudes, pat.b, pat.a, strict=True)])
    np.testing.assert_allclose(energy, true_energy, rtol=0.08)


def test_order_is_the_simplest_that_explains(fitted):
    """BIC: two poles (+ the onset's numerator) for one resonance, four to six for two; the old least-SAD rule gave about 7."""
    name, _, pat, _ = fitted
    orders = np.array([len(a) - 1 for a in pat.a])
    lo, hi = (2, 3) if name == "one" else (4, 6)
    assert lo <= np.median(orders) <= hi
    assert pat.metadata["order_criterion"] == "BIC"


def test_constant_position_is_refused_in_one_line(tmp_path, capsys):
    rec = patterned_recording(seconds=1.0, seed=2)
    still = np.tile(rec["position"][:1], (rec["accel"].size, 1))
    save_recording(tmp_path / "still.npz", {"a": rec["accel"], "p": still}, rate=RATE)
    assert main(["fit", "pattern", str(tmp_path / "still.npz"), "--accel", "a", "--position", "p", "-o", str(tmp_path / "x.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "needs the tool to travel" in err and not (tmp_path / "x.json").exists()
