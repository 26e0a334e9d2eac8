"""Every fit reads its recording's signals through one reader (flowtex.fit.inputs.signal): one message per mistake."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.io.recordings import save_recording

N = 3000


@pytest.fixture()
def recording(tmp_path):
    t = np.arange(N) / 1000.0
    accel = np.sin(2 * np.pi * 90.0 * t)
    accel[[7, 1200]] = np.nan
    arrays = {"a": accel, "f": 1.0 + 0.5 * np.sin(2 * np.pi * 0.5 * t), "v": np.full(N, 50.0),
              "p": np.column_stack([50.0 * t, np.zeros(N), np.zeros(N)])}
    path = tmp_path / "r.npz"
    save_recording(path, arrays, rate=1000.0)
    return path


KINDS = {
    "texture": ["--accel", "a", "--force", "f", "--speed", "v"],
    "taps": ["--accel", "a", "--force", "f", "--speed", "v"],
    "pattern": ["--accel", "a", "--position", "p"],
    "compliance": ["--accel", "a", "--force", "f"],
}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_fit_refuses_a_bad_signal_with_the_same_line(kind, recording, tmp_path, capsys):
    out = tmp_path / "out.json"
    assert main(["fit", kind, str(recording), *KINDS[kind], "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"{recording}: signal 'a' (--accel): 2 NaN/inf sample(s) (at sample 7, 1200); "
                        "interpolate or cut them out first"), err
    assert not out.exists()


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_fit_names_a_missing_signal_and_what_the_file_has(kind, recording, tmp_path, capsys):
    args = [("nope" if a == "a" else a) for a in KINDS[kind]]
    assert main(["fit", kind, str(recording), *args, "-o", str(tmp_path / "out.json")]) == 1
    assert f"{recording}: no signal 'nope' (--accel); the file has: a, f, p, v" in capsys.readouterr().err


def test_fit_texture_on_a_speed_in_m_per_s_says_to_check_the_unit(tmp_path, capsys):
    """A speed in m/s (0.05 for 50 mm/s) fitted nothing with "none is moving", which does not point at the unit."""
    path = tmp_path / "ms.npz"
    save_recording(path, {"a": np.random.default_rng(0).standard_normal(N), "f": np.full(N, 1.0), "v": np.full(N, 0.05)},
                   rate=1000.0)
    assert main(["fit", "texture", str(path), *KINDS["texture"], "-o", str(tmp_path / "s.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert "every piece's median speed is below 5 mm/s; check --speed is in mm/s" in err, err
