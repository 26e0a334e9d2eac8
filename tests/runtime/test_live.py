"""Live loop against the in-process simulated device (virtual bus). No timing asserts."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cantools
import numpy as np
import pytest

from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.runtime.live import BusError, run_live

REPO = Path(__file__).resolve().parents[2]
DBC = REPO / "graphs" / "devices" / "example.dbc"

GRAPH = """
flowtex: 1
name: passthrough
rate: 1000
inputs:
  position: {shape: [3], unit: mm}
  normal_force: {unit: N}
nodes:
  lp: {type: first_order_lowpass, params: {cutoff_hz: 50}}
  k: {type: gain, params: {k: 0.01}}
  v: {type: gain, params: {k: 0.25}}
edges:
  - position -> lp.x
  - lp.y -> k.x
  - normal_force -> v.x
outputs:
  force: k.y
  vibration: v.y
"""

MAP = """
flowtex_map: 1
overrun_limit_ms: 100000    # a loaded test machine must not trip the overrun watchdog
inputs:
  position:
    signals: [ToolPosition.PosX, ToolPosition.PosY, ToolPosition.PosZ]
    timeout_ms: 5
  normal_force: {signal: ToolForce.NormalForce, timeout_ms: 5}
outputs:
  vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}
  force: {signals: [ForceCmd.Fx, ForceCmd.Fy, ForceCmd.Fz], clamp: [-4, 4], safe: [0, 0, 0]}
"""


@pytest.fixture
def setup(tmp_path):
    (tmp_path / "g.yaml").write_text(textwrap.dedent(GRAPH))
    (tmp_path / "m.yaml").write_text(textwrap.dedent(MAP))
    t = np.arange(3000) / 1000.0
    pos = np.stack([100 * np.sin(2 * np.pi * t), 50 * np.cos(6 * np.pi * t), 10 + 0 * t], axis=1)
    force = 3 + np.sin(10 * np.pi * t)  # vibration = 0.25 * force stays inside the clamp and non-zero
    np.savez(tmp_path / "rec.npz", position=pos, normal_force=force, rate=np.float64(1000))
    return tmp_path


def _tx(path):
    return [m for m in read_session(path) if not m.is_rx]


def test_two_second_simulated_run_counts_and_safe_exit(setup):
    g = load_graph(setup / "g.yaml")
    rec = setup / "s.blf"
    r = run_live(g, DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=2000, record=rec, status=None)
    assert r.error is None and r.exit_reason == "duration"
    assert r.ticks == 2000
    assert r.frames_in == 2000 * 2  # ToolPosition + ToolForce each tick
    assert r.frames_out == 2000 * 2
    assert r.device.frames_received == 2000 * 2 + 2  # plus the exit safe values
    assert r.watchdog_events == 0
    frames = list(read_session(rec))
    assert sum(m.is_rx for m in frames) == 4000 and sum(not m.is_rx for m in frames) == 4002
    db = cantools.database.load_file(DBC)
    last = _tx(rec)[-2:]
    assert bytes(last[0].data) == db.get_message_by_name("VoiceCoilCmd").encode({"Current": 0, "Enable": 0, "Mode": 0})
    assert bytes(last[1].data) == db.get_message_by_name("ForceCmd").encode({"Fx": 0, "Fy": 0, "Fz": 0})
    # a regular tick carries the graph's value: vibration = 0.25 * normal force as decoded by cantools
    rx = [m for m in frames if m.is_rx]
    nf = db.decode_message(rx[2 * 100 + 1].arbitration_id, rx[2 * 100 + 1].data)["NormalForce"]
    cur = db.decode_message(0x200, _tx(rec)[2 * 100].data)["Current"]
    assert cur == pytest.approx(0.25 * nf, abs=1e-4)


def test_sensor_dropout_trips_watchdog_and_sends_safe_values(setup):
    g = load_graph(setup / "g.yaml")
    rec = setup / "s.log"
    r = run_live(g, DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=1000, record=rec, status=None,
                 drop={"ToolForce": (300, 600)})
    assert r.error is None
    assert r.watchdog_events == 1
    db = cantools.database.load_file(DBC)
    cur = np.array([db.decode_message(0x200, m.data)["Current"] for m in _tx(rec) if m.arbitration_id == 0x200])
    # last frame received at tick 299, timeout 5 ticks: tick 305 is the first stale tick
    assert np.all(cur[:305] > 0.4)
    assert np.all(cur[305:600] == 0.0)
    assert np.all(cur[600:1000] > 0.4)   # fresh again as soon as frames return
    assert cur[-1] == 0.0


def test_bus_that_cannot_be_opened(setup):
    g = load_graph(setup / "g.yaml")
    with pytest.raises(BusError) as e:
        run_live(g, DBC, setup / "m.yaml", bus="socketcan:flowtexnone0", max_ticks=10, status=None)
    assert "cannot open CAN bus" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(BusError, match="unknown interface"):
        run_live(g, DBC, setup / "m.yaml", bus="nosuchbus:0", max_ticks=10, status=None)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_leaves_safe_values_last(setup, sig):
    rec = setup / f"s{int(sig)}.log"
    cmd = [sys.executable, "-m", "flowtex.runtime.commands", "live", str(setup / "g.yaml"), "--dbc", str(DBC),
           "--map", str(setup / "m.yaml"), "--simulate", str(setup / "rec.npz"), "--record", str(rec), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and (not rec.exists() or rec.stat().st_size < 20000):
            time.sleep(0.1)
            assert proc.poll() is None, proc.stderr.read().decode()
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err.decode()
    tx = _tx(rec)
    assert len(tx) > 100
    db = cantools.database.load_file(DBC)
    assert db.decode_message(0x200, tx[-2].data)["Current"] == 0.0
    assert [db.decode_message(0x201, tx[-1].data)[k] for k in ("Fx", "Fy", "Fz")] == [0, 0, 0]
    assert db.decode_message(0x200, tx[-4].data)["Current"] > 0.4  # the tick before was a live one
