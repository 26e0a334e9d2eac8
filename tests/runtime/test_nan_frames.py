"""One rule for a tick's non-finite sensor frames, on both decoder paths (docs/live.md, "What happens each tick", step 3).

A frame in which a bound float signal is NaN or inf is ignored; the latest finite frame of that message in the tick is
the one decoded (its values written, its watchdog entries stamped); a tick with no finite frame of the message writes
nothing. The same cases run through the compiled slot (frames of the DBC's length) and the Python codec (longer CAN FD
frames), and mixed; the expected value is the latest finite one as cantools decodes it, computed here from the list.
"""

from __future__ import annotations

import math
import struct

import can
import cantools
import pytest
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)
from test_livesafe_frames import nan_setup

from flowtex.graph.compiled import load_graph
from flowtex.io.codec_tables import decode_packed
from flowtex.runtime.live import load_io
from flowtex.runtime.tick import rx_decoder

DB = cantools.database.load_file(DBC)
STATUS = DB.get_message_by_name("DeviceStatus")
NAN, INF = math.nan, math.inf

CASES = [
    [30.0],
    [NAN],
    [30.0, NAN],
    [NAN, 30.0],
    [30.0, 41.5, INF],
    [30.0, NAN, -INF],
    [NAN, 30.0, NAN, 41.5, NAN],
    [NAN, -INF],
]


def frame(value: float, longer: bool) -> can.Message:
    """A DeviceStatus frame carrying CoilTemperature = ``value`` (float32): the DBC's 8 bytes, or 12 (CAN FD padding)."""
    data = struct.pack("<f", value) + bytes(4) + (bytes(4) if longer else b"")
    return can.Message(arbitration_id=STATUS.frame_id, is_extended_id=False, is_fd=longer, data=data)


def latest_finite(values: list[float]) -> float | None:
    """What the rule says the tick decodes: cantools' reading of the last frame whose value is finite."""
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return None
    return float(DB.decode_message(STATUS.frame_id, frame(finite[-1], False).data)["CoilTemperature"])


@pytest.mark.parametrize("values", CASES, ids=lambda v: "-".join(str(x) for x in v))
@pytest.mark.parametrize("layout", ["exact", "longer", "alternating", "alternating-longer-first"])
def test_the_latest_finite_frame_of_a_tick_stands_on_every_path(setup, values, layout):  # noqa: F811
    m = nan_setup(setup)
    g = load_graph(setup / "nan.yaml", block_rows=1)
    io = load_io(g, DBC, m)
    td = io.codec.decoder
    assert STATUS.frame_id in td.slot_of  # the DBC-length frames take the compiled slot
    longer = {"exact": [False] * len(values), "longer": [True] * len(values),
              "alternating": [k % 2 == 1 for k in range(len(values))],
              "alternating-longer-first": [k % 2 == 0 for k in range(len(values))]}[layout]
    rx = [frame(v, lg) for v, lg in zip(values, longer, strict=True)]
    wd = io.new_watchdog(2_000_000)
    inp = g.input_view("normal_force")
    inp[:] = 12.5
    mask = rx_decoder(io, wd)(rx, 7, td.words)
    if mask:
        decode_packed(td.ibuf, td.fbuf, mask, 7, io.codec.arena, wd.last)
    want = latest_finite(values)
    if want is None:
        assert inp.tolist() == [12.5] and (wd.last < 0).all()  # nothing written, nothing stamped
    else:
        assert inp.tolist() == [want] and (wd.last[[i for i, (name, _) in enumerate(io.watchdog_keys) if name == "normal_force"]] == 7).all()
