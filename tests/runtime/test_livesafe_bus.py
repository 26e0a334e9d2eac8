"""Live safety against what real buses and devices do: frame formats the bus cannot carry, and frames a device sends
that the DBC describes otherwise.

Every DBC is built from the bundled example by editing one line (test_livesafe_dbc's ``_dbc``).
"""

from __future__ import annotations

import errno
import math
import os
import re
import signal
import threading
from io import StringIO

import can
import pytest
from hypothesis import given
from hypothesis import strategies as st
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)
from test_livesafe_dbc import _dbc
from test_livesafe_frames import nan_setup
from test_nan_frames import frame as nan_frame

from flowtex.errors import GraphError
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import SessionWriter, read_session
from flowtex.io.codec_tables import decode_packed
from flowtex.io.slcan_protocol import encode_frame
from flowtex.io.slcan_pty import open_pty
from flowtex.runtime import buses
from flowtex.runtime.audio_ring import ARRIVAL_WINDOW_NS, sensor_arrival_ns
from flowtex.runtime.buses import BusError, open_bus, send_when_queued
from flowtex.runtime.live import LiveConfig, load_io, run_live
from flowtex.runtime.simdevice import run_device
from flowtex.runtime.tick import RefusedFrames, rx_decoder

FD_ATTRIBUTE = ('\nBA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN",' + '"reserved",' * 12 + '"StandardCAN_FD","ExtendedCAN_FD";\n'
                'BA_DEF_DEF_ "VFrameFormat" "StandardCAN";\nBA_ "VFrameFormat" BO_ 512 14;\n')
"""The DBC attribute that marks VoiceCoilCmd (BO_ 512) a CAN FD message."""


def test_an_actuator_message_longer_than_a_classic_frame_must_be_can_fd(setup):  # noqa: F811
    """VoiceCoilCmd given 12 bytes without being marked CAN FD: the runtime would send classic frames of 12 bytes, which
    no bus takes (flowtex_slcan refused the first with a ValueError, 'tick 0: ValueError: ... could not send the safe
    values ... make it safe by hand'; the virtual bus of --simulate carried them). Refused with the map now, naming the
    output's line and the fix; marked CAN FD, it runs and sends CAN FD frames."""
    dbc = _dbc(setup, "BO_ 512 VoiceCoilCmd: 4 Host", "BO_ 512 VoiceCoilCmd: 12 Host", "long.dbc")
    g = load_graph(setup / "g.yaml")
    with pytest.raises(GraphError) as e:
        load_io(g, dbc, setup / "m.yaml")
    line = next(i for i, t in enumerate((setup / "m.yaml").read_text().splitlines(), 1) if t.strip().startswith("vibration:"))
    text = str(e.value)
    assert text.startswith(f"{setup / 'm.yaml'}:{line}:") and "'VoiceCoilCmd'" in text and "12 data bytes" in text, text
    assert "CAN FD" in text and "at most 8 bytes in its BO_ line" in text, text
    with pytest.raises(GraphError):
        run_live(g, LiveConfig(dbc, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=5, status=None))
    with pytest.raises(ValueError):  # why: what the runtime sent before, a classic frame of 12 bytes, no adapter carries
        encode_frame(can.Message(arbitration_id=0x200, is_extended_id=False, data=bytes(12)))

    fd = _fd_dbc(setup)
    coil = next(m for m in load_io(g, fd, setup / "m.yaml").tx if m.arbitration_id == 0x200)
    assert coil.is_fd and len(coil.data) == 12
    r = run_live(g, LiveConfig(fd, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=5, status=None))
    assert r.error is None and r.ticks == 5


def _fd_dbc(folder):
    """The example DBC with VoiceCoilCmd a CAN FD message of 12 bytes."""
    dbc = _dbc(folder, "BO_ 512 VoiceCoilCmd: 4 Host", "BO_ 512 VoiceCoilCmd: 12 Host", "long.dbc")
    dbc.write_text(dbc.read_text() + FD_ATTRIBUTE)
    return dbc


def test_a_bus_that_speaks_classic_can_only_is_refused_for_can_fd_messages(setup):  # noqa: F811
    """VoiceCoilCmd is CAN FD and the bus is flowtex_slcan (slcan carries classic frames only): the session started
    and ended at its first send, 'tick 0: ValueError: slcan_fast: CAN FD and error frames are not supported; could not
    send the safe values ... make it safe by hand'. Refused now before any frame, in one line naming the bus and the
    message, no log left; and simulate-device --pty (an slcan adapter) likewise, before its pty is announced."""
    dbc = _fd_dbc(setup)
    pty = open_pty()
    try:
        with pytest.raises(BusError) as e:
            run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, setup / "m.yaml", bus=f"flowtex_slcan:{pty.slave_path}",
                                                              max_ticks=5, status=None, record=setup / "s.blf"))
    finally:
        pty.close()
    assert str(e.value).startswith(f"--bus 'flowtex_slcan:{pty.slave_path}' carries classic CAN frames only, but the DBC makes "
                                   "VoiceCoilCmd CAN FD"), str(e.value)
    assert not list(setup.glob("*s.*blf"))
    announced = StringIO()
    with pytest.raises(BusError, match=r"^--pty \(an slcan adapter\) carries classic CAN frames only"):
        run_device(None, str(dbc), str(setup / "m.yaml"), str(setup / "rec.npz"), duration_s=0.05, pty=True, status=None,
                   announce=announced)
    assert announced.getvalue() == ""


def test_a_short_can_fd_sensor_message_may_come_classic(setup):  # noqa: F811
    """ToolForce marked CAN FD in 8 bytes: a device may send it in classic frames, which the decoder takes, so a classic
    bus is not refused for it (the session runs), while simulate-device --pty, which would send it, is."""
    dbc = _dbc(setup, "BO_ 512 VoiceCoilCmd: 4 Host", "BO_ 512 VoiceCoilCmd: 4 Host", "short.dbc")
    dbc.write_text(dbc.read_text() + FD_ATTRIBUTE.replace("BO_ 512 14", "BO_ 257 14"))
    pty = open_pty()
    try:
        r = run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, setup / "m.yaml", bus=f"flowtex_slcan:{pty.slave_path}",
                                                              max_ticks=3, status=None))
    finally:
        pty.close()
    assert r.ticks == 3 and r.error is None
    with pytest.raises(BusError, match=r"^--pty \(an slcan adapter\) carries classic CAN frames only, but the DBC makes ToolForce"):
        run_device(None, str(dbc), str(setup / "m.yaml"), str(setup / "rec.npz"), duration_s=0.05, pty=True, status=None,
                   announce=StringIO())


def test_a_bus_is_opened_for_can_fd_when_the_session_has_can_fd_messages(setup, monkeypatch):  # noqa: F811
    """python-can's socketcan opens a classic raw socket unless asked for ``fd``: it refused to send the FD frames (the
    safe ones too) and never delivered one. open_bus asks for it when the DBC makes a bound message CAN FD, only then."""
    asked: list[dict] = []

    class Fake:
        protocol = can.CanProtocol.CAN_FD

        def __init__(self, **kw):
            asked.append(kw)

        def shutdown(self) -> None:
            pass

    monkeypatch.setattr(can, "Bus", Fake)
    open_bus("socketcan:can0", 500000, needs_fd=["VoiceCoilCmd"])
    open_bus("socketcan:can0", 500000)
    open_bus("socketcan:can0", 500000, fd=True)  # FD messages that may also come classic: opened for FD, not judged
    assert asked == [{"interface": "socketcan", "channel": "can0", "bitrate": 500000, "fd": True},
                     {"interface": "socketcan", "channel": "can0", "bitrate": 500000},
                     {"interface": "socketcan", "channel": "can0", "bitrate": 500000, "fd": True}]
    Fake.protocol = can.CanProtocol.CAN_20  # an interface that did not take the request
    with pytest.raises(BusError, match="carries classic CAN frames only"):
        open_bus("socketcan:can0", None, needs_fd=["VoiceCoilCmd"])
    open_bus("socketcan:can0", None, fd=True)  # nothing needs FD: a classic bus passes


def test_a_sensor_message_longer_than_a_classic_frame_is_not_judged(setup):  # noqa: F811
    """A device may send a long sensor message in CAN FD frames, which the decoder takes whatever the DBC says."""
    dbc = _dbc(setup, "BO_ 257 ToolForce: 8 HapticDevice", "BO_ 257 ToolForce: 12 HapticDevice", "long.dbc")
    assert load_io(load_graph(setup / "g.yaml"), dbc, setup / "m.yaml").map.inputs["normal_force"]


def _inject(channel: str, frames: list[can.Message]) -> tuple[threading.Event, threading.Thread, can.BusABC]:
    """Another node on the virtual bus sending ``frames`` every 0.5 ms until the event is set."""
    injector = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    stop = threading.Event()

    def flood() -> None:
        while not stop.is_set():
            for m in frames:
                injector.send(m)
            stop.wait(0.0005)

    thread = threading.Thread(target=flood, daemon=True)
    thread.start()
    return stop, thread, injector


def test_a_sensor_whose_frames_the_dbc_does_not_describe_is_named_with_what_came(setup):  # noqa: F811
    """A device sending ToolForce in 6 bytes (the DBC says 8) and ToolPosition as extended frames: every frame is
    refused, rightly (outputs safe throughout, exit code 3), but the line said only 'no sensor frame received ... the
    N frame(s) that arrived were none of them', sending its user to check cables and power. It now says, per message,
    what arrived under its ID number that the DBC does not describe as it."""
    channel = "livesafe-mismatch"
    stop, thread, injector = _inject(channel, [
        can.Message(arbitration_id=0x101, is_extended_id=False, data=bytes(6)),
        can.Message(arbitration_id=0x100, is_extended_id=True, data=bytes(8))])
    try:
        r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", bus=f"virtual:{channel}", max_ticks=300,
                                                              status=None))
    finally:
        stop.set()
        thread.join()
        injector.shutdown()
    assert r.error is None and r.no_sensor_frames and r.frames_in > 0
    line = r.silence
    assert re.search(r"ToolPosition \(id 0x100; \d+ frame\(s\) of its ID number as extended frames arrived, which the DBC "
                     r"does not describe as ToolPosition\)", line), line
    assert re.search(r"ToolForce \(id 0x101; \d+ frame\(s\) shorter than the DBC's 8 data bytes \(the last of 6\) arrived", line), line


@pytest.mark.parametrize("longer", [False, True], ids=["compiled-slot", "python-codec"])
def test_a_sensor_sending_only_nan_is_named_with_what_came(setup, longer):  # noqa: F811
    """Only NaN CoilTemperature frames (dropped whole, rightly): the silent sensor is named with them, on the compiled
    slot (frames of the DBC's length, dropped inside the compiled decoder) and the Python codec (longer frames)."""
    m = nan_setup(setup)
    g = load_graph(setup / "nan.yaml", block_rows=1)
    io = load_io(g, DBC, m)
    wd = io.new_watchdog(2_000_000)
    refused = RefusedFrames()
    decode = rx_decoder(io, wd, refused)
    td = io.codec.decoder
    for k in range(3):
        mask = decode([nan_frame(math.nan, longer)], k, td.words)
        if mask:
            decode_packed(td.ibuf, td.fbuf, mask, k, io.codec.arena, wd.last)
    assert (wd.last < 0).all()
    count = "3" if longer else "some"
    assert refused.describe(io, "DeviceStatus") == (f"; {count} frame(s) with a float signal NaN or inf (no measurement) arrived, "
                                                    "which the DBC does not describe as DeviceStatus")
    assert RefusedFrames().describe(load_io(g, DBC, m), "DeviceStatus") == ""  # nothing came: nothing to say


class Interrupted(Exception):
    """What the test's own SIGINT handler raises: the handler in place before the session and after it."""


def test_a_second_ctrl_c_while_the_session_writes_its_files_keeps_them(setup, monkeypatch):  # noqa: F811
    """The first Ctrl-C ends the loop (safe values last); an impatient second one arrives while the log is closed and
    --stats written. The loop's stop handlers were gone by then: the second raised in the middle of the close, the
    log was discarded (a BLF cut in its flush left its .part file), --stats was not written and the session reported
    nothing (flowtex live: 'interrupted', exit 130). The handlers now stay until the files are written."""
    real_close = SessionWriter.close

    def close_after_a_ctrl_c(self, keep=True):
        os.kill(os.getpid(), signal.SIGINT)  # delivered to the main thread at its next bytecode: inside this close
        return real_close(self, keep)

    def before(signum, frame):
        raise Interrupted

    monkeypatch.setattr(SessionWriter, "close", close_after_a_ctrl_c)
    old = signal.signal(signal.SIGINT, before)
    try:
        r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=50,
                                                              status=None, record=setup / "s.blf", stats_path=setup / "st.json"))
        assert signal.getsignal(signal.SIGINT) is before  # the session's handlers are gone again
    finally:
        signal.signal(signal.SIGINT, old)
    assert r.error is None and r.ticks == 50 and r.exit_reason == "SIGINT"
    assert (setup / "st.json").is_file() and sorted(p.name for p in setup.iterdir() if p.name.startswith(("s", ".s"))) == ["s.blf", "st.json"]
    assert len([m for m in read_session(setup / "s.blf") if not m.is_rx]) == 2 * 51  # 50 ticks and the exit block


SENSORS = {0x100: (None, (0,), False), 0x101: (None, (1,), False)}
"""A CanIO.decoders of two standard sensor messages, as sensor_arrival_ns reads it."""
WALL_MINUS_PERF = 1_700_000_000_000_000_000
NOW = 5_000_000_000  # perf_counter ns of the tick: wall time 1700000005 s


def _at(seconds: float, fid: int = 0x100, **kw) -> can.Message:
    return can.Message(arbitration_id=fid, data=bytes(8), timestamp=seconds, **{"is_extended_id": False, **kw})


def test_the_audio_latency_starts_at_the_newest_sensor_frame_in_the_hosts_clock():
    """The audio latency ran from the newest timestamp of any frame of the tick: another node's frame (or an error or
    remote frame) after the sensor's made it shorter than it was; an adapter's own clock (seconds since it started)
    gave latencies of decades; an infinite timestamp ended the session ('tick k: OverflowError')."""
    sensor = _at(1_700_000_004.998)
    want = int(1_700_000_004.998 * 1e9) - WALL_MINUS_PERF
    later = [_at(1_700_000_004.9995, 0x300), _at(1_700_000_004.9995, 0x101, is_extended_id=True),
             _at(1_700_000_004.9995, 0x101, is_error_frame=True), _at(1_700_000_004.9995, 0x101, is_remote_frame=True)]
    assert sensor_arrival_ns([sensor, *later], WALL_MINUS_PERF, SENSORS, NOW) == want
    assert sensor_arrival_ns(later, WALL_MINUS_PERF, SENSORS, NOW) == 0  # no sensor frame: no latency sample
    for clock in (12.5, 1_700_000_100.0, math.inf, -math.inf, math.nan, -3.0):  # an adapter's clock, the future, nonsense
        assert sensor_arrival_ns([_at(clock)], WALL_MINUS_PERF, SENSORS, NOW) == 0, clock
        assert sensor_arrival_ns([_at(clock), sensor], WALL_MINUS_PERF, SENSORS, NOW) in (want, 0), clock


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=6))
def test_any_timestamps_give_a_latency_sample_in_the_window_or_none(stamps):
    arrival = sensor_arrival_ns([_at(t, 0x100 + i % 2) for i, t in enumerate(stamps)], WALL_MINUS_PERF, SENSORS, NOW)
    assert arrival == 0 or ARRIVAL_WINDOW_NS[0] <= NOW - arrival <= ARRIVAL_WINDOW_NS[1]


@pytest.mark.parametrize("suffix", [".log", ".blf", ".asc"])
def test_a_received_frame_without_a_time_is_logged_and_read_back(tmp_path, suffix):
    """An interface's frame stamped NaN or inf (or None): a .log wrote '(nan)', which flowtex's reader refuses ('t.log:1:1:
    timestamp '(nan)' is not '(SECONDS)'': the session could not be replayed), and a .blf or .asc ended the session
    ('frame time nan s cannot be written ...'). The frame is written at the log's last time now; the replay reads
    frames in order, never by their times, so every frame reads back, in order."""
    path = tmp_path / f"s{suffix}"
    w = SessionWriter(path)
    sent = can.Message(arbitration_id=0x200, is_extended_id=False, data=bytes(4))
    for k, stamp in enumerate([1_700_000_000.0, math.nan, math.inf, -math.inf, None]):
        got = can.Message(arbitration_id=0x100, is_extended_id=False, data=bytes([k]) * 8, timestamp=1.0)
        got.timestamp = stamp
        w.write_tick([got], [sent])
    w.close()
    frames = list(read_session(path))
    assert [(m.arbitration_id, m.is_rx, bytes(m.data[:1])) for m in frames] == [
        f for k in range(5) for f in ((0x100, True, bytes([k])), (0x200, False, b"\0"))]
    assert all(math.isfinite(m.timestamp) for m in frames)


def test_another_node_sending_the_actuator_commands_is_named(setup):  # noqa: F811
    """A second sender of VoiceCoilCmd on the bus (another flowtex live left running, a test tool) commands the coil
    with values no clamp or safe value of this session governs, its exit frames included. The session ignored those
    frames without a word; it now ends with a warning naming the message, its ID and the bus."""
    channel = "livesafe-two-senders"
    stop, thread, injector = _inject(channel, [can.Message(arbitration_id=0x200, is_extended_id=False, data=bytes(4)),
                                               can.Message(arbitration_id=0x200, is_extended_id=False, is_remote_frame=True,
                                                           dlc=4)])
    try:
        r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", bus=f"virtual:{channel}",
                                                              simulate=setup / "rec.npz", max_ticks=200, status=None))
    finally:
        stop.set()
        thread.join()
        injector.shutdown()
    assert r.error is None
    line = next(w for w in r.warnings if "VoiceCoilCmd" in w)
    assert re.fullmatch(r"\d+ frame\(s\) of actuator message VoiceCoilCmd \(id 0x200\) arrived from another node on the "
                        r"simulated device's virtual bus: the device also took commands that were not this session's, .*", line)
    assert not any("ForceCmd" in w for w in r.warnings)  # nobody else sent that one; a remote frame is no command
    # an adapter's echo of a frame this session sent (neoVI's default; python-can marks it not received) is no other sender
    io = load_io(load_graph(setup / "g.yaml", block_rows=1), DBC, setup / "m.yaml")
    refused = RefusedFrames()
    echo = can.Message(arbitration_id=0x201, is_extended_id=False, data=bytes(6), is_rx=False)
    rx_decoder(io, io.new_watchdog(2_000_000), refused)([echo], 0, io.codec.decoder.words)
    assert refused.foreign == {}


class FloodBus(can.BusABC):
    """A bus with ``flood`` frames of another node pending (a flood faster than the loop reads), then quiet."""

    def __init__(self, flood: int):
        super().__init__(channel="flood")
        self.left = flood
        self.read_before_send: list[int] = []
        self._flood = flood

    def _recv_internal(self, timeout):
        if self.left == 0:
            return None, False
        self.left -= 1
        return can.Message(arbitration_id=0x555, is_extended_id=False, data=bytes(8)), False

    def send(self, msg, timeout=None):
        self.read_before_send.append(self._flood - self.left)


def test_a_flood_of_frames_does_not_keep_the_loop_from_its_tick(setup, monkeypatch):  # noqa: F811
    """The receive read until the bus was empty: a bus delivering frames faster than the loop reads them (a flood on a
    vcan interface, which has no bitrate) kept it there for ever, no tick, no watchdog, outputs frozen at their last
    live values, Ctrl-C unheard. A tick now takes at most buses.TICK_FRAMES (the replay's limit; 1000 here) and leaves
    the rest for the next one. Here a finite flood of 5000 frames: tick 0 read them all before its first frame went out."""
    bus = FloodBus(5000)
    monkeypatch.setattr(buses, "TICK_FRAMES", 1000, raising=False)  # (the old code had none: it read all)
    monkeypatch.setattr("flowtex.runtime.live.open_bus", lambda *a, **k: bus)
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", bus="virtual:flood", max_ticks=8, status=None))
    assert r.error is None and r.ticks == 8 and r.frames_in == 5000 and r.no_sensor_frames
    sends_per_tick = 2  # VoiceCoilCmd, ForceCmd
    assert bus.read_before_send[::sends_per_tick][:6] == [1000, 2000, 3000, 4000, 5000, 5000]


class QueueFullBus(can.BusABC):
    """A socketcan-like bus whose transmit queue is full (ENOBUFS) on the sends numbered in ``full``; no sensor frames."""

    def __init__(self, full: set[int]):
        super().__init__(channel="queue")
        self.full, self.calls, self.sent = full, 0, []

    def _recv_internal(self, timeout):
        return None, False

    def send(self, msg, timeout=None):
        self.calls += 1
        if self.calls in self.full:
            raise can.CanOperationError("Failed to transmit: No buffer space available", errno.ENOBUFS)
        self.sent.append((msg.arbitration_id, bytes(msg.data)))


def test_a_transmit_queue_full_for_a_moment_does_not_end_the_session_or_leave_it_unsafe(setup, monkeypatch):  # noqa: F811
    """socketcan's ENOBUFS (the interface's queue of 10 frames filled while the bus was busy; python-can's select does not
    wait for it) ended the session at once, and at the exit left the safe values unsent ('could not send the safe values
    ... make it safe by hand') though the queue had room a moment later. A full queue now gets the send timeout (0.5 s)."""
    bus = QueueFullBus({3, 4, 5, 13})  # tick 1's second frame three times; the exit block's first frame once
    monkeypatch.setattr("flowtex.runtime.live.open_bus", lambda *a, **k: bus)
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", bus="virtual:queue", max_ticks=5, status=None))
    assert r.error is None and r.safe_sent and r.ticks == 5
    assert [fid for fid, _ in bus.sent] == [0x200, 0x201] * 6  # every tick's frames and the exit block, in order


def test_a_transmit_queue_that_stays_full_is_a_bus_error_naming_it():
    calls = []

    def full(msg, timeout):
        calls.append(timeout)
        raise can.CanOperationError("Failed to transmit: No buffer space available", errno.ENOBUFS)

    first = can.CanOperationError("Failed to transmit: No buffer space available", errno.ENOBUFS)
    with pytest.raises(can.CanOperationError, match=r"transmit queue stayed full for 0\.01 s \(is the device connected"):
        send_when_queued(full, can.Message(arbitration_id=0x200), 0.01, first)
    assert calls  # it tried again
    other = can.CanOperationError("Failed to transmit: Network is down", errno.ENETDOWN)
    with pytest.raises(can.CanOperationError, match="Network is down"):  # any other failure at once
        send_when_queued(full, can.Message(arbitration_id=0x200), 0.01, other)
