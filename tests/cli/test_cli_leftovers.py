"""Nothing left behind (issue 27, section 2): SIGTERM like Ctrl-C in the offline verbs, --into through a symlink, and
output names up to the 255-character limit."""

from __future__ import annotations

import os
import signal
import stat

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import friction_session
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.io.recordings import load_recording, save_recording
from tests.cli.gain_graph import GAIN_GRAPH as GRAPH
from tests.cli.test_cli_sigint import signal_during_write

VERBS = {
    "run": lambda d, out: ["run", str(d / "g.yaml"), "-i", str(d / "in.npz"), "-o", str(out), "--no-plugins"],
    "resample": lambda d, out: ["resample", str(d / "in.npz"), "--rate", "500", "-o", str(out)],
}


@pytest.mark.parametrize("verb, signum", [("run", signal.SIGTERM), ("resample", signal.SIGTERM), ("run", signal.SIGHUP)])
def test_sigterm_during_the_write_keeps_the_old_output_and_leaves_no_part_file(tmp_path, verb, signum):
    """numpy.savez is held after writing the temporary file (tests/cli/test_cli_sigint.py); SIGTERM then arrives.
    SIGHUP (the terminal closed) is the same; before, it ended the process at once and left the temporary file."""
    (tmp_path / "g.yaml").write_text(GRAPH)
    save_recording(tmp_path / "in.npz", {"x": np.arange(5000, dtype=np.float64)}, rate=1000.0)
    out = tmp_path / "out.npz"
    save_recording(out, {"y": np.full(3, 7.0)}, rate=1000.0)
    before = out.read_bytes()
    code, stderr = signal_during_write(tmp_path, VERBS[verb](tmp_path, out), signum)
    assert code == 128 + signum and stderr.strip().splitlines()[-1] == "terminated", stderr
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.yaml", "in.npz", "out.npz", "writing"]


def test_fit_friction_into_a_symlink_updates_the_target_and_keeps_the_link(tmp_path, capsys):
    rec = friction_session(mu=0.4, duration_s=10.0, seed=3)
    save_recording(tmp_path / "f.npz", rec.arrays, 1000.0)
    (tmp_path / "sets").mkdir()
    target = save_model_set(synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2, mu=0.9),
                            tmp_path / "sets" / "s.json")
    target.chmod(0o640)
    link = tmp_path / "current.json"
    link.symlink_to(os.path.join("sets", "s.json"))
    code = main(["fit", "friction", str(tmp_path / "f.npz"), "--force", "normal_force", "--friction-force", "tangential_force",
                 "--into", str(link), "-o", str(tmp_path / "mu.json")])
    assert code == 0, capsys.readouterr().err
    assert link.is_symlink() and os.readlink(link) == os.path.join("sets", "s.json")
    mu = load_model_set(target).mu
    assert mu == pytest.approx(0.4, rel=0.03)  # friction_session's 3 % (see tests/fit/test_friction_defaults.py)
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert sorted(p.name for p in (tmp_path / "sets").iterdir()) == ["s.json"]  # no temporary file left


@pytest.mark.parametrize("length", [246, 250, 255])
def test_an_output_name_up_to_255_characters_is_written(tmp_path, capsys, length):
    """The temporary name keeps at most 24 characters of the stem, so it fits wherever the output's own name fits."""
    save_recording(tmp_path / "in.npz", {"x": np.sin(np.arange(2000) / 10.0)}, rate=1000.0)
    out = tmp_path / ("r" * (length - 4) + ".npz")
    assert len(out.name) == length
    code = main(["resample", str(tmp_path / "in.npz"), "--rate", "500", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    assert load_recording(out).rate == 500.0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["in.npz", out.name])
