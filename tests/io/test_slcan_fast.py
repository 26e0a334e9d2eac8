"""FastSlcanBus / slcan parser: exact line encoding, round trips, chunk splits, malformed input, a real pty."""

from __future__ import annotations

import random
import threading
import time

import can
import pytest

from flowtex.io.slcan_fast import INTERFACE_NAME, FastSlcanBus, register_interface
from flowtex.io.slcan_protocol import SlcanParser, encode_frame
from flowtex.io.slcan_pty import open_pty


def msg(ident: int, data: bytes = b"", ext: bool = False, remote: bool = False, dlc: int | None = None) -> can.Message:
    return can.Message(arbitration_id=ident, data=data, is_extended_id=ext, is_remote_frame=remote, dlc=dlc)


def same(a: can.Message, b: can.Message) -> bool:
    return (a.arbitration_id, a.is_extended_id, a.is_remote_frame, a.dlc, bytes(a.data)) == (
        b.arbitration_id,
        b.is_extended_id,
        b.is_remote_frame,
        b.dlc,
        bytes(b.data),
    )


# Lines written out by hand from the Lawicel slcan spec (independent of the encoder).
SPEC_LINES = [
    (msg(0x123, bytes([0x11, 0x22, 0x33])), b"t1233112233\r"),
    (msg(0x000), b"t0000\r"),
    (msg(0x7FF, bytes(range(0xF8, 0x100))), b"t7FF8F8F9FAFBFCFDFEFF\r"),
    (msg(0x1ABCDEF0 >> 1, bytes([0xDE, 0xAD]), ext=True), b"T0D5E6F782DEAD\r"),
    (msg(0x1FFFFFFF, ext=True), b"T1FFFFFFF0\r"),
    (msg(0x456, remote=True, dlc=4), b"r4564\r"),
    (msg(0x12345, ext=True, remote=True, dlc=8), b"R000123458\r"),
]


@pytest.mark.parametrize(("m", "line"), SPEC_LINES)
def test_encode_matches_spec_lines(m, line):
    assert encode_frame(m) == line


@pytest.mark.parametrize(("m", "line"), SPEC_LINES)
def test_decode_spec_lines(m, line):
    p = SlcanParser()
    p.feed(line, 123.0)
    assert p.frames == 1 and p.malformed == 0
    got = p.messages.popleft()
    assert same(got, m)
    assert got.timestamp == 123.0


@pytest.mark.parametrize("ext", [False, True])
@pytest.mark.parametrize("remote", [False, True])
@pytest.mark.parametrize("dlc", range(9))
def test_round_trip_all_kinds_and_dlcs(ext, remote, dlc):
    ident = 0x1F2E3D4C if ext else 0x5A5
    data = b"" if remote else bytes((17 * i + dlc) & 0xFF for i in range(dlc))
    m = msg(ident, data, ext=ext, remote=remote, dlc=dlc)
    line = encode_frame(m)
    # length from the spec: kind + id digits + dlc digit + 2 hex per byte + CR
    assert len(line) == 1 + (8 if ext else 3) + 1 + (0 if remote else 2 * dlc) + 1
    p = SlcanParser()
    p.feed(line, 0.0)
    assert same(p.messages.popleft(), m)


def test_encode_rejects_what_slcan_cannot_carry():
    with pytest.raises(ValueError, match="out of range"):
        encode_frame(msg(0x800))
    with pytest.raises(ValueError, match="out of range"):
        encode_frame(msg(0x20000000, ext=True))
    with pytest.raises(ValueError, match="FD"):
        encode_frame(can.Message(arbitration_id=1, data=bytes(12), is_fd=True))
    with pytest.raises(ValueError, match="DLC 2 but 3 data bytes"):
        encode_frame(can.Message(arbitration_id=1, data=b"abc", dlc=2, check=False))


def stream_of(n: int, seed: int) -> tuple[list[can.Message], bytes]:
    rng = random.Random(seed)
    msgs = []
    for _ in range(n):
        ext = rng.random() < 0.5
        remote = rng.random() < 0.2
        dlc = rng.randrange(9)
        ident = rng.randrange(0x20000000 if ext else 0x800)
        data = b"" if remote else bytes(rng.randrange(256) for _ in range(dlc))
        msgs.append(msg(ident, data, ext=ext, remote=remote, dlc=dlc))
    return msgs, b"".join(encode_frame(m) for m in msgs)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_chunk_boundaries_anywhere(seed):
    msgs, stream = stream_of(300, seed)
    rng = random.Random(seed + 100)
    p = SlcanParser()
    i = 0
    while i < len(stream):
        k = rng.choice([1, 2, 3, 7, 13, 31, 64, 200])
        p.feed(stream[i : i + k], 0.0)
        i += k
    assert p.malformed == 0 and p.frames == len(msgs)
    got = list(p.messages)
    assert all(same(a, b) for a, b in zip(got, msgs, strict=True))


def test_byte_by_byte():
    msgs, stream = stream_of(40, 9)
    p = SlcanParser()
    for b in stream:
        p.feed(bytes([b]), 0.0)
    assert [same(a, b) for a, b in zip(p.messages, msgs, strict=True)] == [True] * 40


BAD_LINES = [
    b"t12G1AA",  # non-hex id
    b"t1239" + b"00" * 9,  # DLC 9
    b"t123A" + b"00" * 10,  # DLC 'A'
    b"t1232AA",  # one data byte short
    b"t1231AABB",  # two extra hex digits (neither data nor a 4-digit timestamp)
    b"t8001AA",  # standard id > 0x7FF
    b"T200000000",  # extended id > 0x1FFFFFFF
    b"t12",  # too short
    b"t+121AA",  # sign characters int() would accept
    b"t1_21AA",
    b"r1232AA",  # remote frame with data
    b"t1231AAEA60",  # timestamp 60000 ms is out of range
    b"q1231AA",  # unknown letter (host role)
]


def test_malformed_lines_are_skipped_and_counted():
    good = encode_frame(msg(0x321, b"\x01\x02"))
    p = SlcanParser()
    p.feed(b"".join(line + b"\r" + good for line in BAD_LINES), 0.0)
    assert p.malformed == len(BAD_LINES)
    assert p.frames == len(BAD_LINES)
    assert all(same(m, msg(0x321, b"\x01\x02")) for m in p.messages)
    assert p.malformed_lines[-1] == b"q1231AA"


def test_overlong_garbage_without_terminator_is_dropped():
    p = SlcanParser()
    p.feed(b"x" * 200, 0.0)
    assert p.malformed == 1
    p.feed(b"\r" + encode_frame(msg(1, b"\x05")), 0.0)
    assert p.frames == 1 and same(p.messages.popleft(), msg(1, b"\x05"))


def test_replies_acks_bell_and_crlf():
    p = SlcanParser()
    p.feed(b"\r\r\x07z\rZ\rV1013\rF00\r" + b"t1001AB\r\n" + b"t1001CD\n\r", 0.0)
    assert p.acks == 4  # two OK, z and Z
    assert p.errors == 1
    assert list(p.replies) == [b"V1013", b"F00"]
    assert p.malformed == 0
    assert [bytes(m.data) for m in p.messages] == [b"\xab", b"\xcd"]


def test_timestamps_parse_and_unwrap():
    p = SlcanParser(device_timestamps=True)
    # 59 999 ms, then 2 ms after the wrap at 60 000 ms, then 1000 ms later
    p.feed(b"t1001AAEA5F\rt1001BB0002\rT000000010" + b"03EA" + b"\r", 1000.0)
    a, b, c = list(p.messages)
    assert a.timestamp == pytest.approx(1000.0)
    assert b.timestamp - a.timestamp == pytest.approx(0.003)
    assert c.timestamp - b.timestamp == pytest.approx(1.0)
    assert bytes(b.data) == b"\xbb" and c.dlc == 0
    q = SlcanParser()  # host time by default, timestamp digits still validated and stripped
    q.feed(b"t1001AAEA5F\r", 5.0)
    assert q.messages[0].timestamp == 5.0 and bytes(q.messages[0].data) == b"\xaa"


def test_encode_timestamp_wraps():
    assert encode_frame(msg(0x100, b"\xaa"), timestamp_ms=60_005) == b"t1001AA0005\r"


def test_role_validation():
    with pytest.raises(ValueError, match="role"):
        SlcanParser(role="adapter")


# -- real pty ----------------------------------------------------------------------


@pytest.fixture
def pty_pair():
    pty = open_pty()
    dev = FastSlcanBus(pty.master_fd, role="device")
    host = FastSlcanBus(pty.slave_path, bitrate=500_000)
    try:
        yield pty, dev, host
    finally:
        host.shutdown()
        dev.shutdown()
        pty.close()


def test_pty_open_commands_and_both_directions(pty_pair):
    pty, dev, host = pty_pair
    assert dev.recv(0.2) is None  # processes C, S6, O and answers them
    assert dev.is_open
    host.send(msg(0x123, b"\x01\x02\x03"))
    got = dev.recv(1.0)
    assert got is not None and same(got, msg(0x123, b"\x01\x02\x03"))
    dev.send(msg(0x1ABCDEF, bytes(range(8)), ext=True))
    got = host.recv(1.0)
    assert got is not None and same(got, msg(0x1ABCDEF, bytes(range(8)), ext=True))
    assert host.parser.acks == 3  # OK replies to C, S6, O
    assert host.malformed == 0 and dev.malformed == 0


def test_pty_device_timestamps_and_close(pty_pair):
    pty, dev, host = pty_pair
    host._write_all(b"Z1\r", timeout=1.0)
    dev.recv(0.2)
    assert dev.timestamps_on
    dev.send(msg(0x10, b"\x01"))
    got = host.recv(1.0)
    assert got is not None and same(got, msg(0x10, b"\x01"))
    assert host.malformed == 0
    host.shutdown()  # sends C
    dev.recv(0.2)
    assert not dev.is_open
    dev.send(msg(0x10, b"\x02"))
    assert dev.tx_dropped == 1


def test_can_bus_interface_name():
    register_interface()
    pty = open_pty()
    dev = FastSlcanBus(pty.master_fd, role="device")
    try:
        with can.Bus(interface=INTERFACE_NAME, channel=pty.slave_path) as bus:
            assert isinstance(bus, FastSlcanBus)
            dev.recv(0.2)
            dev.send(msg(0x55, b"\x99"))
            got = bus.recv(1.0)
            assert got is not None and same(got, msg(0x55, b"\x99"))
    finally:
        dev.shutdown()
        pty.close()


def test_open_missing_path_is_a_clear_error():
    with pytest.raises(can.CanInitializationError, match="cannot open /nonexistent/tty"):
        FastSlcanBus("/nonexistent/tty")


def test_pty_throughput_in_order_between_threads():
    """20 000 frames device -> host across a real pty: all arrive, in order (rate printed, not asserted)."""
    n = 20_000
    pty = open_pty()
    dev = FastSlcanBus(pty.master_fd, role="device")
    host = FastSlcanBus(pty.slave_path)
    try:
        dev.recv(0.2)  # handle the host's open commands
        assert dev.is_open

        def writer() -> None:
            batch = []
            for i in range(n):
                batch.append(msg(0x100 + (i % 0x600), i.to_bytes(4, "little") + b"\xa5" * (i % 5)))
                if len(batch) == 10:
                    dev.send_many(batch, timeout=10.0)
                    batch = []
            dev.send_many(batch, timeout=10.0)

        t0 = time.perf_counter()
        th = threading.Thread(target=writer)
        th.start()
        got = []
        deadline = time.monotonic() + 30.0
        while len(got) < n and time.monotonic() < deadline:
            m = host.recv(1.0)
            if m is not None:
                got.append(m)
            got.extend(host.recv_available())
        dt = time.perf_counter() - t0
        th.join(10.0)
        assert len(got) == n
        assert host.malformed == 0
        for i, m in enumerate(got):
            assert int.from_bytes(bytes(m.data[:4]), "little") == i
            assert m.arbitration_id == 0x100 + (i % 0x600) and bytes(m.data[4:]) == b"\xa5" * (i % 5)
        print(f"\nFastSlcanBus over a pty: {n / dt:,.0f} frames/s")
    finally:
        host.shutdown()
        dev.shutdown()
        pty.close()


def test_bell_split_across_chunks_and_after_garbage():
    p = SlcanParser()
    p.feed(b"xy\x07t10", 0.0)  # garbage ended by BEL, then the start of a frame
    p.feed(b"01AB\r", 0.0)
    assert (p.errors, p.malformed, p.frames, p.acks) == (1, 1, 1, 0)
    assert bytes(p.messages[0].data) == b"\xab"


def test_protocol_and_pty_names_still_import_from_slcan_fast():
    """encode_frame, SlcanParser and the pty helpers moved to slcan_protocol / slcan_pty; the old path gives the same objects."""
    import flowtex.io.slcan_fast as fast
    import flowtex.io.slcan_protocol as protocol
    import flowtex.io.slcan_pty as pty_mod

    for name in ("encode_frame", "SlcanParser", "MAX_LINE", "BITRATE_COMMANDS"):
        assert getattr(fast, name) is getattr(protocol, name)
    for name in ("open_pty", "SlcanPty"):
        assert getattr(fast, name) is getattr(pty_mod, name)
