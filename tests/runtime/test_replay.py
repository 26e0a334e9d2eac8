"""Replay of a recorded simulated session equals the live frames byte for byte."""

from __future__ import annotations

import cantools
import numpy as np
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.runtime.live import LiveConfig, run_live
from flowtex.runtime.replay import replay_session


def test_replay_equals_live_and_offline(setup):  # noqa: F811
    g = load_graph(setup / "g.yaml")
    live_log = setup / "live.blf"
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=600, record=live_log, status=None,
                               drop={"ToolPosition": (200, 260)}, seed=3))
    assert r.error is None and r.watchdog_events == 1
    g2 = load_graph(setup / "g.yaml")
    rep = replay_session(g2, live_log, DBC, setup / "m.yaml", setup / "replay.log", seed=3)
    assert rep.ticks == 600 and rep.exit_block
    # every tick the graph produced matches; the dropout ticks are explained by the watchdog
    assert rep.unexplained_ticks == [] and rep.overrun_ticks == []
    assert rep.mismatched_ticks == list(range(205, 260))  # last frame at tick 199, 5-tick timeout; back at 260
    assert rep.watchdog_ticks == rep.mismatched_ticks
    live_tx = [m for m in read_session(live_log) if not m.is_rx][:-2]
    replay_tx = [m for m in read_session(setup / "replay.log")]
    assert len(live_tx) == len(replay_tx) == 1200
    for k, (a, b) in enumerate(zip(live_tx, replay_tx, strict=True)):
        if not 205 <= k // 2 < 260:
            assert (a.arbitration_id, bytes(a.data)) == (b.arbitration_id, bytes(b.data))

    # .npz outputs equal an offline run over the inputs cantools decodes from the received frames
    rep2 = replay_session(load_graph(setup / "g.yaml"), live_log, DBC, setup / "m.yaml", setup / "out.npz", seed=3)
    assert rep2.mismatched_ticks == rep.mismatched_ticks
    db = cantools.database.load_file(DBC)
    pos = np.zeros(3)
    nf = 0.0
    P, F = [], []
    frames = list(read_session(live_log))
    for m in frames:
        if m.is_rx:
            d = db.decode_message(m.arbitration_id, m.data)
            if m.arbitration_id == 0x100:
                pos = np.array([d["PosX"], d["PosY"], d["PosZ"]], dtype=float)
            else:
                nf = float(d["NormalForce"])
        elif m.arbitration_id == 0x201:
            P.append(pos)
            F.append(nf)
    P, F = np.array(P[:600]), np.array(F[:600])
    ref = load_graph(setup / "g.yaml").run({"position": P, "normal_force": F}, seed=3)
    out = np.load(setup / "out.npz")
    np.testing.assert_array_equal(out["force"], ref["force"])
    np.testing.assert_array_equal(out["vibration"], ref["vibration"])


def test_replay_names_overrun_watchdog_ticks_and_real_mismatches_and_prints_a_summary(setup, capsys, monkeypatch):  # noqa: F811
    """A live log where tick 300 carries the safe values (what the overrun watchdog sends) and tick 400 other bytes."""
    from flowtex.cli import main
    from flowtex.io.canlog import SessionWriter

    g = load_graph(setup / "g.yaml")
    live_log = setup / "live.log"
    r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=500, record=live_log, status=None,
                               drop={"ToolPosition": (100, 130)}, seed=3))
    assert r.error is None
    frames = list(read_session(live_log))
    sent = [m for m in frames if not m.is_rx]
    assert len(sent) == 2 * 501  # 500 ticks of (VoiceCoilCmd, ForceCmd) and the exit block of safe values
    safe_voice, safe_force = bytes(sent[-2].data), bytes(sent[-1].data)
    # tick 300: the live run held the outputs safe with every sensor fresh (an overrun); tick 400: a real difference
    assert bytes(sent[600].data) != safe_voice
    sent[600].data, sent[601].data = bytearray(safe_voice), bytearray(safe_force)
    sent[800].data = bytearray(bytes([sent[800].data[0] ^ 0x10]) + bytes(sent[800].data[1:]))
    edited = setup / "edited.log"
    w = SessionWriter(edited)
    for m in frames:
        w.write(m, m.is_rx)
    w.close()

    rep = replay_session(load_graph(setup / "g.yaml"), edited, DBC, setup / "m.yaml", seed=3)
    assert rep.overrun_ticks == [300]
    assert rep.unexplained_ticks == [400]
    assert rep.watchdog_ticks == list(range(105, 130))  # last ToolPosition frame at tick 99, 5-tick timeout; back at 130
    assert rep.mismatched_ticks == sorted(rep.watchdog_ticks + rep.overrun_ticks + rep.unexplained_ticks)

    from flowtex.io import canlog

    reads, held = [], []
    open_once = canlog.open_session
    monkeypatch.setattr(canlog, "open_session", lambda path: reads.append(path) or open_once(path))
    monkeypatch.setattr(canlog, "read_session_checked", lambda path: held.append(path))  # holds every frame: not used
    assert main(["run", str(setup / "g.yaml"), "--input", str(edited), "--dbc", str(DBC), "--map", str(setup / "m.yaml"),
                 "--seed", "3", "--output", str(setup / "replay.npz")]) == 0
    assert reads == [str(edited)] and held == []  # opened once, its start checked before the compile: the replay streams it
    out = capsys.readouterr().out
    assert "ReplayReport(" not in out and "unexplained" not in out
    lines = out.strip().splitlines()
    received = 2 * 500 - 30  # two sensor frames a tick, no ToolPosition in ticks 100-129
    assert sum(m.is_rx for m in frames) == received
    assert lines[0] == f"replayed 500 ticks of {edited} ({received} frames received, 1002 sent live; the log ends with the exit block of safe values)"
    assert lines[1] == "473 ticks: actuator frames equal to the live ones byte for byte"
    assert lines[2].startswith("25 ticks (105-129): live sent the safe values because a sensor was stale")
    assert lines[3].startswith("1 tick (300): live sent the safe values with every sensor fresh: the overrun watchdog")
    assert lines[4].startswith("1 tick (400): DIFFER from the live frames and no watchdog explains it")
    assert lines[5] == f"wrote {setup / 'replay.npz'}"


def test_replay_errors_about_a_text_log_name_its_line(setup, capsys):  # noqa: F811
    """A malformed line (checked before the compile) and a frame out of place (found while splitting ticks): one
    line each, naming the log's line, exit code 1, no traceback."""
    from flowtex.cli import main

    log = setup / "live.log"
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=20,
                                                         record=log, status=None, seed=3))
    assert r.error is None
    lines = log.read_text().splitlines()
    sent = [i + 1 for i, line in enumerate(lines) if line.endswith(" T")]
    assert len(sent) == 2 * 21 and lines[sent[0] - 1].split()[2].startswith("200#")  # one block: 0x200 then 0x201
    cmd = ["run", str(setup / "g.yaml"), "--input", str(log), "--dbc", str(DBC), "--map", str(setup / "m.yaml"),
           "--seed", "3", "--output", str(setup / "replay.npz")]

    def replay_with(number: int, text: str) -> str:
        edited = list(lines)
        edited[number - 1] = text
        log.write_text("\n".join(edited) + "\n")
        assert main(cmd) == 1
        err = [e for e in capsys.readouterr().err.splitlines() if not e.startswith("flowtex: compiling")]  # the notice
        assert len(err) == 1 and "Traceback" not in err[0] and not (setup / "replay.npz").exists()
        return err[0]

    at = sent[6]  # the 0x200 frame of the fourth tick; the 0x201 frame follows it
    received = next(line for line in lines if line.endswith(" R"))
    assert replay_with(at, lines[at - 1].replace("200#", "2G0#")).startswith(f"{log}:{at}:")
    assert replay_with(at, lines[at]) == (
        f"{log}:{at}: sent frame 0x201 where the map's actuator message 0x200 was expected; was this session recorded "
        "with the same map?")
    # the right number as an extended ID: the message said 'sent frame 0x200 where ... 0x200 was expected'
    assert replay_with(at, lines[at - 1].replace("200#", "00000200#")) == (
        f"{log}:{at}: sent frame 0x200 (extended ID) where the map's actuator message 0x200 (standard ID) was expected; "
        "was this session recorded with the same map?")
    assert replay_with(at + 1, received).startswith(f"{log}:{at + 1}: frame 0x")

    # a BLF has no lines: the frame's position in the log (1-based) is named
    from flowtex.io.canlog import SessionWriter

    frames = list(read_session(setup / "live.log"))  # the last edit: a received frame inside a block, at frame `at + 1`
    blf = setup / "edited.blf"
    w = SessionWriter(blf)
    for m in frames:
        w.write(m, m.is_rx)
    w.close()
    assert main([*cmd[:3], str(blf), *cmd[4:]]) == 1
    err = [e for e in capsys.readouterr().err.splitlines() if not e.startswith("flowtex: compiling")]
    assert err == [f"{blf} (frame {at + 1}): frame 0x{frames[at].arbitration_id:x} received in the middle of an actuator "
                   "block; not a flowtex live session log"]


def test_replay_equals_live_with_a_peak_budget_across_a_watchdog_trip(setup):  # noqa: F811
    """Live's forced-safe ticks (ToolPosition dropped at ticks 200-259) refill the peak budget while the graph commands
    more than the clamp; the replay, which guards those ticks unforced to name them, must leave its guard state as
    live's forced ticks did, or it allows fewer peaks than live after the trip (ticks it then called unexplained)."""
    m = setup / "peak.yaml"
    m.write_text((setup / "m.yaml").read_text().replace(
        "clamp: [-1, 1], safe: 0}", "clamp: [-0.6, 0.6], safe: 0, peak: {limit: 1.0, max_ms: 5, recover_ms: 20}}"))
    live_log = setup / "live.blf"
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, m, simulate=setup / "rec.npz", max_ticks=600, record=live_log,
                                                          status=None, drop={"ToolPosition": (200, 260)}, seed=3))
    assert r.error is None and r.watchdog_events == 1
    assert r.summary["peak_limited"]["vibration"] == 0 and r.summary["clamped"]["vibration"] > 0
    rep = replay_session(load_graph(setup / "g.yaml"), live_log, DBC, m, seed=3)
    assert rep.unexplained_ticks == [] and rep.overrun_ticks == []
    assert rep.mismatched_ticks == rep.watchdog_ticks == list(range(205, 260))
