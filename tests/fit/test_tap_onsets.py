"""Issue 18 (4): a tap onset counts only after a stretch without contact; recordings that start in contact get no tap at t = 0."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import tap_session
from flowtex.errors import DataError
from flowtex.fit.taps import DEFAULT_QUIET_S, contact_onsets, fit_taps
from flowtex.io.recordings import save_recording

RATE = 1000.0


def _dragging(n, seed=0):
    """Sliding in contact the whole time (as issue 18's real recordings): force 1 +- 0.3 N, texture-like accel."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    return 1.0 + 0.3 * np.sin(2 * np.pi * 0.4 * t) + 0.005 * rng.standard_normal(n), rng.standard_normal(n)


def test_recording_in_contact_throughout_has_no_tap(tmp_path, capsys):
    force, accel = _dragging(19000)
    assert contact_onsets(force).size == 0
    with pytest.raises(DataError, match="starts in contact has no tap at its start"):
        fit_taps(accel, force, RATE, speed=np.full(force.size, 60.0))
    path = tmp_path / "drag.npz"
    save_recording(path, {"accel": accel, "normal_force": force, "speed": np.full(force.size, 60.0)}, RATE)
    assert main(["fit", "taps", str(path), "--accel", "accel", "--force", "normal_force", "--speed", "speed",
                 "-o", str(tmp_path / "lib.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no tap" in err and not (tmp_path / "lib.json").exists()


def test_contact_at_the_start_then_real_taps():
    """1 s of dragging, then lift-off and taps: the taps are found (onset within 2 ms), nothing at t = 0."""
    rec = tap_session(speeds=(40.0, 90.0, 150.0), seed=1)
    lead = 1000
    force0, accel0 = _dragging(lead, seed=2)
    force = np.concatenate([force0, rec.arrays["normal_force"]])
    accel = np.concatenate([accel0, rec.arrays["accel"]])
    position = np.concatenate([np.zeros((lead, 3)), rec.arrays["position"]])
    taps, _notes = fit_taps(accel, force, RATE, position=position)
    onsets = np.array([t.onset for t in taps])
    assert onsets.size == 3 and np.all(np.abs(onsets - lead - rec.truth["onsets"]) <= 2)  # test_taps_found_and_centroid's 2 ms
    np.testing.assert_allclose([t.speed for t in taps], (40.0, 90.0, 150.0), rtol=0.02)


def test_quiet_stretch_decides_bounce_or_new_tap():
    """A dip below 0.05 N shorter than the quiet stretch is part of the tap; a longer one ends it."""
    quiet = int(DEFAULT_QUIET_S * RATE)
    force = np.zeros(2000)
    force[500:1500] = 1.0
    bounce = force.copy()
    bounce[700:700 + quiet // 2] = 0.0
    assert contact_onsets(bounce, quiet=quiet).tolist() == [500]
    lifted = force.copy()
    lifted[700:700 + quiet + 5] = 0.0
    assert contact_onsets(lifted, quiet=quiet).tolist() == [500, 700 + quiet + 5]
    early = force.copy()
    early[: quiet - 10] = 0.0  # out of contact for less than the stretch, then in contact from sample 40
    early[quiet - 10:500] = 1.0
    assert contact_onsets(early, quiet=quiet).tolist() == []
