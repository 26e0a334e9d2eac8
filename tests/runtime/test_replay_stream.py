"""The replay streams its log: it reports and writes what the whole-list replay did, in memory that does not grow
with the session's length, and still refuses a bad log in one line with nothing left behind."""

from __future__ import annotations

import dataclasses
import re
import textwrap

import can
import numpy as np
import pytest
from can.io.blf import FILE_HEADER_STRUCT
from hypothesis import given, settings
from hypothesis import strategies as st
from long_session import FRAMES_PER_TICK, LongSession, peak_bytes
from replay_whole_list import replay_whole_list
from test_live import DBC, GRAPH, MAP

from flowtex import limits
from flowtex.errors import DataError, FlowtexError
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import SessionWriter, open_session, read_session, read_session_checked
from flowtex.runtime.live import LiveConfig, run_live
from flowtex.runtime.replay import replay_session


def _write(path, frames):
    w = SessionWriter(path)
    for m in frames:
        w.write(m, m.is_rx)
    w.close()
    return path


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """One simulated 500-tick session with a sensor dropped at ticks 100-129 (input watchdog), its tick 300 edited to
    the safe values (as the overrun watchdog sends) and tick 400 to other bytes (unexplained), in the three formats;
    and logs cut short: a BLF cut at 60 % and one whose header was never written, a .log and an .asc cut mid-line."""
    setup = tmp_path_factory.mktemp("stream")
    (setup / "g.yaml").write_text(textwrap.dedent(GRAPH))
    (setup / "m.yaml").write_text(textwrap.dedent(MAP))
    t = np.arange(800) / 1000.0
    pos = np.stack([100 * np.sin(2 * np.pi * t), 50 * np.cos(6 * np.pi * t), 10 + 0 * t], axis=1)
    np.savez(setup / "rec.npz", position=pos, normal_force=3 + np.sin(10 * np.pi * t), rate=np.float64(1000))
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=500,
                                                          record=setup / "live.blf", status=None,
                                                          drop={"ToolPosition": (100, 130)}, seed=3))
    assert r.error is None and r.watchdog_events == 1
    frames = list(read_session(setup / "live.blf"))
    sent = [m for m in frames if not m.is_rx]
    sent[600].data, sent[601].data = bytearray(sent[-2].data), bytearray(sent[-1].data)  # tick 300: the safe values
    sent[800].data = bytearray(bytes([sent[800].data[0] ^ 0x10]) + bytes(sent[800].data[1:]))  # tick 400: other bytes
    paths = {s: _write(setup / f"s{s}", frames) for s in (".blf", ".log", ".asc")}
    data = paths[".blf"].read_bytes()
    (setup / "cut.blf").write_bytes(data[:int(len(data) * 0.6)])
    header = list(FILE_HEADER_STRUCT.unpack_from(data))
    header[10], header[12] = 144, 0
    (setup / "killed.blf").write_bytes(FILE_HEADER_STRUCT.pack(*header) + data[FILE_HEADER_STRUCT.size:])
    for s in (".log", ".asc"):
        text = paths[s].read_bytes()
        (setup / f"cut{s}").write_bytes(text[:text.index(b"\n", len(text) // 2) + 12])
    return setup


def _both(setup, name, out=None):
    """The streamed replay's and the whole-list replay's reports (and outputs at ``new{out}``, ``old{out}``)."""
    new = replay_session(load_graph(setup / "g.yaml"), setup / name, DBC, setup / "m.yaml",
                         setup / f"new{out}" if out else None, seed=3)
    old = replay_whole_list(load_graph(setup / "g.yaml"), setup / name, DBC, setup / "m.yaml",
                            setup / f"old{out}" if out else None, seed=3)
    return new, old


@pytest.mark.parametrize("name", ["s.blf", "s.log", "s.asc", "cut.blf", "killed.blf", "cut.log", "cut.asc"])
def test_a_streamed_replay_reports_what_the_whole_list_replay_did(logs, name):
    new, old = _both(logs, name)
    assert dataclasses.asdict(new) == dataclasses.asdict(old)
    assert str(new) == str(old)
    if name.startswith("s."):  # the complete logs: every kind of tick is there
        assert new.exit_block and new.ticks == 500 and new.truncated is None
        assert new.watchdog_ticks == list(range(105, 130)) and new.overrun_ticks == [300] and new.unexplained_ticks == [400]
    else:
        assert new.truncated is not None and not new.exit_block and 0 < new.ticks
    if name == "cut.blf":  # the header's 1972 frames (1000 - 30 received, 1002 sent) at the found ticks' frames a tick
        found = list(can.BLFReader(logs / name))
        last = max(i for i, m in enumerate(found) if not m.is_rx and m.arbitration_id == 0x201)
        received = sum(m.is_rx for m in found[:last])
        assert new.expected_ticks == pytest.approx((1972 - 2) / (2 + received / new.ticks), rel=1e-12)


@pytest.mark.parametrize(("name", "out"), [("s.blf", ".npz"), ("cut.log", ".npz"), ("s.asc", ".log"), ("cut.blf", ".blf")])
def test_a_streamed_replay_writes_what_the_whole_list_replay_wrote(logs, name, out):
    new, old = _both(logs, name, out)
    assert new.ticks == old.ticks
    if out == ".npz":
        a, b = np.load(logs / "new.npz"), np.load(logs / "old.npz")
        assert sorted(a.files) == sorted(b.files) == ["force", "rate", "vibration"]
        for key in a.files:
            np.testing.assert_array_equal(a[key], b[key])  # bit for bit
        assert a["force"].shape == (new.ticks, 3)
    else:
        key = [(m.is_rx, m.arbitration_id, bytes(m.data), m.timestamp) for m in read_session(logs / f"new{out}")]
        assert key == [(m.is_rx, m.arbitration_id, bytes(m.data), m.timestamp) for m in read_session(logs / f"old{out}")]
        assert len(key) == 2 * new.ticks


@pytest.mark.parametrize("suffix", [".log", ".blf"])
def test_a_frame_out_of_place_late_in_the_log_is_named_and_leaves_no_output(logs, suffix):
    """Found while streaming, after ticks were replayed and written: the same one line as the whole-list replay's, and
    the output is not written (an older file of that name is left as it was)."""
    frames = list(read_session(logs / "s.blf"))
    sent = [i for i, m in enumerate(frames) if not m.is_rx]
    at = sent[2 * 450]  # the first frame of tick 450's block
    frames[at], frames[at + 1] = frames[at + 1], frames[at]
    bad = _write(logs / f"bad{suffix}", frames)
    errors = []
    for fn, out in ((replay_session, logs / "out.npz"), (replay_whole_list, logs / "out.npz")):
        out.write_bytes(b"older")
        with pytest.raises(DataError) as info:
            fn(load_graph(logs / "g.yaml"), bad, DBC, logs / "m.yaml", out, seed=3)
        assert out.read_bytes() == b"older"
        errors.append(str(info.value))
    assert errors[0] == errors[1]
    place = f"{bad}:{at + 1}" if suffix == ".log" else f"{bad} (frame {at + 1})"
    assert errors[0] == (f"{place}: sent frame 0x201 where the map's actuator message 0x200 was expected; was this session "
                         "recorded with the same map?")
    assert sorted(p.name for p in logs.iterdir() if p.name.startswith("out")) == ["out.npz"]  # no temporary file left


def test_the_start_check_fails_fast_and_the_replay_names_a_bad_line_at_the_end(logs):
    """open_session (before the compile) reads the log's start only: a malformed last line passes it and is named,
    with its line, by the replay that streams the whole log."""
    lines = (logs / "s.log").read_text().splitlines()
    bad = logs / "late.log"
    bad.write_text("\n".join([*lines[:-1], lines[-1].replace("#", "G")]) + "\n")
    session = open_session(bad)
    with pytest.raises(DataError, match=rf"^{re.escape(str(bad))}:{len(lines)}:\d+: frame '201G"):
        replay_session(load_graph(logs / "g.yaml"), bad, DBC, logs / "m.yaml", seed=3, log=session)
    early = logs / "early.log"
    early.write_text("\n".join([lines[0].replace("#", "G"), *lines[1:]]) + "\n")
    with pytest.raises(DataError, match=rf"^{re.escape(str(early))}:1:\d+: "):
        open_session(early)


def test_a_replay_whose_output_log_cannot_hold_the_frame_times_names_the_output(logs):
    """The replay's actuator frames keep live's times; an .asc output dates them, and a .log recorded with times out of a
    date's range made that an internal error (OverflowError), then a line naming the writer's temporary file."""
    far = logs / "far.log"
    far.write_text(re.sub(r"^\(\d+\.\d+\)", "(1e300)", (logs / "s.log").read_text(), flags=re.M))
    out = logs / "far_out.asc"
    with pytest.raises(DataError) as info:
        replay_session(load_graph(logs / "g.yaml"), far, DBC, logs / "m.yaml", out, seed=3)
    assert str(info.value).startswith(f"-o {out}: frame time 1e+300 s cannot be written in a .asc log") and not out.exists()
    assert replay_session(load_graph(logs / "g.yaml"), far, DBC, logs / "m.yaml", logs / "far_out.log", seed=3).ticks


def test_a_log_without_directions_says_so(logs, monkeypatch):
    """A candump -L log has no R/T direction, so python-can reads every frame as received: the replay found no tick
    and said only 'no complete tick' (or, past MAX_TICK_FRAMES, 'is this a flowtex live session log?')."""
    plain = logs / "plain.log"
    plain.write_text("".join(line[:-2] + "\n" for line in (logs / "s.log").read_text().splitlines(keepends=True)
                             if line.endswith((" R\n", " T\n"))))
    hint = "are all marked received and none is marked sent: a log without directions, as candump -L writes?"
    with pytest.raises(DataError, match=re.escape(hint)):
        replay_session(load_graph(logs / "g.yaml"), plain, DBC, logs / "m.yaml", seed=3)
    monkeypatch.setattr(limits, "MAX_TICK_FRAMES", 50)
    with pytest.raises(DataError) as info:
        replay_session(load_graph(logs / "g.yaml"), plain, DBC, logs / "m.yaml", seed=3)
    assert str(info.value).startswith(f"{plain}:51: more than 50 frames received in one tick") and hint in str(info.value)


def test_received_frames_without_a_block_are_refused_at_the_tick_limit(logs, monkeypatch):
    """The replay holds one tick's received frames: a log of received frames and no block is refused at the frame past
    MAX_TICK_FRAMES, naming it (the whole-list replay held them all and said there was nothing to replay)."""
    rx = [m for m in read_session(logs / "s.blf") if m.is_rx][:50]
    log = _write(logs / "rx_only.log", rx)
    monkeypatch.setattr(limits, "MAX_TICK_FRAMES", 50)
    with pytest.raises(DataError, match="nothing to replay: the log holds 50 frame"):
        replay_session(load_graph(logs / "g.yaml"), log, DBC, logs / "m.yaml", seed=3)
    monkeypatch.setattr(limits, "MAX_TICK_FRAMES", 49)
    with pytest.raises(DataError) as info:
        replay_session(load_graph(logs / "g.yaml"), log, DBC, logs / "m.yaml", seed=3)
    assert str(info.value).startswith(f"{log}:50: more than 49 frames received in one tick") and "\n" not in str(info.value)
    assert "MAX_TICK_FRAMES" in str(info.value)


@pytest.fixture(scope="module")
def long_session(tmp_path_factory):
    return LongSession(tmp_path_factory.mktemp("long"))


N = 1000


@pytest.mark.parametrize("suffix", [".blf", ".log"])
def test_replay_memory_does_not_grow_with_the_session(long_session, suffix):
    """tracemalloc's peak while replaying N and 4N ticks (four frames a tick, every tick equal to live). The frames the
    whole-list replay held for the 3N more ticks (measured here: read_session_checked's list, about 290 bytes a BLF
    frame and 360 a .log frame) add 3N x 4 x that: 3.5 MB (BLF) and 4.3 MB (.log) at N = 1000 (at N = 1500 its peak
    grew by 7.8 and 9.0 MB). The streamed replay's peak (0.86 MB for a BLF, 0.16 MB for a .log, at N as at 4N) moved
    by -2 to -3 KB (2026-11-27, N = 1500). Tolerance 5 % of the frame storage (175 KB; N = 1000 keeps the short BLF
    log beyond one 128 KiB container, so both runs hold the same reader state): what may grow is only the report's lists (empty:
    no tick differs) and the readers' state (one BLF container of 128 KiB, one text line), the same at N and 4N, so
    5 % (about 60 bytes a tick over the 3N ticks: a fifth of one frame) fails on any frame kept a tick, while passing
    tracemalloc's noise of a few KB."""
    s = long_session
    short, long = s.write(s.folder / f"n{suffix}", N), s.write(s.folder / f"4n{suffix}", 4 * N)
    graph = load_graph(s.graph)

    def replay(path):
        rep = replay_session(graph, path, s.dbc, s.map, seed=3)
        assert rep.identical and rep.exit_block and rep.ticks in (N, 4 * N)

    replay(short)  # first call: the map's codecs and the decoder tables are built and cached
    held = peak_bytes(lambda: read_session_checked(short)) / (N * FRAMES_PER_TICK + 2)
    assert 150 < held < 1000  # a python-can Message and its data: the storage the whole-list replay needed a frame
    growth = peak_bytes(lambda: replay(long)) - peak_bytes(lambda: replay(short))
    frame_storage = 3 * N * FRAMES_PER_TICK * held
    assert growth < 0.05 * frame_storage, (growth, frame_storage)


@settings(max_examples=20, deadline=None)
@given(suffix=st.sampled_from([".blf", ".log", ".asc"]), cut=st.floats(0.0, 1.0),
       flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(1, 255)), max_size=3))
def test_any_cut_or_corrupted_log_replays_as_the_whole_list_replay_did(logs, suffix, cut, flips):
    """Fuzz (hypothesis): a log cut anywhere, with a few bytes changed, gives the streamed replay the report the
    whole-list replay gave, or makes both fail in one line naming the file (which line may differ: the whole-list
    replay read every frame before splitting ticks, the streamed one meets a frame out of place before a later bad
    line)."""
    data = bytearray((logs / f"s{suffix}").read_bytes())
    for where, x in flips:
        data[int(where * (len(data) - 1))] ^= x
    path = logs / f"fuzz{suffix}"
    path.write_bytes(bytes(data[:int(cut * len(data))]))
    outcomes = []
    for fn in (replay_session, replay_whole_list):
        try:
            outcomes.append(dataclasses.asdict(fn(load_graph(logs / "g.yaml"), path, DBC, logs / "m.yaml", seed=3)))
        except FlowtexError as exc:
            assert "\n" not in str(exc) and str(path) in str(exc)
            outcomes.append("refused")
    assert outcomes[0] == outcomes[1]
