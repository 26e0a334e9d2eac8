"""Live safety against hostile frames on the bus: frames that carry a sensor message's ID number but are not that message.

A DBC message is a frame ID *in a frame format*: a standard (11-bit) and an extended (29-bit) ID of the same number
are different messages on the bus. A frame of the other format must not reach the graph's inputs or stamp the input
watchdog: a stopped sensor would otherwise stay "fresh" while another node sends frames of the other format. (A remote
frame, which requests a message without carrying it, has no data in python-can, whatever its DLC, so it never
decodes; the flood below sends those too.)
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import textwrap
import threading
import tty
from pathlib import Path

import can
import cantools
import numpy as np
import pytest
from test_live import DBC, GRAPH, MAP, REPO, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.graph.compiled import load_graph
from flowtex.io.codec_tables import decode_packed
from flowtex.runtime.live import LiveConfig, load_io, run_live
from flowtex.runtime.tick import rx_decoder

DB = cantools.database.load_file(DBC)
ENV = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
"""Subprocesses run the flowtex under test, whatever the folder they start in."""
FORCE = DB.get_message_by_name("ToolForce")
BIG = bytes(FORCE.encode({"NormalForce": 60, "SurfNormalX": 0, "SurfNormalY": 0, "SurfNormalZ": 0}))
"""A ToolForce payload of 60 N: vibration = 0.25 * 60 = 15 A, far outside the map's clamp [-1, 1]."""


def _impostors() -> list[can.Message]:
    """Frames with ToolForce's ID number (0x101) and length that are not ToolForce frames."""
    return [can.Message(arbitration_id=FORCE.frame_id, is_extended_id=True, data=BIG),
            can.Message(arbitration_id=FORCE.frame_id, is_extended_id=False, is_remote_frame=True, dlc=8, data=BIG)]


def test_an_extended_frame_with_a_standard_sensor_id_is_not_that_sensor(setup):  # noqa: F811
    """The live decoder (compiled slots and the Python codecs; the replay decodes with it) does not take it."""
    g = load_graph(setup / "g.yaml", block_rows=1)
    msg = _impostors()[0]
    io = load_io(g, DBC, setup / "m.yaml")
    wd = io.new_watchdog(2_000_000)
    before = wd.last.copy()
    words = np.zeros_like(io.codec.decoder.words)
    assert rx_decoder(io, wd)([msg], 7, words) == 0  # no compiled slot marked
    assert not io.decode(msg, 7, wd)  # the Python codec (the live one for other lengths)
    np.testing.assert_array_equal(wd.last, before)
    # the real frame is taken, so the refusal above is not an accident of the payload
    real = can.Message(arbitration_id=FORCE.frame_id, is_extended_id=False, data=BIG)
    assert rx_decoder(io, wd)([real], 7, words) != 0
    assert io.decode(real, 8, wd)


def test_a_frame_that_decodes_nothing_leaves_the_ticks_real_frame_be(setup):  # noqa: F811
    """A remote frame (a request for ToolForce, no data) or a short frame after the tick's real ToolForce frame: the
    real one still counts, as the Python codec, which decodes frame by frame, also has it. Before, the later frame
    cleared the real one's slot: the sensor looked stale (outputs safe) whenever another node requested its message."""
    g = load_graph(setup / "g.yaml", block_rows=1)
    io = load_io(g, DBC, setup / "m.yaml")
    wd = io.new_watchdog(2_000_000)
    real = can.Message(arbitration_id=FORCE.frame_id, is_extended_id=False, data=BIG)
    short = can.Message(arbitration_id=FORCE.frame_id, is_extended_id=False, data=BIG[:3])
    j = io.codec.decoder.slot_of[FORCE.frame_id]
    words = np.zeros_like(io.codec.decoder.words)
    for later in (_impostors()[1], short):
        assert rx_decoder(io, wd)([real, later], 7, words) == 1 << j
        assert io.decode(real, 7, wd) and not io.decode(later, 7, wd)  # the Python codec's view of the same two frames


def test_a_stopped_sensor_trips_the_watchdog_whatever_impostors_say(setup):  # noqa: F811
    """End to end: ToolForce stops at tick 300 while another client floods the bus with extended and remote 0x101
    frames; the watchdog trips and every actuator frame after it (read by a second python-can client) is safe.
    Before, the impostors kept the sensor 'fresh' and drove the output to its clamp (15 A wanted, 1 A sent)."""
    channel = "livesafe-impostors"
    listener = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    injector = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    stop = threading.Event()

    def flood() -> None:
        while not stop.is_set():
            for m in _impostors():
                injector.send(m)
            stop.wait(0.0005)

    thread = threading.Thread(target=flood, daemon=True)
    thread.start()
    try:
        r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", bus=f"virtual:{channel}",
                                                              simulate=setup / "rec.npz", max_ticks=1000, status=None,
                                                              drop={"ToolForce": (300, None)}))
    finally:
        stop.set()
        thread.join()
        injector.shutdown()
    try:
        sent = []
        msg = listener.recv(0)
        while msg is not None:
            if msg.arbitration_id == 0x200 and not msg.is_extended_id and not msg.is_remote_frame:
                sent.append(DB.decode_message(0x200, msg.data)["Current"])
            msg = listener.recv(0)
    finally:
        listener.shutdown()
    assert r.error is None and r.ticks == 1000 and r.watchdog_events == 1
    assert r.summary["clamped"]["vibration"] == 0  # no 60 N impostor ever reached the graph
    assert len(sent) == 1001  # 1000 ticks and the exit block
    # the last ToolForce frame is tick 299's; with timeout_ms 5 at 1 kHz tick 305 is the first stale one
    assert min(sent[:305]) > 0.4  # live values (0.25 * 2..4 N) until then, never an impostor's
    assert sent[305:] == [0.0] * (1001 - 305)  # then safe values to the end


def test_a_bus_that_blocks_on_send_ends_the_session_in_one_line(setup):  # noqa: F811
    """An slcan adapter that stops reading (a pty whose other end this test holds and never reads): its buffer fills
    and every write waits. The session ends by itself with one line that claims no safe values, exit code 1, long
    before its --duration. Before, the send waited forever: Ctrl-C, a second Ctrl-C and SIGTERM only set the stop flag
    of a loop that never came back to read it, so nothing but SIGKILL ended the process."""
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        proc = subprocess.run([sys.executable, "-m", "flowtex", "live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map",
                               str(setup / "m.yaml"), "--bus", f"flowtex_slcan:{os.ttyname(slave)}", "--duration", "60",
                               "--quiet"], capture_output=True, text=True, timeout=50, env=ENV)
    finally:
        os.close(slave)
        os.close(master)
    lines = [line for line in proc.stderr.splitlines() if not line.startswith("flowtex: compiling")]
    assert proc.returncode == 1 and len(lines) == 1, proc.stderr
    assert lines[0].startswith("CAN bus error at tick ") and "the other end is not reading" in lines[0], lines
    assert "could not send the safe values (frame id 0x200, 0x201)" in lines[0] and "(safe values sent)" not in lines[0]


NAN_GRAPH = (textwrap.dedent(GRAPH)
             .replace("  v: {type: gain, params: {k: 0.25, unit: A}}",
                      "  lpf: {type: first_order_lowpass, params: {cutoff_hz: 50}}\n  v: {type: gain, params: {k: 0.01, unit: A}}")
             .replace("  - normal_force -> v.x", "  - normal_force -> lpf.x\n  - lpf.y -> v.x"))
"""test_live's graph with a low-pass (state) between normal_force and the vibration output."""


def nan_setup(folder: Path) -> Path:
    """Write ``nan.yaml`` (:data:`NAN_GRAPH`) and ``mnan.yaml``, test_live's map with normal_force bound to
    DeviceStatus.CoilTemperature (a float32 signal, which a frame can carry as NaN or inf); returns the map."""
    (folder / "nan.yaml").write_text(NAN_GRAPH)
    m = folder / "mnan.yaml"
    m.write_text(textwrap.dedent(MAP).replace("normal_force: {signal: ToolForce.NormalForce, timeout_ms: 5}",
                                              "normal_force: {signal: DeviceStatus.CoilTemperature, timeout_ms: 5}"))
    return m


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), float("-inf")])
def test_a_non_finite_float_signal_is_no_measurement(setup, bad):  # noqa: F811
    """normal_force bound to DeviceStatus.CoilTemperature (a float32 signal), through a low-pass: one NaN or inf
    frame written into the input made the filter's state NaN, so the output was NaN (sent as its safe value) for the
    rest of the session, with no watchdog event. The frame is dropped whole instead: no input written, no watchdog
    stamp, in the live decoder (compiled slot and Python codec, which the replay uses too) and in CanIO.decode."""
    assert "lpf.y -> v.x" in NAN_GRAPH
    m = nan_setup(setup)
    g = load_graph(setup / "nan.yaml", block_rows=1)
    io = load_io(g, DBC, m)
    status = DB.get_message_by_name("DeviceStatus")
    good = can.Message(arbitration_id=status.frame_id, is_extended_id=False, data=struct.pack("<f", 30.0) + bytes(4))
    frame = can.Message(arbitration_id=status.frame_id, is_extended_id=False, data=struct.pack("<f", bad) + bytes(4))
    assert not np.isfinite(DB.decode_message(status.frame_id, frame.data)["CoilTemperature"])  # cantools reads it so
    td = io.codec.decoder
    j = td.slot_of[status.frame_id]
    for path in ("compiled", "python", "CanIO.decode"):
        wd = io.new_watchdog(2_000_000)
        inp = g.input_view("normal_force")
        inp[:] = 12.5
        rx = rx_decoder(io, wd)
        if path == "compiled":
            mask = rx([frame], 7, td.words)  # the compiled slot (a finite frame before it would stand: test_nan_frames.py)
            assert mask == 1 << j
            decode_packed(td.ibuf, td.fbuf, mask, 7, io.codec.arena, wd.last)
        elif path == "python":  # a longer frame (CAN FD padding) goes through the Python codec
            longer = can.Message(arbitration_id=status.frame_id, is_extended_id=False, is_fd=True, data=bytes(frame.data) + bytes(4))
            assert rx([longer], 7, td.words) == 0
        else:
            assert not io.decode(frame, 7, wd)
        assert inp.tolist() == [12.5], path  # not written
        assert (wd.last < 0).all(), path  # not stamped: a sensor sending only such frames trips the watchdog
    g.input_view("normal_force")[:] = 0.0
    assert io.decode(good, 8, wd) and g.input_view("normal_force").tolist() == [30.0]  # a finite one still decodes


def test_a_silent_extended_sensor_is_named_as_extended(setup):  # noqa: F811
    """Frames of the other format are other messages, so a device that sends an extended message as a standard frame
    is silent: the line says which format was expected."""
    dbc = setup / "ext.dbc"
    text = DBC.read_text()
    assert "BO_ 257 ToolForce: 8 HapticDevice" in text
    dbc.write_text(text.replace("BO_ 257 ToolForce: 8 HapticDevice", f"BO_ {(1 << 31) | 257} ToolForce: 8 HapticDevice"))
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=50,
                                                          status=None, drop={"ToolForce": (0, None)}))
    assert r.error is None and r.silent_messages == ["ToolForce"]
    assert r.silence.startswith("no frame of ToolForce (extended id 0x101) received in 50 ticks"), r.silence


def test_replay_decodes_a_tick_as_live_did_when_its_last_frame_is_not_finite(setup, monkeypatch):  # noqa: F811
    """A tick that received a finite DeviceStatus frame and then a NaN one: live ignores the NaN frame and decodes the
    finite one (the latest finite frame of the tick stands, tests/runtime/test_nan_frames.py). The replay decodes a
    tick's frames as the live tick does (flowtex.runtime.tick.rx_decoder, then the compiled decoder), so whatever the
    rule, replay equality holds by construction."""
    from flowtex.runtime import simdevice
    from flowtex.runtime.replay import replay_session

    m = nan_setup(setup)
    status = DB.get_message_by_name("DeviceStatus")
    nan = can.Message(arbitration_id=status.frame_id, is_extended_id=False, data=struct.pack("<f", float("nan")) + bytes(4))
    publish = simdevice.SimulatedDevice.publish

    def twice_at_100(self, k):  # tick 100's finite frame, then a NaN frame of the same message in the same tick
        publish(self, k)
        if k == 100:
            self.bus.send(nan)

    monkeypatch.setattr(simdevice.SimulatedDevice, "publish", twice_at_100)
    log = setup / "nan.blf"
    r = run_live(load_graph(setup / "nan.yaml"), LiveConfig(DBC, m, simulate=setup / "rec.npz", max_ticks=300, record=log,
                                                            status=None, seed=3))
    assert r.error is None
    frames = [f for f in __import__("flowtex.io.canlog", fromlist=["read_session"]).read_session(log) if f.is_rx]
    assert any(f.arbitration_id == status.frame_id and not np.isfinite(struct.unpack("<f", bytes(f.data[:4]))[0])
               for f in frames)  # the NaN frame reached live and the log
    rep = replay_session(load_graph(setup / "nan.yaml"), log, DBC, m, setup / "replay.log", seed=3)
    assert rep.ticks == 300 and rep.unexplained_ticks == [] and rep.mismatched_ticks == [], rep.summary()
