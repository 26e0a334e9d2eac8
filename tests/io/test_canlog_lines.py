"""Every error about a text CAN session log (.log candump -L, .asc) names the file and the line (and the column).

The valid logs are written by flowtex's own SessionWriter (python-can's writers); the reference for what a valid log
holds is python-can's own ``can.LogReader`` reading the same file.
"""

from __future__ import annotations

import re

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.errors import DataError
from flowtex.io.canlog import SessionWriter, read_session, read_session_checked

N_FRAMES = 12


def _write_log(path, n=N_FRAMES):
    """A session of ``n`` frames: received 0x100 (8 bytes) and sent 0x200 (4 bytes), alternately."""
    w = SessionWriter(path)
    for i in range(n):
        rx = i % 2 == 0
        w.write(can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100 if rx else 0x200, is_extended_id=False,
                            data=bytes([i, 1, 2, 3, 4, 5, 6, 7]) if rx else bytes([i, 9, 9, 9])), rx)
    w.close()
    return path


def _replace_line(path, number, text):
    lines = path.read_text().split("\n")
    lines[number - 1] = text
    path.write_text("\n".join(lines))


def _key(m):
    return (round(m.timestamp, 6), m.arbitration_id, m.is_extended_id, m.is_rx, bytes(m.data))


@pytest.mark.parametrize("suffix", [".log", ".asc"])
def test_valid_logs_read_as_python_can_reads_them_with_the_line_of_each_frame(tmp_path, suffix):
    path = _write_log(tmp_path / f"s{suffix}")
    reference = list(can.LogReader(path))
    frames, completeness = read_session_checked(path)
    assert [_key(m) for m in frames] == [_key(m) for m in reference] and len(frames) == N_FRAMES
    assert [_key(m) for m in read_session(path)] == [_key(m) for m in reference]
    # the line of each frame, found independently: the lines that hold a frame's direction
    text = path.read_text().splitlines()
    expected = [i + 1 for i, line in enumerate(text) if re.search(r" (R|T|Rx|Tx)( |$)", line)]
    assert list(completeness.lines) == expected and len(expected) == N_FRAMES


LOG_CASES = {  # the line, what the error says, and where its column points (the first occurrence of that text)
    "bad hex in the data": ("(1000.004000) can0 100#04010203ZZ050607 R", "is not hexadecimal (character 'Z')", "ZZ"),
    "bad CAN ID": ("(1000.004000) can0 1G0#0401020304050607 R", "CAN ID '1G0' is not 1 to 8 hexadecimal digits", "1G0"),
    "standard ID above 7FF": ("(1000.004000) can0 FFF#0401020304050607 R", "standard CAN ID FFF is above 7FF", "FFF"),
    "extended ID above 29 bits": ("(1000.004000) can0 FFFFFFFF#0401020304050607 R", "extended CAN ID FFFFFFFF is above 1FFFFFFF",
                                  "FFFFFFFF"),
    "truncated line": ("(1000.004000) can0", "2 field(s) where '(TIMESTAMP) CHANNEL ID#DATA' is expected: is the line cut?", "("),
    "data cut to an odd number of digits": ("(1000.004000) can0 100#040102030405060 R", "odd number of hex digits (15)", "0401"),
    "no # between ID and data": ("(1000.004000) can0 1000401020304050607 R", "has no '#' between the CAN ID and the data", "1000401"),
    "bad timestamp": ("(1000.0x4000) can0 100#0401020304050607 R", "timestamp '(1000.0x4000)' is not '(SECONDS)'", "("),
    "bad direction": ("(1000.004000) can0 100#0401020304050607 X", "direction 'X' must be R (received) or T (sent)", " X"),
    "CAN FD flags python-can cannot read": ("(1000.004000) can0 100##F0401020304050607 R", "CAN FD flags 'F' after '##'", "F04"),
    "too many data bytes": ("(1000.004000) can0 100#040102030405060708 R", "9 data bytes; a classic CAN frame holds at most 8", "0401"),
    "NUL byte (binary)": ("(1000.004000) can0 100#04010203\x0004050607 R", "byte 0x00 is not text", "\x00"),
}


@pytest.mark.parametrize("kind", list(LOG_CASES))
@pytest.mark.parametrize("line", [1, 5, N_FRAMES])
def test_each_malformed_log_line_is_named_by_file_line_and_column(tmp_path, kind, line):
    text, says, at = LOG_CASES[kind]
    column = text.index(at) + 1 + (at == " X")
    path = _write_log(tmp_path / "s.log")
    _replace_line(path, line, text)
    with pytest.raises(DataError) as err:
        read_session_checked(path)
    message = str(err.value)
    assert message.startswith(f"{path}:{line}:{column}: ") and says in message
    assert "\n" not in message
    with pytest.raises(DataError, match=re.escape(f"{path}:{line}:{column}: ")):
        list(read_session(path))


@pytest.mark.parametrize("suffix", [".log", ".asc"])
def test_a_byte_order_mark_is_read_past(tmp_path, suffix):
    """A log saved by a Windows editor starts with a UTF-8 byte-order mark; the .log's first timestamp was refused
    ('\\ufeff(1000.000000)' is not '(SECONDS)')."""
    path = _write_log(tmp_path / f"s{suffix}")
    plain = [_key(m) for m in read_session_checked(path)[0]]
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    frames, completeness = read_session_checked(path)
    assert [_key(m) for m in frames] == plain and len(plain) == N_FRAMES and completeness.problem is None


def test_python_can_alone_misread_the_odd_digit_line_that_is_now_refused(tmp_path):
    """The old reader (python-can's, unchecked) took 15 hex digits for 8 bytes, the last one made up."""
    path = _write_log(tmp_path / "s.log")
    _replace_line(path, 1, LOG_CASES["data cut to an odd number of digits"][0])
    assert bytes(next(iter(can.LogReader(path))).data) == bytes([4, 1, 2, 3, 4, 5, 6, 0])
    with pytest.raises(DataError, match="odd number of hex digits"):
        read_session_checked(path)


@settings(max_examples=25, deadline=None)
@given(line=st.integers(1, N_FRAMES), kind=st.sampled_from(sorted(LOG_CASES)))
def test_the_line_named_is_the_malformed_one_wherever_it_is(tmp_path_factory, line, kind):
    path = _write_log(tmp_path_factory.mktemp("log") / "s.log")
    _replace_line(path, line, LOG_CASES[kind][0])
    with pytest.raises(DataError, match=re.escape(f"{path}:{line}:")):
        read_session_checked(path)


def test_a_binary_file_named_log_is_refused_at_its_first_line(tmp_path):
    path = tmp_path / "s.log"
    path.write_bytes(bytes(range(128, 256)) * 40)  # no newline, not UTF-8: a BLF or anything else renamed
    with pytest.raises(DataError, match=re.escape(f"{path}:1:1: byte 0x80 is not text: is this a binary file named .log?")):
        list(read_session(path))
    path.write_bytes(b"\x00\x01\x02\n" * 10)  # valid UTF-8, but control characters
    with pytest.raises(DataError, match=re.escape(f"{path}:1:1: byte 0x00 is not text")):
        read_session_checked(path)


def test_an_endless_line_is_refused_without_reading_it_whole(tmp_path):
    path = tmp_path / "s.log"
    path.write_bytes(b"A" * (70 * 1024) + b"\n")
    with pytest.raises(DataError, match=re.escape(f"{path}:1: a line longer than 64 KiB")):
        read_session_checked(path)


def test_timestamps_going_backwards_are_read_in_file_order(tmp_path):
    """Not refused: the replay uses the frames' order, never their times, and received frames carry the interface's
    clock, which need not agree with the host's clock that stamps the sent ones."""
    path = _write_log(tmp_path / "s.log")
    _replace_line(path, 5, "(900.000000) can0 100#0401020304050607 R")
    frames, completeness = read_session_checked(path)
    assert [m.timestamp for m in frames][3:6] == [pytest.approx(1000.003), 900.0, pytest.approx(1000.005)]
    assert completeness.problem is None


def test_a_cut_last_line_is_left_out_even_when_it_would_not_parse(tmp_path):
    path = _write_log(tmp_path / "s.log")
    path.write_bytes(path.read_bytes() + b"(1000.0120")
    frames, completeness = read_session_checked(path)
    assert len(frames) == N_FRAMES and completeness.problem == "its last line is cut off"
    with pytest.raises(DataError, match=re.escape(f"{path}:{N_FRAMES + 1}:1: 1 field(s)")):
        list(read_session(path))  # without the completeness check the cut line is read, and named


ASC_CASES = {
    "bad hex in the data": ("d 8 04 01 02 ZZ 04 05 06 07", "data byte 'ZZ' is not a number in base 16"),
    "bad CAN ID": (None, "CAN ID '1G0' is not a number in base 16"),
    "truncated after the ID": (None, "the frame line ends after '100': is the line cut?"),
    "fewer bytes than the DLC": ("d 8 04 01", "DLC 8 announces 8 data bytes but the line holds 2: is the line cut?"),
    "bad DLC": ("d Q 04 01 02 03 04 05 06 07", "DLC 'Q' is not a number"),
    "bad timestamp": (None, "timestamp '0.0x4000' is not a number of seconds"),
    "NaN timestamp": (None, "timestamp 'nan' is not a number of seconds"),  # a number to float(), skipped by python-can
    "infinite timestamp": (None, "timestamp '1e400' is not a number of seconds"),
    "negative timestamp": (None, "timestamp '-0.004' is not a number of seconds"),
    "timestamp without a point": (None, "timestamp '4' is not a number of seconds"),
    "standard ID above 7FF": (None, "standard CAN ID FFF is above 7FF"),
    "extended ID above 29 bits": (None, "extended CAN ID FFFFFFFF is above 1FFFFFFF"),
}


@pytest.mark.parametrize("kind", list(ASC_CASES))
def test_each_malformed_asc_frame_line_is_named_by_file_and_line(tmp_path, kind):
    path = _write_log(tmp_path / "s.asc")
    lines = path.read_text().split("\n")
    number = next(i for i, s in enumerate(lines) if " Rx " in s) + 1 + 2  # the second received frame
    old = lines[number - 1]
    head = old[:old.index(" d ")]  # ' 0.004000 1  100             Rx'
    tail, says = ASC_CASES[kind]
    new = {"bad CAN ID": old.replace(" 100 ", " 1G0 "), "truncated after the ID": head[:head.index(" 100 ") + 4],
           "bad timestamp": re.sub(r"^\s*\S+", " 0.0x4000", old), "NaN timestamp": re.sub(r"^\s*\S+", " nan", old),
           "infinite timestamp": re.sub(r"^\s*\S+", " 1e400", old), "negative timestamp": re.sub(r"^\s*\S+", " -0.004", old),
           "timestamp without a point": re.sub(r"^\s*\S+", " 4", old), "standard ID above 7FF": old.replace(" 100 ", " FFF "),
           "extended ID above 29 bits": old.replace(" 100 ", " FFFFFFFFx ")}.get(kind) or f"{head} {tail}"
    _replace_line(path, number, new)
    with pytest.raises(DataError) as err:
        read_session_checked(path)
    assert re.match(re.escape(f"{path}:{number}") + r"(:\d+)?: ", str(err.value)) and says in str(err.value)
    # python-can alone skips or misreads these lines without a word (or fails without saying where)
    try:
        got = [(m.arbitration_id, bytes(m.data)) for m in can.LogReader(path)]
    except ValueError:
        return
    assert len(got) < N_FRAMES or got[2] != (0x100, bytes([2, 1, 2, 3, 4, 5, 6, 7]))


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
def test_a_session_log_given_as_a_recording_says_how_to_replay_it(tmp_path, suffix):
    """flowtex plot s.log (or fit, resample) said only "unknown recording format '.log'", a suffix flowtex does read."""
    from flowtex.io.recordings import load_recording

    path = _write_log(tmp_path / f"s{suffix}")
    with pytest.raises(DataError, match=re.escape(f"{path}: a CAN session log, not a recording (.npz, .csv, .h5 or .wav); "
                                                  f"replay it into one: flowtex run GRAPH.yaml --input {path} --dbc")):
        load_recording(path)


def test_valid_candump_variants_read_as_python_can_reads_them(tmp_path):
    """Lines the check must let through: plain candump -L (no direction), CRLF endings, extended IDs, remote frames,
    CAN FD frames with flags, empty data, blank lines."""
    lines = ["(1000.000100) can0 100#0A1B2C3D", "(1000.000200) can0 1FFFFFFF#00 R", "(1000.000300) can1 123#R T",
             "(1000.000400) can0 123#R4", "", "(1000.000500) can0 321##1" + "AB" * 12 + " T", "(1000.000600) vcan0 7FF# R"]
    path = tmp_path / "s.log"
    path.write_bytes("\r\n".join(lines).encode() + b"\r\n")
    frames, completeness = read_session_checked(path)
    reference = list(can.LogReader(path))
    assert len(frames) == 6 and [_key(m) for m in frames] == [_key(m) for m in reference]
    assert [m.is_fd for m in frames] == [False] * 4 + [True, False] and frames[1].is_extended_id
    assert list(completeness.lines) == [1, 2, 3, 4, 6, 7] and completeness.problem is None


def test_asc_can_fd_lines_are_checked_as_classic_ones_are(tmp_path):
    """A CAN FD line as python-can writes it reads back; cut short, python-can took the bytes left for the whole frame
    (a 12-byte frame read as 1 byte) without a word, and a bad byte failed with no column."""
    path = tmp_path / "s.asc"
    w = SessionWriter(path)
    w.write(can.Message(timestamp=1000.0, arbitration_id=0x321, is_fd=True, bitrate_switch=True, data=bytes(range(12)),
                        is_extended_id=False), True)
    w.close()
    frames, _ = read_session_checked(path)
    assert [(m.is_fd, bytes(m.data)) for m in frames] == [(True, bytes(range(12)))]
    lines = path.read_text().split("\n")
    number = next(i for i, s in enumerate(lines) if " CANFD " in s) + 1
    fd = lines[number - 1]
    data_at = fd.index(" 00 01 02")
    cut = fd[:data_at] + " 00"
    _replace_line(path, number, cut)
    assert [len(m.data) for m in can.LogReader(path)] == [1]  # python-can alone
    with pytest.raises(DataError, match=re.escape(f"{path}:{number}:1: CAN FD data length 12 announces 12 bytes but the "
                                                  "line holds 1: is the line cut?")):
        read_session_checked(path)
    _replace_line(path, number, fd[:data_at] + " 00 ZZ" + fd[data_at + 6:])
    with pytest.raises(DataError, match=re.escape(f"{path}:{number}:1: data byte 'ZZ' is not a number in base 16")):
        read_session_checked(path)

