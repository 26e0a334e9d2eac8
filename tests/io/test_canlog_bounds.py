"""CAN session logs are read within documented bounds, whatever the file claims (docs/recordings.md, Limits).

Every hostile file here is small: the claims are forged in headers, the sizes made by sparse files, and the frame
limit lowered (``monkeypatch``) so that a log of a few frames stands for one of millions. Each reader call is capped
with ``islice`` so that a reader that loops for ever fails the test instead of hanging it.
"""

from __future__ import annotations

import itertools
import os
import signal
import struct
import zlib
from pathlib import Path

import can
import pytest
from can.io.blf import FILE_HEADER_STRUCT, LOG_CONTAINER_STRUCT, OBJ_HEADER_BASE_STRUCT

from flowtex import limits
from flowtex.cli import main
from flowtex.errors import DataError
from flowtex.io import canlog_blf
from flowtex.io.canlog import SessionWriter, read_session, read_session_checked

REPO = Path(__file__).resolve().parents[2]
FRAMES = 40


def _write_log(path: Path) -> Path:
    w = SessionWriter(path)
    for i in range(FRAMES):
        w.write(can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100 + i % 3, data=bytes([i] * 8),
                            is_extended_id=False), i % 2 == 0)
    w.close()
    return path


def _frames(path: Path, most: int = 10 * FRAMES) -> list[can.Message]:
    """At most ``most`` frames of the log (a reader that repeats a frame for ever stops here, and the test fails)."""
    return list(itertools.islice(read_session(path), most))


def _refused(path: Path, *needles: str) -> str:
    with pytest.raises(DataError) as info:
        _frames(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "\n" not in msg, msg
    for needle in needles:
        assert needle in msg, msg
    return msg


def _blf_parts(path: Path, write: bool = True) -> tuple[bytes, bytes]:
    """A BLF written by flowtex (``_write_log``, or the file at ``path``) as (its file header, the unpacked data of its one
    container)."""
    data = (_write_log(path) if write else path).read_bytes()
    head = FILE_HEADER_STRUCT.unpack_from(data)[1]
    _, _, _, size, _ = OBJ_HEADER_BASE_STRUCT.unpack_from(data, head)
    assert data[head + size:].strip(b"\0") == b""  # one container holds the 40 frames
    body = data[head + OBJ_HEADER_BASE_STRUCT.size + LOG_CONTAINER_STRUCT.size: head + size]
    return data[:head], zlib.decompress(body)


def _container(payload: bytes, compressed: bytes | None = None) -> bytes:
    """One LOG_CONTAINER object holding ``payload`` zlib-compressed (or the given compressed bytes)."""
    body = LOG_CONTAINER_STRUCT.pack(2, len(payload)) + (zlib.compress(payload) if compressed is None else compressed)
    size = OBJ_HEADER_BASE_STRUCT.size + len(body)
    return OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", 16, 1, size, 10) + body + b"\0" * (size % 4)


def _filler(size: int = 2**20) -> bytes:
    """A container holding one object of a type python-can skips (it reads no frame from it), ``size`` bytes."""
    return _container(OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", 32, 1, size, 999) + bytes(size - OBJ_HEADER_BASE_STRUCT.size))


def test_forged_blf_is_read_like_the_real_one(tmp_path):
    """The helpers rebuild a log python-can reads: the forgeries below differ from it only where they say."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    path = tmp_path / "same.blf"
    path.write_bytes(header + _container(inner))
    assert [m.data for m in _frames(path)] == [bytes([i] * 8) for i in range(FRAMES)]


@pytest.mark.parametrize("version", [1, 9])
def test_blf_frame_object_of_size_zero_is_refused_not_repeated(tmp_path, version):
    """python-can yields the same frame for ever when a frame object's size is 0; when the object's header version is
    one it does not know (9), it skips the object onto itself for ever without a frame (a replay fuzz case hung, and
    pytest's log capture of python-can's warning grew by 60 MB/s)."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    bad = bytearray(inner)
    struct.pack_into("<HI", bad, 6, version, 0)  # the first frame object's header version and obj_size
    path = tmp_path / "zero.blf"
    path.write_bytes(header + _container(bytes(bad)))

    def hung(signum, frame):  # the loop yields no frame for islice to stop: a reader that hangs fails here instead
        raise AssertionError("the BLF reader did not return within 20 s")

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(20)
    try:
        _refused(path, "(byte 144)", "an object in this container claims 0 bytes, less than its 16-byte header")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def test_blf_frame_data_that_looks_like_a_small_object_header_is_read(tmp_path):
    """The byte pattern of a too-small object inside a frame's data (a CAN FD frame's 64 bytes) is not an object: the
    objects are walked as python-can walks them, and the log reads as written."""
    w = SessionWriter(tmp_path / "d.blf")
    looks = (b"LOBJ" + bytes(4) + bytes([5, 0, 0, 0])) * 5 + bytes(4)  # 64 bytes, five look-alike headers of size 5
    for i in range(FRAMES):
        w.write(can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100, data=looks, is_fd=True,
                            is_extended_id=False), True)
    w.close()
    header, inner = _blf_parts(tmp_path / "d.blf", write=False)
    assert canlog_blf._SMALL_OBJECT.search(inner)  # the fast search finds it; the walk does not
    assert [m.data for m in _frames(tmp_path / "d.blf")] == [looks] * FRAMES


def test_blf_zlib_bomb_is_refused_before_it_is_unpacked(tmp_path):
    """64 MiB of zeros compress to 64 KiB; python-can unpacks any container whole."""
    header, _ = _blf_parts(tmp_path / "w.blf")
    zipper = zlib.compressobj(9)
    bomb = b"".join(zipper.compress(bytes(2**20)) for _ in range(64)) + zipper.flush()
    path = tmp_path / "bomb.blf"
    path.write_bytes(header + _container(b"", compressed=bomb))
    _refused(path, "(byte 144)", "MAX_BLF_CONTAINER_BYTES", f"{limits.MAX_BLF_CONTAINER_BYTES / 2**20:g} MiB")


def test_blf_frame_object_claiming_to_span_every_container_is_refused(tmp_path):
    """A frame object claiming 2 GiB makes python-can keep every later container in memory, joined again each time."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    bad = bytearray(inner)
    struct.pack_into("<I", bad, 8, 2**31)
    filler = _container(bytes(2**20))
    path = tmp_path / "span.blf"
    path.write_bytes(header + _container(bytes(bad)) + filler * 20)
    _refused(path, "spans more than", "MiB of containers")


def test_blf_object_smaller_than_its_header_is_refused(tmp_path):
    header, inner = _blf_parts(tmp_path / "w.blf")
    obj = bytearray(_container(inner))
    struct.pack_into("<I", obj, 8, 3)
    path = tmp_path / "small.blf"
    path.write_bytes(header + bytes(obj))
    _refused(path, "(byte 144)", "claims 3 bytes, less than its 16-byte header")


def test_blf_header_claiming_a_huge_header_is_refused(tmp_path):
    header, inner = _blf_parts(tmp_path / "w.blf")
    forged = bytearray(header)
    struct.pack_into("<I", forged, 4, 2**31)
    path = tmp_path / "head.blf"
    path.write_bytes(bytes(forged) + _container(inner))
    _refused(path, "header claims to be 2,147,483,648 bytes long")


def test_blf_header_counting_more_frames_than_the_limit_is_refused_before_reading(tmp_path, monkeypatch):
    header, inner = _blf_parts(tmp_path / "w.blf")
    monkeypatch.setattr(canlog_blf, "BoundedBLFReader", None)  # reading a frame would fail with a TypeError
    fields = list(FILE_HEADER_STRUCT.unpack(header[:FILE_HEADER_STRUCT.size]))
    fields[12] = limits.MAX_CANLOG_FRAMES + 1
    path = tmp_path / "count.blf"
    path.write_bytes(FILE_HEADER_STRUCT.pack(*fields) + header[FILE_HEADER_STRUCT.size:] + _container(inner))
    _refused(path, f"its header counts {limits.MAX_CANLOG_FRAMES + 1:,} frames", "MAX_CANLOG_FRAMES")


def test_blf_containers_unpacking_past_the_log_limit_are_refused(tmp_path, monkeypatch):
    header, inner = _blf_parts(tmp_path / "w.blf")
    path = tmp_path / "many.blf"
    path.write_bytes(header + _container(inner) + _filler() * 12)
    monkeypatch.setattr(canlog_blf, "MAX_CANLOG_BYTES", 20 * 2**20)
    assert len(_frames(path)) == FRAMES  # 12 MiB unpacked: read
    monkeypatch.setattr(canlog_blf, "MAX_CANLOG_BYTES", 10 * 2**20)
    _refused(path, "unpack to more than 10 MiB", "MAX_CANLOG_BYTES")  # 10 MiB stands for 1 GiB


@pytest.mark.parametrize("suffix", [".blf", ".log", ".asc"])
def test_logs_with_more_frames_than_the_limit_are_refused_at_the_frame(tmp_path, monkeypatch, suffix):
    """The same log is read at the limit and refused one frame below it, naming where the limit was passed."""
    path = _write_log(tmp_path / f"s{suffix}")
    if suffix == ".blf":  # a header that counts no frame (as a killed session's): the frames are counted as read
        data = bytearray(path.read_bytes())
        fields = list(FILE_HEADER_STRUCT.unpack_from(data))
        fields[12] = 0
        data[:FILE_HEADER_STRUCT.size] = FILE_HEADER_STRUCT.pack(*fields)
        path.write_bytes(bytes(data))
    monkeypatch.setattr(limits, "MAX_CANLOG_FRAMES", FRAMES)
    assert len(_frames(path)) == FRAMES
    monkeypatch.setattr(limits, "MAX_CANLOG_FRAMES", FRAMES - 1)
    where = f"{path} (frame {FRAMES})" if suffix == ".blf" else f"{path}:"
    msg = _refused(path, f"more than {FRAMES - 1:,} frames", "MAX_CANLOG_FRAMES")
    assert msg.startswith(where), msg
    with pytest.raises(DataError, match="MAX_CANLOG_FRAMES"):
        read_session_checked(path)


@pytest.mark.parametrize("suffix", [".log", ".asc"])
def test_text_logs_with_more_lines_than_the_limit_are_refused_at_the_line(tmp_path, monkeypatch, suffix):
    """Blank lines are no frames, yet each costs the line reader's time: they are bounded too."""
    path = _write_log(tmp_path / f"s{suffix}")
    lines = len(path.read_bytes().splitlines())
    monkeypatch.setattr(limits, "MAX_CANLOG_LINES", lines)
    assert len(_frames(path)) == FRAMES
    path.write_bytes(path.read_bytes() + b"\n")
    _refused(path, f"more than {lines:,} lines", "MAX_CANLOG_LINES")
    assert str(path) + f":{lines + 1}: " in _refused(path)


@pytest.mark.parametrize("suffix", [".blf", ".log", ".asc"])
def test_a_folder_or_an_empty_file_named_as_a_log(tmp_path, suffix):
    folder = tmp_path / f"f{suffix}"
    folder.mkdir()
    _refused(folder, "is a folder, not a CAN log")
    empty = tmp_path / f"e{suffix}"
    empty.write_bytes(b"")
    if suffix == ".blf":
        _refused(empty, "not a BLF log", "0 bytes read")
    else:
        assert _frames(empty) == []  # an empty text log holds no frame; the replay says there is nothing to replay


@pytest.mark.parametrize("suffix", [".blf", ".log", ".asc"])
def test_log_larger_than_the_limit_is_refused_by_its_size(tmp_path, suffix):
    """A sparse file (it occupies a few KiB) with a real log at its start, past MAX_CANLOG_BYTES."""
    path = _write_log(tmp_path / f"big{suffix}")
    with open(path, "r+b") as fh:
        fh.truncate(limits.MAX_CANLOG_BYTES + 1)
    _refused(path, f"up to {limits.MAX_CANLOG_BYTES / 2**20:g} MiB")


def test_replay_of_a_forged_blf_is_one_line(tmp_path, capsys):
    """``flowtex run`` with the size-0 object: exit 1 and one line, before the graph is compiled."""
    header, inner = _blf_parts(tmp_path / "w.blf")
    bad = bytearray(inner)
    struct.pack_into("<I", bad, 8, 0)
    path = tmp_path / "zero.blf"
    path.write_bytes(header + _container(bytes(bad)))
    before = sorted(os.listdir(tmp_path))
    code = main(["run", str(REPO / "graphs" / "live_texture.yaml"), "--input", str(path), "--dbc",
                 str(REPO / "graphs" / "devices" / "example.dbc"), "--map", str(REPO / "graphs" / "devices" / "example_map.yaml"),
                 "-o", str(tmp_path / "out.npz")])
    err = capsys.readouterr().err.strip()
    assert code == 1 and len(err.splitlines()) == 1 and "claims 0 bytes, less than its 16-byte header" in err, err
    assert sorted(os.listdir(tmp_path)) == before  # no output, no temporary file


def test_a_python_can_without_the_blf_frame_parser_is_one_line(tmp_path, monkeypatch):
    """The bounded reader hands containers to python-can's private BLF frame parser; a python-can without it (another
    major version) is named with the fix, not an AttributeError in the middle of a replay."""
    log = _write_log(tmp_path / "s.blf")
    assert len(_frames(log)) == FRAMES  # the installed python-can has the parser
    monkeypatch.delattr(canlog_blf.BLFReader, "_parse_container")
    with pytest.raises(DataError) as err:
        _frames(log)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{log}: this python-can (") and "convert the log to .asc" in msg
