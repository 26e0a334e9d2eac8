"""Replaying a session log cut short says so: how many ticks the session had and how many the log holds."""

from __future__ import annotations

import textwrap

import can
import numpy as np
import pytest
from can.io.blf import FILE_HEADER_STRUCT
from hypothesis import given, settings
from hypothesis import strategies as st
from test_live import DBC, GRAPH, MAP

from flowtex.errors import FlowtexError
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session_checked
from flowtex.runtime.live import LiveConfig, run_live
from flowtex.runtime.replay import replay_session

TICKS = 600


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A complete 600-tick BLF and .log of one simulated session (two sensor and two actuator frames a tick)."""
    setup = tmp_path_factory.mktemp("session")  # noqa: F811
    (setup / "g.yaml").write_text(textwrap.dedent(GRAPH))
    (setup / "m.yaml").write_text(textwrap.dedent(MAP))
    t = np.arange(TICKS) / 1000.0
    pos = np.stack([100 * np.sin(2 * np.pi * t), 50 * np.cos(6 * np.pi * t), 10 + 0 * t], axis=1)
    np.savez(setup / "rec.npz", position=pos, normal_force=3 + np.sin(10 * np.pi * t), rate=np.float64(1000))
    g = load_graph(setup / "g.yaml")
    for name in ("s.blf", "s.log"):
        r = run_live(g, LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=TICKS, record=setup / name, status=None, seed=3))
        assert r.error is None and r.ticks == TICKS
    return setup


def _replay(setup, path):
    return replay_session(load_graph(setup / "g.yaml"), path, DBC, setup / "m.yaml", seed=3)


def _complete_blocks(frames: list[can.Message]) -> int:
    """Independent count: (0x200, 0x201) pairs sent by the runtime, in order."""
    sent = [m.arbitration_id for m in frames if not m.is_rx]
    return sum(1 for a, b in zip(sent[::2], sent[1::2], strict=False) if (a, b) == (0x200, 0x201))


def test_a_complete_log_replays_every_tick_and_says_all(session):
    rep = _replay(session, session / "s.blf")
    assert rep.truncated is None and rep.exit_block and rep.ticks == TICKS
    assert f"{TICKS} ticks: actuator frames equal to the live ones byte for byte (all of them)" in str(rep)


@pytest.mark.parametrize("fraction", [0.3, 0.75])
def test_a_truncated_blf_says_how_many_ticks_it_expected_and_found(session, fraction):
    data = (session / "s.blf").read_bytes()
    cut = session / "cut.blf"
    cut.write_bytes(data[:int(len(data) * fraction)])
    frames = list(can.BLFReader(cut))  # python-can reads up to the cut without a word
    found = _complete_blocks(frames)
    assert 0 < found < TICKS
    rep = _replay(session, cut)
    assert rep.ticks == found and not rep.exit_block  # the last complete block is a tick, not the exit block
    assert rep.expected_ticks == TICKS  # (8002 header frames - 2 exit frames) / (2 received + 2 sent a tick)
    text = str(rep)
    assert f"the log is TRUNCATED: {len(data[:int(len(data) * fraction)])} of the {len(data)} bytes and {len(frames)} of the " \
           f"{4 * TICKS + 2} frames its header states are in the file" in text
    assert f"expected {TICKS} ticks, found {found}: the rest of the session is not in the log" in text
    assert "(all of them)" not in text
    assert rep.unexplained_ticks == []


def test_a_blf_whose_header_was_never_written(session):
    """A recording killed before closing: python-can's header still says 144 bytes and 0 frames."""
    data = bytearray((session / "s.blf").read_bytes())
    header = list(FILE_HEADER_STRUCT.unpack_from(data))
    header[10], header[12] = 144, 0
    FILE_HEADER_STRUCT.pack_into(data, 0, *header)
    killed = session / "killed.blf"
    killed.write_bytes(bytes(data))
    frames, completeness = read_session_checked(killed)
    assert completeness.expected_frames is None and "header was never written" in completeness.problem
    rep = _replay(session, killed)
    assert rep.ticks == _complete_blocks(frames) == TICKS + 1  # the exit block cannot be told apart: replayed as a tick
    assert f"found {TICKS + 1} ticks; the log does not say how many the session had" in str(rep)


def test_a_text_log_cut_in_the_middle_of_a_line(session):
    data = (session / "s.log").read_bytes()
    cut_at = data.index(b"\n", len(data) // 2) + 12  # a dozen bytes into a line
    cut = session / "cut.log"
    cut.write_bytes(data[:cut_at])
    whole_lines = session / "lines.log"
    whole_lines.write_bytes(data[:data.rindex(b"\n", 0, cut_at) + 1])
    rep = _replay(session, cut)
    assert rep.truncated == "its last line is cut off" and not rep.exit_block
    assert rep.ticks == _complete_blocks(list(can.LogReader(whole_lines)))
    assert f"found {rep.ticks} ticks; the log does not say how many the session had" in str(rep)


@settings(max_examples=25, deadline=None)
@given(cut=st.floats(0.0, 1.0), flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(1, 255)), max_size=3))
def test_any_cut_or_corrupted_blf_replays_or_fails_in_one_line(session, cut, flips):
    """Fuzz (hypothesis): a BLF cut anywhere, with a few bytes changed, replays what it holds (saying it is cut) or
    ends in one line naming the file; never another exception."""
    data = bytearray((session / "s.blf").read_bytes())
    for where, x in flips:
        data[int(where * (len(data) - 1))] ^= x
    path = session / "fuzz.blf"
    path.write_bytes(bytes(data[:int(cut * len(data))]))
    try:
        rep = _replay(session, path)
    except FlowtexError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    if cut < 0.99 and not flips:
        assert rep.truncated is not None and "(all of them)" not in str(rep)
