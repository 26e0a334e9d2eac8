"""CAN session logs a reader misread or held whole before: error frames in a .log flowtex itself wrote, an .asc whose
header has no 'internal events logged' line, a BLF object python-can skips that claims gigabytes, a container that claims
more than a container may hold, and a container python-can's frame parser cannot read (named at its byte)."""

from __future__ import annotations

import re

import can
import pytest
from can.io.blf import LOG_CONTAINER_STRUCT, OBJ_HEADER_BASE_STRUCT
from hypothesis import given, settings
from hypothesis import strategies as st
from test_canlog_bounds import FRAMES, _blf_parts, _container, _frames, _refused

from flowtex import limits
from flowtex.errors import DataError
from flowtex.io.canlog import SessionWriter, read_session, read_session_checked
from tests.memory import peak_bytes


def _session(path, error_frame):
    """A received 0x100, ``error_frame``, a sent 0x200, as live records them (error frames come in with the received)."""
    w = SessionWriter(path)
    w.write(can.Message(timestamp=1000.0, arbitration_id=0x100, is_extended_id=False, data=bytes(range(8))), True)
    w.write(error_frame, True)
    w.write(can.Message(timestamp=1000.002, arbitration_id=0x200, is_extended_id=False, data=bytes(4)), False)
    w.close()
    return path


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
@pytest.mark.parametrize("data", [bytes(8), b""])
def test_an_error_frame_live_recorded_reads_back_as_an_error_frame(tmp_path, suffix, data):
    """A bus error frame among the frames live received: python-can writes it in a .log as '20000080#...' (its
    CAN_ERR_FLAG | CAN_ERR_BUSERROR), which the .log line check refused as an ID above 29 bits, so flowtex could not
    read the session it had recorded."""
    err = can.Message(timestamp=1000.001, is_error_frame=True, arbitration_id=0x80, data=data, channel="can0")
    path = _session(tmp_path / f"s{suffix}", err)
    frames, completeness = read_session_checked(path)
    assert [(m.is_error_frame, m.arbitration_id if not m.is_error_frame else None) for m in frames] == [
        (False, 0x100), (True, None), (False, 0x200)]
    assert completeness.problem is None


def test_a_candump_error_frame_python_can_would_read_as_data_is_refused_at_its_line(tmp_path):
    """candump writes an error frame's class in its ID (CAN_ERR_FLAG 20000000 plus class bits); python-can reads it as
    an error frame only with the bus-error bit (80), else as an extended data frame of the class bits (ID 0x4 here)."""
    path = tmp_path / "s.log"
    path.write_text("(1000.000000) can0 100#0001020304050607 R\n(1000.000100) can0 20000004#0004000000000000\n")
    assert [m.arbitration_id for m in can.LogReader(path)] == [0x100, 0x4]  # python-can alone: a data frame
    with pytest.raises(DataError, match=re.escape(f"{path}:2:") + ".*error frame.*20000004.*class 4"):
        read_session_checked(path)


ASC_HEAD = "date Fri Nov 27 13:25:23.102 2026\nbase hex  timestamps absolute\n"
ASC_FRAMES = (" 0.000100 1  100             Rx   d 8 00 01 02 03 04 05 06 07\n"
              " 0.000200 1  200             Tx   d 4 00 00 00 00\n")


@pytest.mark.parametrize("head", ["", ASC_HEAD, "// a comment\n" + ASC_HEAD, ASC_HEAD + "\n"])
def test_an_asc_without_the_events_line_keeps_its_first_frame(tmp_path, head):
    """python-can's ASCReader reads header lines (date, base, comments) until 'internal events logged', and takes the
    line that ends the header without it as header too: a frame there was dropped without a word."""
    path = tmp_path / "s.asc"
    path.write_text(head + ASC_FRAMES)
    frames, _ = read_session_checked(path)
    assert [(m.arbitration_id, m.is_rx, len(m.data)) for m in frames] == [(0x100, True, 8), (0x200, False, 4)]
    full = tmp_path / "full.asc"
    full.write_text(ASC_HEAD + "internal events logged\n" + ASC_FRAMES)  # the reference: python-can's own layout
    assert [(round(m.timestamp, 6), m.arbitration_id) for m in frames] == [
        (round(m.timestamp, 6), m.arbitration_id) for m in read_session(full)]


def test_a_huge_object_python_can_skips_is_skipped_not_read(tmp_path):
    """An object of a type that holds no frames (here 999, 32 MiB of it) is passed over: it was read whole into memory
    (up to the 16 GiB a log may be) only to be dropped."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    size = 32 * 2**20
    path = tmp_path / "big.blf"
    with open(path, "wb") as fh:
        fh.write(header + OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", 16, 1, size, 999))
        fh.seek(size - OBJ_HEADER_BASE_STRUCT.size, 1)  # a sparse body
        fh.write(_container(inner))
    assert len(_frames(path)) == FRAMES
    assert peak_bytes(lambda: _frames(path)) < 4 * 2**20  # the 40 frames and one 128 KiB container, far below the 32 MiB


def test_a_container_claiming_more_than_a_container_holds_is_refused_before_it_is_read(tmp_path):
    """A container object claiming 64 MiB (sparse here) cannot hold a container of at most MAX_BLF_CONTAINER_BYTES
    unpacked; it was read whole before the unpacked size was checked."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    size = 64 * 2**20
    path = tmp_path / "claim.blf"
    with open(path, "wb") as fh:
        fh.write(header + OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", 16, 1, size, 10) + LOG_CONTAINER_STRUCT.pack(0, size))
        fh.truncate(len(header) + size)
    peak = peak_bytes(lambda: pytest.raises(DataError, _frames, path))
    assert peak < 4 * 2**20
    _refused(path, f"(byte {len(header)})", "67,108,864 bytes", "MAX_BLF_CONTAINER_BYTES")


def test_a_container_python_can_cannot_parse_is_named_at_its_byte(tmp_path):
    """A container of zeros: python-can's parser finds no object in it ('Could not find next object', no place)."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    path = tmp_path / "zeros.blf"
    path.write_bytes(header + _container(bytes(2**16)) + _container(inner))
    _refused(path, f"(byte {len(header)})", "Could not find next object")
    assert limits.MAX_BLF_CONTAINER_BYTES > 2**16


HEADER_LINES = ["date Fri Nov 27 13:25:23.102 2026", "base hex  timestamps absolute", "base hex  timestamps relative",
                "// a comment", "", "internal events logged", "no internal events logged",
                "Begin Triggerblock Fri Nov 27 13:25:23.102 2026", " 0.000000 Start of measurement", "a line of other text"]


@settings(max_examples=60, deadline=None)
@given(head=st.lists(st.sampled_from(HEADER_LINES), max_size=6))
def test_any_asc_header_keeps_every_frame(tmp_path_factory, head):
    """Whatever header lines come before the frames (in any order, or none), every frame is read: the line that ends
    python-can's header is never a frame."""
    path = tmp_path_factory.mktemp("asc") / "s.asc"
    path.write_text("".join(line + "\n" for line in head) + ASC_FRAMES)
    frames, _ = read_session_checked(path)
    assert [(m.arbitration_id, m.is_rx, bytes(m.data)) for m in frames] == [(0x100, True, bytes(range(8))),
                                                                          (0x200, False, bytes(4))]


@pytest.mark.parametrize("suffix", [".blf", ".asc"])
@pytest.mark.parametrize("stamp", [1e300, 1e308, -1e300])
def test_a_frame_time_a_writer_cannot_date_is_one_line_and_no_file(tmp_path, suffix, stamp):
    """python-can's .asc and .blf writers turn frame times into dates: a replay of a .log whose times are out of a
    date's range (1e300 s) into an .asc or .blf output was an internal error (OverflowError: timestamp out of range for
    platform time_t). The .log writer writes any time."""
    from flowtex.io.canlog import RecordError

    path = tmp_path / f"out{suffix}"
    path.write_bytes(b"an older log")
    w = SessionWriter(path)
    for i in range(3):
        w.write(can.Message(timestamp=stamp + i, arbitration_id=0x200, is_extended_id=False, data=bytes(4)), False)
    try:
        w.close()
    except RecordError as exc:
        msg = str(exc)
        assert msg.startswith(f"{path}: ") and "frame time" in msg and "a .log" in msg and "\n" not in msg, msg
    else:  # a writer that takes it (python-can's BLF keeps times relative to the first frame) must read back
        assert len(read_session(path).__next__().data) == 4
        return
    assert path.read_bytes() == b"an older log" and [p.name for p in tmp_path.iterdir()] == [path.name]


def test_a_base_line_after_the_header_is_ignored_as_python_can_ignores_it(tmp_path):
    """python-can reads 'base hex|dec' in the header only; the line check took one anywhere, and refused the hex bytes
    after a stray 'base dec' line ('data byte 'F3' is not a number in base 10') that python-can reads as hex."""
    path = tmp_path / "s.asc"
    path.write_text(ASC_HEAD + "internal events logged\n" + ASC_FRAMES + "base dec  timestamps absolute\n"
                    + " 0.000300 1  100             Rx   d 2 F3 0C\n")
    frames, _ = read_session_checked(path)
    assert [bytes(m.data) for m in frames] == [bytes(m.data) for m in can.LogReader(path)] == [
        bytes(range(8)), bytes(4), b"\xf3\x0c"]
