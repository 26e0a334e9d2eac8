"""Live safety against what real buses and devices do: frame formats the bus cannot carry, and frames a device sends
that the DBC describes otherwise.

Every DBC is built from the bundled example by editing one line (test_livesafe_dbc's ``_dbc``).
"""

from __future__ import annotations

import can
import pytest
from test_live import setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)
from test_livesafe_dbc import _dbc

from flowtex.errors import GraphError
from flowtex.graph.compiled import load_graph
from flowtex.io.slcan_protocol import encode_frame
from flowtex.runtime.live import LiveConfig, load_io, run_live

FD_ATTRIBUTE = ('\nBA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN",' + '"reserved",' * 12 + '"StandardCAN_FD","ExtendedCAN_FD";\n'
                'BA_DEF_DEF_ "VFrameFormat" "StandardCAN";\nBA_ "VFrameFormat" BO_ 512 14;\n')
"""The DBC attribute that marks VoiceCoilCmd (BO_ 512) a CAN FD message."""


def test_an_actuator_message_longer_than_a_classic_frame_must_be_can_fd(setup):  # noqa: F811
    """VoiceCoilCmd given 12 bytes without being marked CAN FD: the runtime would send classic frames of 12 bytes, which
    no bus takes (flowtex_slcan refused the first with a ValueError, 'tick 0: ValueError: ... could not send the safe
    values ... make it safe by hand'; the virtual bus of --simulate carried them). Refused with the map now, naming the
    output's line and the fix; marked CAN FD, it runs and sends CAN FD frames."""
    dbc = _dbc(setup, "BO_ 512 VoiceCoilCmd: 4 Host", "BO_ 512 VoiceCoilCmd: 12 Host", "long.dbc")
    g = load_graph(setup / "g.yaml")
    with pytest.raises(GraphError) as e:
        load_io(g, dbc, setup / "m.yaml")
    line = next(i for i, t in enumerate((setup / "m.yaml").read_text().splitlines(), 1) if t.strip().startswith("vibration:"))
    text = str(e.value)
    assert text.startswith(f"{setup / 'm.yaml'}:{line}:") and "'VoiceCoilCmd'" in text and "12 data bytes" in text, text
    assert "CAN FD" in text and "at most 8 bytes in its BO_ line" in text, text
    with pytest.raises(GraphError):
        run_live(g, LiveConfig(dbc, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=5, status=None))
    with pytest.raises(ValueError):  # why: what the runtime sent before, a classic frame of 12 bytes, no adapter carries
        encode_frame(can.Message(arbitration_id=0x200, is_extended_id=False, data=bytes(12)))

    fd = setup / "fd.dbc"
    fd.write_text(dbc.read_text() + FD_ATTRIBUTE)
    io = load_io(g, fd, setup / "m.yaml")
    coil = next(m for m in io.tx if m.arbitration_id == 0x200)
    assert coil.is_fd and len(coil.data) == 12
    r = run_live(g, LiveConfig(fd, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=5, status=None))
    assert r.error is None and r.ticks == 5


def test_a_sensor_message_longer_than_a_classic_frame_is_not_judged(setup):  # noqa: F811
    """A device may send a long sensor message in CAN FD frames, which the decoder takes whatever the DBC says."""
    dbc = _dbc(setup, "BO_ 257 ToolForce: 8 HapticDevice", "BO_ 257 ToolForce: 12 HapticDevice", "long.dbc")
    assert load_io(load_graph(setup / "g.yaml"), dbc, setup / "m.yaml").map.inputs["normal_force"]
