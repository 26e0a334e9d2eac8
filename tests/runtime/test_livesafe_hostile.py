"""Live safety against hostile DBCs, maps, outputs and start-up conditions (issue 27, section 1).

Every DBC is built here from the bundled example by editing one line. Sessions that run are recorded, and the
recorded frames are read back with python-can and decoded with cantools (independent of flowtex's codecs).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time

import can
import cantools
import pytest
from test_live import DBC, MAP, REPO, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)
from test_livesafe_dbc import BASE, _dbc

from flowtex.cli import main
from flowtex.errors import DataError, GraphError
from flowtex.graph.compiled import load_graph
from flowtex.io.atomic import OutputError
from flowtex.io.canlog import read_session
from flowtex.io.dbc import load_dbc
from flowtex.runtime.live import LiveConfig, run_live
from tests.child_signals import sigint_as_a_terminal_gives_it, signal_state

ENV = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
"""Subprocesses run the flowtex under test, whatever the folder they start in."""
ENABLE = ' SG_ Enable : 16|1@1+ (1,0) [0|1] "" HapticDevice'
MODE = ' SG_ Mode : 17|3@1+ (1,0) [0|7] "" HapticDevice'


def _frames(path) -> list[can.Message]:
    """The sent frames of a recorded session, read with python-can (not flowtex's reader)."""
    with can.LogReader(str(path)) as reader:
        return [m for m in reader if not m.is_rx]


def _session(setup, dbc, map_path=None, **kw):  # noqa: F811
    return run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, map_path or setup / "m.yaml", simulate=setup / "rec.npz", status=None, **kw))


@pytest.mark.parametrize("number,what", [(1 << 40, "which is no CAN ID"), (1 << 32, "which is no CAN ID"),
                                         (0x800, "standard CAN ID 0x800, beyond 11 bits"),
                                         ((1 << 31) | (1 << 29), "extended CAN ID 0x20000000, beyond 29 bits")])
def test_a_can_id_beyond_its_bits_is_refused_not_masked(setup, number, what):  # noqa: F811
    """cantools keeps the low 32 bits (2^40 -> ID 0x000, the highest priority on the bus): the number as written is checked."""
    dbc = _dbc(setup, "BO_ 513 ForceCmd", f"BO_ {number} ForceCmd")
    if number >= 1 << 32:  # what cantools alone makes of it: a frame id inside the legal range
        fid = cantools.database.load_string(dbc.read_text(), database_format="dbc").get_message_by_name("ForceCmd").frame_id
        assert fid == number & 0x7FFFFFFF
    line = BASE[:BASE.index("BO_ 513 ForceCmd")].count("\n") + 1
    with pytest.raises(DataError) as e:
        load_dbc(dbc)
    assert str(e.value).startswith(f"{dbc}:{line}: message 'ForceCmd' has ") and what in str(e.value), str(e.value)
    with pytest.raises(DataError):
        _session(setup, dbc, max_ticks=5, record=setup / "s.blf")
    assert not (setup / "s.blf").exists()


def test_an_extended_id_goes_out_as_written(setup):  # noqa: F811
    """Bit 31 marks an extended frame: 0x1ABCDE is sent as extended ID 0x1ABCDE (python-can) carrying the command (cantools)."""
    dbc = _dbc(setup, "BO_ 513 ForceCmd", f"BO_ {(1 << 31) | 0x1ABCDE} ForceCmd")
    r = _session(setup, dbc, max_ticks=20, record=setup / "s.blf")
    assert r.error is None
    db = cantools.database.load_file(dbc)
    force = [m for m in _frames(setup / "s.blf") if m.arbitration_id == 0x1ABCDE]
    assert len(force) == 21 and all(m.is_extended_id for m in force)
    assert db.decode_message(0x1ABCDE, force[-1].data) == {"Fx": 0.0, "Fy": 0.0, "Fz": 0.0}  # the exit frame


@pytest.mark.parametrize("old,new,sig,arrives", [(ENABLE, ENABLE.replace("[0|1]", "[1|1]"), "Enable", "1"),
                                                 (MODE, MODE.replace("[0|7]", "[2|7]"), "Mode", "2")])
def test_an_unbound_signal_whose_zero_the_dbc_cannot_carry_is_refused(setup, old, new, sig, arrives):  # noqa: F811
    """Unbound signals are sent as physical 0; a DBC range excluding 0 would put 'enabled' / mode 2 in every safe frame."""
    dbc = _dbc(setup, old, new)
    with pytest.raises(GraphError) as e:
        _session(setup, dbc, max_ticks=5, record=setup / "s.blf")
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{setup / 'm.yaml'}:")
    for part in (f"signal {sig!r} no output binds", f"would arrive as {arrives}", f"VoiceCoilCmd.{sig}"):
        assert part in msg, msg
    assert not (setup / "s.blf").exists()


def test_unbound_signals_go_out_as_zero_in_every_frame(setup):  # noqa: F811
    """With the example DBC (0 inside both ranges) every VoiceCoilCmd frame, the exit frame included, has Enable 0, Mode 0."""
    r = _session(setup, DBC, max_ticks=30, record=setup / "s.log")
    assert r.error is None
    db = cantools.database.load_file(DBC)
    coil = [db.decode_message(m.arbitration_id, m.data, decode_choices=False) for m in _frames(setup / "s.log") if m.arbitration_id == 0x200]
    assert len(coil) == 31
    assert all(d["Enable"] == 0 and d["Mode"] == 0 for d in coil)


def test_an_output_on_a_message_the_device_transmits_is_refused(setup):  # noqa: F811
    """ToolContact's transmitter (BO_ line) is HapticDevice, which sends the position the map reads: two senders on 0x102."""
    m = setup / "contact.yaml"
    m.write_text(textwrap.dedent(MAP).replace("{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}",
                                              "{signal: ToolContact.Penetration, clamp: [-1, 1], safe: 0}"))
    with pytest.raises(GraphError) as e:
        _session(setup, DBC, m, max_ticks=5)
    assert "output 'vibration' writes message 'ToolContact' (CAN ID 0x102), which the DBC says HapticDevice transmits" in str(e.value)
    # with no transmitter in the DBC (Vector__XXX) nothing says who sends it: not refused on this ground
    dbc = _dbc(setup, "BO_ 258 ToolContact: 3 HapticDevice", "BO_ 258 ToolContact: 3 Vector__XXX")
    r = _session(setup, dbc, m, max_ticks=5)
    assert r.error is None


@pytest.mark.parametrize("old,new,key", [
    ("overrun_limit_ms: 100000", "overrun_limit_ms: 1e13", "overrun_limit_ms"),
    ("normal_force: {signal: ToolForce.NormalForce, timeout_ms: 5}", "normal_force: {signal: ToolForce.NormalForce, timeout_ms: 1e300}",
     "timeout_ms"),
    ("clamp: [-1, 1], safe: 0}", "clamp: [-1, 1], safe: 0, peak: {limit: 1.5, max_ms: 1e300}}", "peak max_ms")])
def test_an_absurd_duration_in_the_map_is_refused_naming_its_line(setup, old, new, key, capsys):  # noqa: F811
    """Durations past what the watchdog's integer ns and ticks hold were an OverflowError: at tick 0 (overrun_limit_ms,
    'tick 0: OverflowError: int too big to convert') or an internal error (timeout_ms, peak max_ms)."""
    m = setup / "absurd.yaml"
    text = textwrap.dedent(MAP)
    assert old in text
    m.write_text(text.replace(old, new))
    rc = main(["live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(m), "--simulate", str(setup / "rec.npz"),
               "--duration", "0.05", "--quiet"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and not line.startswith("flowtex: compiling")]
    assert rc == 1 and len(err) == 1, err
    assert re.match(rf"{re.escape(str(m))}:\d+:\d+: .*{key} must be .*at most 86400000 \(one day\), got \S+$", err[0]), err


def test_stats_where_no_file_can_be_created_is_refused_before_the_session(setup):  # noqa: F811
    """As root, os.access says /sys/kernel is writable; creating a file there fails. Checked by creating one."""
    if not os.path.isdir("/sys/kernel") or not os.access("/sys/kernel", os.W_OK):
        pytest.skip("needs /sys/kernel reported writable (root)")
    for option, path in (("stats_path", "/sys/kernel/stats.json"), ("record", "/sys/kernel/s.blf")):
        with pytest.raises(OutputError, match=r"cannot create a file in folder /sys/kernel"):
            _session(setup, DBC, max_ticks=5, **{option: path})
    args = ["live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(setup / "m.yaml"), "--simulate", str(setup / "rec.npz"),
            "--duration", "0.05", "--quiet", "--record-audio", "/sys/kernel/out.wav"]
    assert main(args) == 1


def _holds_open(pid: int, path: str) -> bool:
    """True when process ``pid`` has ``path`` open (Linux: its /proc fd links; the slcan pty tests run on Linux only)."""
    fds = f"/proc/{pid}/fd"
    try:
        names = os.listdir(fds)
    except OSError:
        return False
    for name in names:
        try:
            if os.readlink(f"{fds}/{name}") == path:
                return True
        except OSError:
            continue
    return False


def _cli(setup, *extra, **kw):  # noqa: F811
    cmd = [sys.executable, "-m", "flowtex", "live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(setup / "m.yaml"), *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=setup, env=ENV, **kw)


def test_a_cpu_that_does_not_exist_is_refused_with_quiet(setup, capsys):  # noqa: F811
    allowed = sorted(os.sched_getaffinity(0))
    code = main(["live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(setup / "m.yaml"), "--simulate", str(setup / "rec.npz"),
                 "--duration", "0.05", "--quiet", "--rt", "--cpu", str(max(allowed) + 97)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "--cpu" in err[0] and "no such CPU" in err[0], err


def test_real_time_warnings_are_printed_with_quiet(setup, capsys):  # noqa: F811
    """--rt-priority 99 is granted to root; what is refused is printed (stderr) even without a status line."""
    r = _session(setup, DBC, max_ticks=5, rt=True, rt_priority=1000)  # outside SCHED_FIFO's 1..99: refused, not raised
    err = capsys.readouterr().err
    assert r.error is None and "real-time setup incomplete: priority 1000 outside SCHED_FIFO range" in err, err


def test_ctrl_c_during_start_up_says_interrupted_and_exits_130(setup):  # noqa: F811
    """SIGINT while the command loads (imports, numba, the graph's compile): one line, exit 130, no traceback."""
    for delay in (0.6, 1.2):
        session = setup / f"s{delay}.log"
        proc = _cli(setup, "--simulate", str(setup / "rec.npz"), "--duration", "30", "--quiet", "--record", str(session),
                    preexec_fn=sigint_as_a_terminal_gives_it)
        time.sleep(delay)
        state = signal_state(proc.pid)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        _out, err = proc.communicate(timeout=120)
        assert "Traceback" not in err, err
        # 0: the loop was already running, a clean stop. -SIGINT: CPython ends by re-raising SIGINT at exit once a
        # KeyboardInterrupt crossed its C-level code runner (during a cold numba compile), however it was then handled;
        # a shell sees 130 (128 + SIGINT) either way
        assert proc.returncode in (130, -signal.SIGINT, 0), err
        if proc.returncode != 0:
            assert err.strip().splitlines()[-1] == "interrupted", err
        else:  # the SIGINT stopped the loop: the session did not run its 30 s (docs/testing.md, "A Ctrl-C lost in a test's child")
            sent = sum(1 for m in read_session(session) if not m.is_rx)
            assert sent < 30_000, f"the SIGINT was lost ({sent} frames sent); signal state when it was sent: {state}; {err}"


def test_safe_values_not_sent_are_not_claimed_sent(setup):  # noqa: F811
    """The device (an slcan pty) vanishes mid-session: the line says the safe values could not be sent, not '(safe values sent)'."""
    dev = subprocess.Popen([sys.executable, "-m", "flowtex", "simulate-device", str(setup / "rec.npz"), "--pty", "--duration", "60",
                            "--dbc", str(DBC), "--map", str(setup / "m.yaml")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True, env=ENV)
    live = None
    try:
        m = re.search(r"--bus (flowtex_slcan:/dev/pts/\d+)", dev.stdout.readline())
        assert m
        live = _cli(setup, "--bus", m.group(1), "--duration", "60", "--quiet", "--record", str(setup / "s.log"))
        deadline = time.monotonic() + 120
        pts = m.group(1).split(":", 1)[1]
        # the loop runs once the runtime holds the pty open and its log exists (the log is created before the bus
        # opens: on a loaded machine the device was killed before the runtime had opened the pty at all)
        while not (_holds_open(live.pid, pts) and list(setup.glob(".s.*.part.log"))) and time.monotonic() < deadline:
            assert live.poll() is None, live.communicate()
            time.sleep(0.05)
        time.sleep(0.3)
        dev.kill()  # the device's end of the tty closes
        dev.wait(timeout=30)
        _out, err = live.communicate(timeout=60)
    finally:
        for p in (dev, live):
            if p is not None and p.poll() is None:
                p.kill()
    # the device stops sending when it dies, so the input watchdog may report the stale sensor (a true warning) in the
    # ticks before the first write fails; whether it does is a race between the kill and the next write
    lines = [line for line in err.strip().splitlines()
             if not line.startswith("flowtex: compiling") and not (line.startswith("watchdog: ") and "stale" in line)]
    assert live.returncode == 1 and len(lines) == 1, err
    assert "could not send the safe values" in lines[0] and "did not receive them" in lines[0], err
    assert "(safe values sent)" not in lines[0]
