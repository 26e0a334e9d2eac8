"""flowtex fit friction and flowtex fit taps against ground truth (flowtex.datasets)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import friction_session, tap_session
from flowtex.fit.friction import fit_friction
from flowtex.io.taplib import read_tap_library
from flowtex.models.taps import spectral_centroid


@pytest.mark.parametrize("offset", [0.0, 0.05])
def test_mu_within_3_percent(offset):
    """mu within 3 % (the issue's tolerance) with 10 % tangential noise, stiction spikes and lift-offs.

    The estimate's own spread is far smaller (its 95 % interval is ~0.2 % wide
    for 18000 samples), so 3 % leaves room for the spikes' residual pull.
    """
    rec = friction_session(mu=0.4, duration_s=20.0, seed=3, offset=offset, spikes=25, lifts=4)
    a = rec.arrays
    fit = fit_friction(a["normal_force"], a["tangential_force"], offset=bool(offset))
    assert fit.mu == pytest.approx(0.4, rel=0.03)
    assert fit.in_contact < a["normal_force"].size  # the lift-offs were left out
    assert fit.rejected > 0                         # the stiction spikes got weight 0
    if offset:
        assert fit.offset == pytest.approx(offset, abs=0.01)
        m = a["normal_force"] >= 0.1
        ratio = np.median(a["tangential_force"][m] / a["normal_force"][m])
        assert abs(ratio / 0.4 - 1) > 0.03  # why not the median of ratios: the offset biases it


def test_friction_cli_into(tmp_path, capsys):
    rec = friction_session(mu=0.55, duration_s=8.0, seed=1)
    path = rec.save(tmp_path / "fr.csv")
    out = tmp_path / "mu.json"
    assert main(["fit", "friction", str(path), "--force", "force", "--normal", "0,0,1", "-o", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["mu"] == pytest.approx(0.55, rel=0.03) and doc["mu_ci"][0] < doc["mu"] < doc["mu_ci"][1]
    capsys.readouterr()
    lifted = 0.01 * np.random.default_rng(0).standard_normal(rec.arrays["normal_force"].size)  # sensor noise only
    bad = rec.arrays | {"normal_force": lifted}
    from flowtex.io.recordings import save_recording

    save_recording(tmp_path / "none.npz", bad, rec.rate)
    assert main(["fit", "friction", str(tmp_path / "none.npz"), "--force", "normal_force", "--friction-force",
                 "tangential_force", "-o", str(tmp_path / "x.json")]) == 1
    assert "no contact anywhere" in capsys.readouterr().err and not (tmp_path / "x.json").exists()


def test_taps_found_and_centroid(tmp_path, capsys):
    """Every tap found (onset within 2 ms), none invented, speeds exact to 2 %, centroid within 5 % of the truth's."""
    speeds = (25.0, 45.0, 60.0, 75.0, 95.0, 130.0, 170.0)
    rec = tap_session(speeds=speeds, seed=4)
    path = rec.save(tmp_path / "taps.npz")
    out = tmp_path / "lib.json"
    assert main(["fit", "taps", str(path), "--accel", "accel", "--force", "normal_force", "--position", "position", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "spectral centroid over 50-100 mm/s" in printed
    lib = read_tap_library(out)
    assert lib.speeds.size == len(speeds)
    np.testing.assert_allclose(lib.speeds, speeds, rtol=0.02)  # constant approach speed: the difference is exact
    onsets = [int(line.split()[1].replace(".", "")) for line in printed.splitlines()[1:1 + len(speeds)]]
    assert np.all(np.abs(np.array(onsets) - rec.truth["onsets"]) <= 2)
    assert spectral_centroid(lib) == pytest.approx(spectral_centroid(rec.truth["library"]), rel=0.05)
