"""Live loop against the in-process simulated device (virtual bus). No timing asserts."""

from __future__ import annotations

import os
import re
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
from flowtex.runtime.live import BusError, LiveConfig, run_live

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
  k: {type: gain, params: {k: 0.01, unit: N}}
  v: {type: gain, params: {k: 0.25, unit: A}}
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
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=2000, record=rec, status=None))
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
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=1000, record=rec, status=None,
                               drop={"ToolForce": (300, 600)}))
    assert r.error is None
    assert r.watchdog_events == 1
    db = cantools.database.load_file(DBC)
    cur = np.array([db.decode_message(0x200, m.data)["Current"] for m in _tx(rec) if m.arbitration_id == 0x200])
    # last frame received at tick 299, timeout 5 ticks: tick 305 is the first stale tick
    assert np.all(cur[:305] > 0.4)
    assert np.all(cur[305:600] == 0.0)
    assert np.all(cur[600:1000] > 0.4)   # fresh again as soon as frames return
    assert cur[-1] == 0.0


class _Terminal(__import__("io").StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("terminal", [True, False], ids=["terminal", "log"])
def test_watchdog_events_get_their_own_named_line_beside_the_status_line(setup, caplog, terminal):
    import logging

    out = _Terminal() if terminal else __import__("io").StringIO()
    g = load_graph(setup / "g.yaml")
    with caplog.at_level(logging.WARNING, logger="flowtex.runtime.safety"):
        r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=1000, status=out,
                                   drop={"ToolForce": (300, 600)}))
    assert r.error is None and r.watchdog_events == 1
    text = out.getvalue()
    event = ("watchdog: tick 305: no ToolForce frame for input 'normal_force' in 5 ticks; "
             "outputs safe until every sensor has sent a fresh frame")
    lines = [chunk.strip() for chunk in text.replace("\r", "\n").split("\n")]
    assert event in lines  # a line of its own, not glued to the status line
    assert text.count("watchdog: tick") == 1
    assert not caplog.records  # printed once, not also logged
    status = [line for line in text.split("\n") if "| missed " in line]
    if terminal:  # over the status line, rewritten in place every 0.5 s: at tick 500 and at the end
        assert f"\r{event}" in text and text.count("\r") == 3
    else:  # a log: newline-terminated lines only, the status line every 5 s (none in this 1-s session) and the last
        assert "\r" not in text and len(status) == 1 and status[0].startswith("tick      1000 |"), text
        assert text.index(event) < text.index(status[0])


def test_bus_that_cannot_be_opened(setup):
    g = load_graph(setup / "g.yaml")
    with pytest.raises(BusError) as e:
        run_live(g, LiveConfig(DBC, setup / "m.yaml", bus="socketcan:flowtexnone0", max_ticks=10, status=None))
    assert "cannot open CAN bus" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(BusError, match="unknown interface"):
        run_live(g, LiveConfig(DBC, setup / "m.yaml", bus="nosuchbus:0", max_ticks=10, status=None))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_signal_leaves_safe_values_last(setup, sig):
    """Ctrl-C, SIGTERM and SIGHUP (the terminal closed) end the session cleanly: safe values last, exit code 0."""
    rec = setup / f"s{int(sig)}.log"
    cmd = [sys.executable, "-m", "flowtex", "live", str(setup / "g.yaml"), "--dbc", str(DBC),
           "--map", str(setup / "m.yaml"), "--simulate", str(setup / "rec.npz"), "--record", str(rec), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        deadline = time.monotonic() + 120
        # the log grows in a temporary file beside it (renamed over s*.log at the end: atomic)
        while time.monotonic() < deadline and sum(p.stat().st_size for p in setup.glob(f".{rec.stem}.*.part{rec.suffix}")) < 20000:
            time.sleep(0.1)
            assert proc.poll() is None, proc.stderr.read().decode()
        assert not rec.exists()
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err.decode()
    assert not list(setup.glob(".*.part.log"))
    tx = _tx(rec)
    assert len(tx) > 100
    db = cantools.database.load_file(DBC)
    assert db.decode_message(0x200, tx[-2].data)["Current"] == 0.0
    assert [db.decode_message(0x201, tx[-1].data)[k] for k in ("Fx", "Fy", "Fz")] == [0, 0, 0]
    assert db.decode_message(0x200, tx[-4].data)["Current"] > 0.4  # the tick before was a live one


# --- compiled table codecs (the live hot path) against cantools ------------------------------
TABLE_DBC = """VERSION ""

NS_ :
    SIG_VALTYPE_

BS_:

BU_: A B

BO_ 100 Mixed: 8 A
 SG_ LeOdd : 3|11@1- (0.25,-3.5) [0|0] "" B
 SG_ BeOdd : 21|13@0+ (0.1,100) [0|0] "" B
 SG_ OneBit : 24|1@1+ (1,0) [0|1] "" B
 SG_ BeSigned7 : 38|7@0- (2,1) [0|0] "" B
 SG_ LeTail : 52|12@1+ (0.5,0) [0|2000] "" B

BO_ 101 Floats: 8 A
 SG_ F32 : 0|32@1- (1,0) [0|0] "" B
 SG_ F32Be : 39|32@0- (0.5,2) [0|0] "" B

BO_ 102 Double: 8 A
 SG_ F64 : 7|64@0- (1,0) [0|0] "" B

BO_ 103 Short: 3 A
 SG_ Cur : 0|16@1- (0.0001,0) [-2|2] "A" B
 SG_ Id : 16|8@1+ (1,0) [0|0] "" B

BO_ 104 BigOnly: 5 A
 SG_ W : 7|40@0+ (0.001,-5) [0|0] "" B

SIG_VALTYPE_ 101 F32 : 1;
SIG_VALTYPE_ 101 F32Be : 1;
SIG_VALTYPE_ 102 F64 : 2;
"""


@pytest.fixture(scope="module")
def table_db(tmp_path_factory):
    path = tmp_path_factory.mktemp("dbc") / "t.dbc"
    path.write_text(TABLE_DBC)
    return cantools.database.load_file(path)


def _random_payload(rng, msg):
    data = bytearray(rng.integers(0, 256, msg.length, dtype=np.uint8).tobytes())
    if any(s.is_float for s in msg.signals):  # keep floats finite (NaN != NaN would hide nothing but complicates ==)
        for s in msg.signals:
            if s.is_float:
                ref = msg.decode(bytes(data), decode_choices=False)
                if not np.isfinite(ref[s.name]):
                    data = bytearray(msg.encode({n: (1.25 if n == s.name else v) for n, v in ref.items()}, strict=False))
    return data


def test_table_decoder_equals_cantools_bit_for_bit(table_db):
    from flowtex.io.codec import MessageCodec
    from flowtex.io.codec_tables import TableDecoder, fast_ok

    rng = np.random.default_rng(7)
    msgs = table_db.messages
    codecs = [MessageCodec(m) for m in msgs]
    assert all(fast_ok(c) for c in codecs)
    arena = np.full(64, np.nan)
    stamps = np.full(len(msgs), -1, dtype=np.int64)
    entries, where = [], []
    pos = 0
    for mi, c in enumerate(codecs):
        targets = []
        for si in range(len(c.signals)):
            k, off = (1.0, 0.0) if si % 2 == 0 else (0.5, 3.25)  # the map's graph = physical * scale + offset
            targets.append((pos, k, off))
            where.append((mi, c.signals[si], pos, k, off))
            pos += 1
        entries.append((c, targets, [mi]))
    dec = TableDecoder(entries)
    for trial in range(300):
        payloads = [_random_payload(rng, m) for m in msgs]
        present = [i for i in range(len(msgs)) if rng.random() < 0.7]
        before = arena.copy()
        mask = 0
        for i in present:
            dec.words[dec.slot_of[msgs[i].frame_id]] = int.from_bytes(payloads[i], "little", signed=True)
            mask |= 1 << dec.slot_of[msgs[i].frame_id]
        dec.run(mask, trial, arena, stamps)
        for mi, sig, p, k, off in where:
            if mi in present:
                ref = msgs[mi].decode(bytes(payloads[mi]), decode_choices=False)[sig]
                expect = float(ref) if (k, off) == (1.0, 0.0) else float(ref) * k + off
                assert arena[p] == expect or (np.isnan(arena[p]) and np.isnan(expect)), (msgs[mi].name, sig, payloads[mi].hex())
            else:
                assert arena[p] == before[p] or np.isnan(before[p])
        assert [int(stamps[i]) for i in present] == [trial] * len(present)


def _clamped(sig, v):
    if sig.minimum is not None and v < sig.minimum:
        return sig.minimum
    if sig.maximum is not None and v > sig.maximum:
        return sig.maximum
    return v


def test_table_encoder_equals_cantools_with_clamp_and_saturation(table_db):
    from flowtex.io.codec import MessageCodec
    from flowtex.io.codec_tables import TableEncoder

    rng = np.random.default_rng(11)
    msgs = table_db.messages
    codecs = [MessageCodec(m) for m in msgs]
    values = np.zeros(64)
    entries, bound = [], []
    pos = 0
    for c in codecs:
        src = []
        for si, name in enumerate(c.signals):
            if name == "Id":  # unbound: sent as physical 0
                src.append(None)
                continue
            k, off = (1.0, 0.0) if si % 2 == 0 else (2.0, -0.5)  # DBC physical = graph value * k + off
            src.append((pos, k, off))
            bound.append(pos)
            pos += 1
        entries.append((c, src))
    enc = TableEncoder(entries)
    half_steps = 0
    for _trial in range(300):
        # physical values inside each signal's raw range (so cantools can be the reference), some exactly halfway
        # between two raw steps (round half to even), some beyond the DBC [min|max] (clamped first)
        for c, (_, src) in zip(codecs, entries, strict=True):
            for s, t in zip(c.message.signals, src, strict=True):
                if t is None:
                    continue
                if s.is_float:
                    phys = float(np.float32(rng.normal(0, 1000))) if s.length == 32 else rng.normal(0, 1e6)
                else:
                    raw_lo, raw_hi = (-(1 << (s.length - 1)), (1 << (s.length - 1)) - 1) if s.is_signed else (0, (1 << s.length) - 1)
                    raw = int(rng.integers(raw_lo, raw_hi + 1)) if raw_hi > raw_lo else raw_lo
                    frac = 0.5 if (rng.random() < 0.3 and raw < raw_hi) else 0.0
                    half_steps += frac > 0
                    phys = (raw + frac) * s.scale + s.offset
                    if s.maximum is not None and rng.random() < 0.1:
                        phys = s.maximum + 1.0
                values[t[0]] = (phys - t[2]) / t[1]
        enc.run(values)
        for mi, (c, src) in enumerate(zip(codecs, (e[1] for e in entries), strict=True)):
            phys = {}
            for s, t in zip(c.message.signals, src, strict=True):
                v = 0.0 if t is None else values[t[0]] * t[1] + t[2]
                phys[s.name] = _clamped(s, v)
            expect = c.message.encode(phys, strict=False)
            got = bytes(enc.payload[enc.offsets[mi]:enc.offsets[mi + 1]])
            assert got == expect, (c.name, phys, got.hex(), expect.hex())
    assert half_steps > 100
    # saturation: a raw value beyond the bit length saturates (cantools would wrap), here without a DBC range
    for p in bound:
        values[p] = 0.0
    mixed = codecs[0]
    i_le = [i for i, (c, src) in enumerate(entries) if c is mixed][0]
    values[entries[i_le][1][0][0]] = 1e9      # LeOdd: 11-bit signed, scale 0.25 -> raw max 1023
    values[entries[i_le][1][1][0]] = -1e9     # BeOdd: 13-bit unsigned -> raw 0
    enc.run(values)
    got = mixed.message.decode(bytes(enc.payload[enc.offsets[i_le]:enc.offsets[i_le + 1]]), decode_choices=False)
    assert got["LeOdd"] == 1023 * 0.25 - 3.5
    assert got["BeOdd"] == pytest.approx(100.0)


def test_fast_ok_refuses_what_the_tables_cannot_reproduce(tmp_path):
    from flowtex.io.codec import MessageCodec
    from flowtex.io.codec_tables import fast_ok

    (tmp_path / "w.dbc").write_text(TABLE_DBC.replace('BO_ 104 BigOnly: 5 A\n SG_ W : 7|40@0+ (0.001,-5) [0|0] "" B',
                                                      'BO_ 104 Wide: 8 A\n SG_ W : 7|64@0- (1,0) [0|0] "" B'))
    db = cantools.database.load_file(tmp_path / "w.dbc")
    assert not fast_ok(MessageCodec(db.get_message_by_name("Wide")))  # 64-bit integers: the Python path is exact
    assert fast_ok(MessageCodec(db.get_message_by_name("Double")))


OVERLOAD_PLUGIN = '''
import numpy as np
from numba import njit
from flowtex.node_api import Node, NodeState, Param, Port


@njit
def overload_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        if x[t, 0] > p[0]:
            raise ValueError("sensor overload")
        y[t, 0] = x[t, 0]


class Overload(Node):
    """Pass x through; raise inside the compiled kernel when x exceeds a limit (a graph that fails mid-session)."""

    type_name = "test_overload"
    params = {"limit": Param("float", doc="largest accepted x")}
    inputs = {"x": Port((), "*", "signal")}
    outputs = {"y": Port("=x", "=x", "x")}
    kernel = overload_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["limit"]]))
'''


def test_exception_inside_the_graph_sends_safe_values_last(setup, flowtex_cli):
    plugins = setup / "plugins"
    plugins.mkdir()
    (plugins / "overload.py").write_text(OVERLOAD_PLUGIN)
    (setup / "boom.yaml").write_text(textwrap.dedent(GRAPH).replace("normal_force -> v.x", "normal_force -> ov.x\n  - ov.y -> v.x")
                                     .replace("  v: {type: gain", "  ov: {type: test_overload, params: {limit: 3.5}}\n  v: {type: gain"))
    g = load_graph(setup / "boom.yaml", plugins=(plugins,))
    # the first tick whose normal force, as the DBC carries it (0.001 N steps), exceeds 3.5 N
    nf = np.load(setup / "rec.npz")["normal_force"]
    first = int(np.argmax(np.round(nf / 0.001) * 0.001 > 3.5))
    assert 10 < first < 100
    log = setup / "boom.log"
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=500, record=log, status=None))
    assert r.exit_reason == "error" and r.ticks == first
    assert r.error == f"tick {first}: ValueError: sensor overload"
    tx = _tx(log)
    assert len(tx) == 2 * first + 2
    db = cantools.database.load_file(DBC)
    assert db.decode_message(0x200, tx[-2].data)["Current"] == 0.0
    assert [db.decode_message(0x201, tx[-1].data)[k] for k in ("Fx", "Fy", "Fz")] == [0, 0, 0]
    assert db.decode_message(0x200, tx[-4].data)["Current"] > 0.4  # the last regular tick was live
    assert r.device.frames_received == 2 * first + 2

    # the command line reports it as one line and exit code 1 (in this process: the verb's report is the point; the
    # signal tests above run flowtex live as a process of its own)
    p = flowtex_cli("live", setup / "boom.yaml", "--plugins", plugins, "--dbc", DBC, "--map", setup / "m.yaml", "--simulate",
                    setup / "rec.npz", "--duration", "0.5", "--quiet")
    assert p.returncode == 1
    # one line for the error; the only other lines allowed are the compile notice (when this process misses the disk
    # cache) and the list of plugin files loaded
    lines = [ln for ln in p.stderr.splitlines() if not ln.startswith(("flowtex: compiling graph", "flowtex: loaded plugin code"))]
    assert lines == [f"tick {first}: ValueError: sensor overload (safe values sent)"]


@pytest.mark.parametrize("rate", [1000.0, 250.0])
def test_peak_durations_off_the_tick_grid_never_allow_more_than_the_map_says(setup, rate):
    """max_ms and recover_ms that are not whole ticks: the allowance holds at most max_ms (whole ticks, rounded down) and
    refills over at least recover_ms (rounded up), so 'for at most max_ms' and the long-run share max_ms / (max_ms +
    recover_ms) of docs/live.md hold. Rounding to the nearest tick allowed 11 ms of peak for max_ms 10.6 at 1 kHz."""
    from flowtex.io.canmap import load_map
    from flowtex.io.codec import MessageCodec
    from flowtex.io.dbc import load_dbc
    from flowtex.runtime.canio import CanIO, port_widths

    max_ms, recover_ms = 10.6, 16.2  # ticks: 10.6 and 16.2 at 1 kHz, 2.65 and 4.05 at 250 Hz
    (setup / "frac.yaml").write_text(textwrap.dedent(MAP).replace(
        "vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}",
        f"vibration: {{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0, peak: {{limit: 1.5, max_ms: {max_ms}, "
        f"recover_ms: {recover_ms}}}}}"))
    g = load_graph(setup / "g.yaml")
    db = load_dbc(DBC)
    canmap = load_map(setup / "frac.yaml", db, DBC, port_widths(g.inputs), port_widths(g.outputs))
    io = CanIO(g, canmap, {m.name: MessageCodec(m) for m in db.messages}, rate)  # the guard at another live rate
    p, r = int(io.guard.peak_max_ticks[0]), int(io.guard.peak_recover_ticks[0])
    tick_ms = 1000.0 / rate
    assert (p, r) == ((10, 17) if rate == 1000.0 else (2, 5))  # floor and ceil of the durations in ticks (nearest: 11, 16; 3, 4)
    assert p * tick_ms <= max_ms < (p + 1) * tick_ms and r * tick_ms >= recover_ms
    assert p / (p + r) <= max_ms / (max_ms + recover_ms)


def test_a_peak_budget_beyond_int64_names_the_output_and_its_line(setup):
    """Day-long max_ms and recover_ms at 1 MHz: 86,400,000,000 and 86,399,999,000 ticks, gcd 1000, a budget of
    86.4e9 x 86,399,999 = 7.5e18 units > 2^62. The error named only the map file and the guard's internals."""
    from flowtex.errors import DataError
    from flowtex.io.canmap import load_map
    from flowtex.io.codec import MessageCodec
    from flowtex.io.dbc import load_dbc
    from flowtex.runtime.canio import CanIO, port_widths

    (setup / "day.yaml").write_text(textwrap.dedent(MAP).replace(
        "vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}",
        "vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0, peak: {limit: 1.5, max_ms: 86400000, "
        "recover_ms: 86399999}}"))
    g = load_graph(setup / "g.yaml")
    db = load_dbc(DBC)
    canmap = load_map(setup / "day.yaml", db, DBC, port_widths(g.inputs), port_widths(g.outputs))
    codecs = {m.name: MessageCodec(m) for m in db.messages}
    assert CanIO(g, canmap, codecs, 1000.0).guard is not None  # 86,400,000 x 86,399,999 units fit at 1 kHz
    with pytest.raises(DataError) as info:
        CanIO(g, canmap, codecs, 1e6)
    msg = str(info.value)
    assert re.match(re.escape(str(setup / "day.yaml")) + r":\d+:\d+: output 'vibration': peak max_ms 86400000 and "
                    r"recover_ms 86399999 are 86400000000 and 86399999000 ticks at 1e\+06 Hz", msg), msg


def test_map_peak_limit_is_mirrored_below_the_clamp(setup):
    from flowtex.runtime.live import load_io

    (setup / "peak.yaml").write_text(textwrap.dedent(MAP).replace(
        "vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}",
        "vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0, peak: {limit: 1.5, max_ms: 3}}").replace(
        "clamp: [-4, 4], safe: [0, 0, 0]}", "clamp: [[-4, 4], [-4, 4], [0, 8]], safe: [0, 0, 0], peak: {limit: [4, 4, 10], max_ms: 2}}"))
    g = load_graph(setup / "g.yaml")
    io = load_io(g, DBC, setup / "peak.yaml")
    # outputs in map order: vibration, force x/y/z. "|value| up to 1.5" for the symmetric clamp; the margin
    # above HIGH (10 - 8 = 2) mirrored below LOW (0 - 2) for the asymmetric one
    assert io.guard.peak_hi.tolist() == [1.5, 4, 4, 10]
    assert io.guard.peak_lo.tolist() == [-1.5, -4, -4, -2]
    assert io.guard.peak_max_ticks.tolist() == [3, 2, 2, 2]  # max_ms in ticks at 1 kHz
    assert io.guard.peak_recover_ticks.tolist() == [180, 120, 120, 120]  # recover_ms absent: 60 x max_ms
    # a command of -3 N on z: within the peak range -2 for 2 ticks, then the clamp's 0
    fz = g.output_view("force")
    seen = []
    for _ in range(4):
        fz[:] = [0.0, 0.0, -3.0]
        io.guard_outputs(False)
        seen.append(io.out[3])
    assert seen == [-2.0, -2.0, 0.0, 0.0]


# --- a session that hears nothing (issue 9 item 5) -------------------------------------------------
def test_a_session_without_any_sensor_frame_says_so_and_exits_3(setup, flowtex_cli):
    # the user's mistake: no --simulate and no device on the bus; a private virtual channel nobody sends on (in this
    # process: exit code 3 is what flowtex.cli.main returns; the signal tests run flowtex live as a process of its own)
    channel = f"flowtex-silent-{os.getpid()}"
    p = flowtex_cli("live", setup / "g.yaml", "--bus", f"virtual:{channel}", "--dbc", DBC, "--map", setup / "m.yaml",
                    "--duration", "0.3", "--quiet")
    assert p.returncode == 3, p.stderr
    last = p.stderr.strip().splitlines()[-1]
    assert last.startswith("no sensor frame received in ")
    # names the expected messages with the DBC's frame ids, and the bus
    assert "ToolPosition (id 0x100)" in last and "ToolForce (id 0x101)" in last, last
    assert f"bus 'virtual:{channel}'" in last and "safe values" in last


def test_one_silent_sensor_message_is_named_but_not_an_error(setup):
    g = load_graph(setup / "g.yaml")
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=200, status=None, drop={"ToolForce": (0, None)}))
    assert r.error is None and not r.no_sensor_frames
    assert r.silent_messages == ["ToolForce"]
    assert r.silence.startswith("no frame of ToolForce (id 0x101) received in 200 ticks on the simulated device's virtual bus")
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=50, status=None))
    assert r.silent_messages == [] and r.silence is None and not r.no_sensor_frames


def test_a_simulated_recording_stating_another_unit_is_refused_before_the_session(setup):
    """--simulate checks the units its recording states against the graph inputs', as flowtex run does
    (tests/test_cli_run.py): before, a normal force stated in mN drove an input in N, 1000x too strong, silently."""
    from flowtex.errors import DataError

    d = dict(np.load(setup / "rec.npz"))
    np.savez(setup / "rec.npz", **d, units=np.array('{"position": "mm", "normal_force": "mN"}'))
    g = load_graph(setup / "g.yaml")
    with pytest.raises(DataError, match=r"rec.npz: signal 'normal_force' is in 'mN' \(the file's units\) but graph '.*' input "
                                        r"'normal_force' takes N; flowtex converts no unit: multiply it by 0.001"):
        run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=20, status=None))
    np.savez(setup / "rec.npz", **d, units=np.array('{"position": "mm", "normal_force": "N"}'))
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=20, status=None))
    assert r.error is None and r.ticks == 20
