"""Session logs keep frames, order and direction in .blf and .log."""

from __future__ import annotations

import can
import pytest

from flowtex.errors import DataError
from flowtex.io.canlog import SessionWriter, read_session


@pytest.mark.parametrize("suffix", [".blf", ".log"])
def test_roundtrip_keeps_direction_and_order(tmp_path, suffix):
    path = tmp_path / f"s{suffix}"
    w = SessionWriter(path)
    msg = can.Message(arbitration_id=0x200, data=bytearray(4), is_extended_id=False)
    sent = []
    for i in range(50):
        rx = can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100 + i % 2, data=bytes([i, 1, 2, 3, 4, 5, 6, 7]), is_extended_id=False)
        w.write(rx, True)
        msg.data[:] = bytes([i, 0, 0, 255 - i])  # reused object, as the live loop does
        msg.timestamp = 1000.0 + i * 1e-3 + 1e-4
        w.write(msg, False)
        sent.append((True, 0x100 + i % 2, bytes([i, 1, 2, 3, 4, 5, 6, 7])))
        sent.append((False, 0x200, bytes([i, 0, 0, 255 - i])))
    w.close()
    got = [(m.is_rx, m.arbitration_id, bytes(m.data)) for m in read_session(path)]
    assert got == sent


def test_bad_paths(tmp_path):
    with pytest.raises(DataError, match="must end in"):
        SessionWriter(tmp_path / "x.txt")
    with pytest.raises(DataError, match="not found"):
        list(read_session(tmp_path / "missing.blf"))
