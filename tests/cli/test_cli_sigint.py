"""Ctrl-C while ``flowtex run`` writes its output leaves the old output intact and no temporary file (issue 17)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from flowtex.io.recordings import load_recording, save_recording
from tests.child_signals import sigint_as_a_terminal_gives_it, signal_state
from tests.cli.gain_graph import GAIN_GRAPH as GRAPH

SLOW_WRITER = """
import sys, time
from pathlib import Path
import numpy

marker = Path(sys.argv.pop(1))
savez = numpy.savez


def savez_then_wait(file, *args, **kwds):  # the data are written into the temporary file; hold before the rename
    savez(file, *args, **kwds)
    file.flush()
    marker.write_text("writing\\n")
    for _ in range(600):  # short sleeps: a SIGINT that lands on another thread of the process is acted on at once
        time.sleep(0.1)


numpy.savez = savez_then_wait
from flowtex.cli import main

sys.exit(main(sys.argv[1:]))
"""
"""``flowtex`` with numpy.savez slowed down in this process only: the test interrupts a write in progress."""


def signal_during_write(tmp_path, verb_args, signum) -> tuple[int, str]:
    """Run ``flowtex VERB_ARGS`` (numpy.savez held after writing its temporary file), send ``signum`` there; (code, stderr)."""
    marker = tmp_path / "writing"
    cmd = [sys.executable, "-c", SLOW_WRITER, str(marker), *map(str, verb_args)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}  # the flowtex under test, whatever the cwd
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=sigint_as_a_terminal_gives_it)
    try:
        deadline = time.monotonic() + 240  # a cold numba compile under load comes first
        while not marker.exists():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the writer never reached its write phase"
            time.sleep(0.05)
        # the new data are in the temporary file now, not yet renamed: interrupt here
        assert [p.name for p in tmp_path.iterdir() if ".part" in p.name]
        state = signal_state(proc.pid)
        proc.send_signal(signum)
        try:
            _stdout, stderr = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the writer ignored the signal for 60 s; its signal state when it was sent: {state}")
    finally:
        if proc.poll() is None:
            proc.kill()
    return proc.returncode, stderr


def test_sigint_during_the_write_keeps_the_old_output(tmp_path):
    (tmp_path / "g.yaml").write_text(GRAPH)
    x = np.arange(5000, dtype=np.float64)
    save_recording(tmp_path / "in.npz", {"x": x}, rate=1000.0)
    out = tmp_path / "out.npz"
    save_recording(out, {"y": np.full(3, 7.0)}, rate=1000.0)  # the old output, which must survive
    before = out.read_bytes()
    code, stderr = signal_during_write(tmp_path, ["run", tmp_path / "g.yaml", "-i", tmp_path / "in.npz", "-o", out, "--no-plugins"],
                                       signal.SIGINT)
    assert code == 130 and stderr.strip().splitlines()[-1] == "interrupted", stderr
    assert out.read_bytes() == before
    assert load_recording(out).arrays["y"].tolist() == [7.0, 7.0, 7.0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.yaml", "in.npz", "out.npz", "writing"]  # no temporary file
