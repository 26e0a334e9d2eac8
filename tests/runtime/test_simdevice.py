"""The simulated device: in-process latency bookkeeping and a two-process session over a pseudo-terminal (slcan)."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import cantools
import numpy as np
import pytest
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.runtime.live import LiveConfig, run_live


def test_in_process_latency_is_zero_ticks(setup):  # noqa: F811
    g = load_graph(setup / "g.yaml")
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=300, status=None))
    assert r.error is None
    dev = r.device
    # one answer per executed tick, plus the exit safe values answering the sample published after the last tick
    assert dev.latency_count == 301
    assert np.all(dev.latency_ticks[:301] == 0)
    assert np.all(dev.latency_s[:301] >= 0.0)
    assert dev.frames_received == 2 * 300 + 2


def _expected_payloads(db, rec):
    """Every sensor payload the device may send for the recording, encoded by cantools (unbound signals 0)."""
    pos, nf = rec["position"], rec["normal_force"]
    tp, tf = db.get_message_by_name("ToolPosition"), db.get_message_by_name("ToolForce")
    a = {tp.encode({"PosX": x, "PosY": y, "PosZ": z, "PosCounter": 0}) for x, y, z in pos}
    b = {tf.encode({"NormalForce": f, "SurfNormalX": 0, "SurfNormalY": 0, "SurfNormalZ": 0}) for f in nf}
    return {tp.frame_id: a, tf.frame_id: b}


def _pty_device(setup, duration_s: int) -> tuple[subprocess.Popen, str]:  # noqa: F811
    """`flowtex simulate-device --pty --exit-on-close` started, and the pty path it announced."""
    cmd = [sys.executable, "-m", "flowtex", "simulate-device", str(setup / "rec.npz"), "--pty", "--exit-on-close",
           "--duration", str(duration_s), "--dbc", str(DBC), "--map", str(setup / "m.yaml")]
    dev = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    line = dev.stdout.readline()
    m = re.search(r"--bus flowtex_slcan:(/dev/pts/\d+)", line)
    if m is None:
        dev.kill()
        raise AssertionError((line, dev.communicate()[1]))
    return dev, m.group(1)


def test_two_process_session_over_a_pty(setup):  # noqa: F811
    dev, path = _pty_device(setup, 60)
    try:
        g = load_graph(setup / "g.yaml")
        log = setup / "pty.log"
        r = run_live(g, LiveConfig(DBC, setup / "m.yaml", bus=f"flowtex_slcan:{path}", max_ticks=1500, record=log, status=None,
                                   install_signals=False))
        out, err = dev.communicate(timeout=60)
    finally:
        if dev.poll() is None:
            dev.kill()
    assert dev.returncode == 0, err
    assert r.error is None and r.ticks == 1500
    s = re.search(r"sent (\d+) sensor frames.*received (\d+) actuator frames", err)
    assert s, err
    sent, received = int(s.group(1)), int(s.group(2))
    # the device closed only after the runtime's 'C': every actuator frame, the exit safe values included, arrived
    assert received == r.frames_out + 2 == 2 * 1500 + 2
    assert 0 < r.frames_in <= sent
    # what crossed the pty is what the device encoded from the recording, byte for byte
    db = cantools.database.load_file(DBC)
    expected = _expected_payloads(db, np.load(setup / "rec.npz"))
    rx = [f for f in read_session(log) if f.is_rx]
    assert len(rx) == r.frames_in
    for f in rx:
        assert bytes(f.data) in expected[f.arbitration_id]
    tx = [f for f in read_session(log) if not f.is_rx]
    assert db.decode_message(0x200, tx[-2].data)["Current"] == 0.0


def test_a_session_opened_and_closed_within_one_tick_ends_the_device(setup):  # noqa: F811
    """--exit-on-close after a host's open and close that the device reads in one batch (a runtime that started before
    the device was serving, or ran while the device was stalled): the device used to miss the open and run on to
    --duration. It announces its pty only once it can serve, and remembers every open it received."""
    from flowtex.io.slcan_fast import FastSlcanBus

    dev, path = _pty_device(setup, 30)
    try:
        host = FastSlcanBus(path)        # writes C, O ...
        host.shutdown()                  # ... and C at once: all three in the device's next read
        out, err = dev.communicate(timeout=20)
    finally:
        if dev.poll() is None:
            dev.kill()
    assert dev.returncode == 0, err
    ticks = int(re.search(r"simulated device: (\d+) ticks", err).group(1))
    assert ticks < 20_000  # ended by the close, not by --duration (30 s = 30,000 ticks at 1 kHz)


def test_simulate_device_needs_bus_or_pty(setup):  # noqa: F811
    base = [sys.executable, "-m", "flowtex", "simulate-device", str(setup / "rec.npz"), "--dbc", str(DBC),
            "--map", str(setup / "m.yaml")]
    p = subprocess.run(base, capture_output=True, text=True, timeout=60)
    assert p.returncode == 1 and "--bus" in p.stderr and "--pty" in p.stderr  # a bad command line is a user error
    p = subprocess.run(base + ["--bus", "socketcan:flowtexnone0", "--duration", "0.1"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 1
    assert p.stderr.strip().count("\n") == 0 and p.stderr.startswith("cannot open CAN bus")


def test_simulate_device_refuses_a_stated_unit_other_than_the_dbc_signals(setup):  # noqa: F811
    """simulate-device has no graph: it used to play a position stated in m onto PosX (DBC unit mm), 1000x off."""
    from flowtex.errors import DataError
    from flowtex.io.canmap import load_map
    from flowtex.io.codec import MessageCodec
    from flowtex.io.dbc import load_dbc
    from flowtex.runtime.simdevice import check_units, run_device

    rec = np.load(setup / "rec.npz")
    np.savez(setup / "m_rec.npz", position=rec["position"] / 1000, normal_force=rec["normal_force"], rate=np.float64(1000),
             units=np.str_('{"position": "m", "normal_force": "N"}'))
    with pytest.raises(DataError) as err:  # refused before the bus opens: this bus does not exist
        run_device("socketcan:flowtexnone0", str(DBC), str(setup / "m.yaml"), str(setup / "m_rec.npz"), duration_s=0.01, status=None)
    msg = str(err.value)
    assert msg == (f"{setup / 'm_rec.npz'}: signal 'position' is in 'm' (the file's units) but DBC signal ToolPosition.PosX (bound by "
                   "map m.yaml) takes mm; flowtex converts no unit: multiply it by 1000 and state its unit as mm"), msg
    db = load_dbc(DBC)
    codecs = {m.name: MessageCodec(m) for m in db.messages}
    canmap = load_map(setup / "m.yaml", db, DBC)
    check_units(canmap, codecs, {"position": "mm", "normal_force": "-"}, "r.npz")  # the DBC's unit, or none stated: passes
    (setup / "scaled.yaml").write_text((setup / "m.yaml").read_text().replace("timeout_ms: 5\n", "scale: 0.001\n    timeout_ms: 5\n", 1))
    check_units(load_map(setup / "scaled.yaml", db, DBC), codecs, {"position": "m"}, "r.npz")  # the map's scale converts
