"""Live safety at start-up, DBC side: safe values the DBC cannot carry and CAN IDs used twice are refused.

The DBC files are built here from the bundled example by editing one BO_/SG_ line; cantools is the
independent decoder and the analytic range (DBC [min|max], raw bit range) the independent reference.
"""

from __future__ import annotations

import textwrap

import cantools
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from test_live import DBC, MAP, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.errors import DataError, GraphError
from flowtex.graph.compiled import load_graph
from flowtex.io.canmap import load_map
from flowtex.io.dbc import load_dbc
from flowtex.io.dbcrange import check_value, round_trip, sendable_range
from flowtex.runtime.live import LiveConfig, run_live

BASE = DBC.read_text()
CURRENT = ' SG_ Current : 0|16@1- (0.0001,0) [-2|2] "A" HapticDevice'


def _dbc(tmp_path, old: str, new: str, name: str = "dev.dbc"):
    assert old in BASE
    path = tmp_path / name
    path.write_text(BASE.replace(old, new))
    return path


def test_safe_value_outside_the_dbc_range_refuses_the_session(setup):  # noqa: F811
    """The issue's case: Current [0.5|2] A, safe 0: the encoder would send 0.5 A on every safe frame and at exit."""
    dbc = _dbc(setup, CURRENT, CURRENT.replace("[-2|2]", "[0.5|2]"))
    db = cantools.database.load_file(dbc)
    assert db.decode_message("VoiceCoilCmd", db.encode_message("VoiceCoilCmd", {"Current": 0.5, "Enable": 0, "Mode": 0}))["Current"] == 0.5
    g = load_graph(setup / "g.yaml")
    with pytest.raises(GraphError) as e:
        run_live(g, LiveConfig(dbc, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=5, status=None, record=setup / "s.blf"))
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"{setup / 'm.yaml'}:")
    for part in ("safe value 0", "VoiceCoilCmd.Current", "arrive as 0.5 A", "[0.5, 2] A"):
        assert part in msg, msg
    assert not (setup / "s.blf").exists()  # refused before the session: nothing recorded


def test_safe_value_is_checked_before_the_clamp(setup):  # noqa: F811
    """A safe value outside both the DBC range and the map's clamp is reported as the DBC problem (checked first)."""
    dbc = _dbc(setup, CURRENT, CURRENT.replace("[-2|2]", "[-1|1]"))
    bad = setup / "bad.yaml"
    bad.write_text(textwrap.dedent(MAP).replace("clamp: [-1, 1], safe: 0}", "clamp: [-1, 1], safe: 1.5}"))
    with pytest.raises(GraphError, match=r"safe value 1\.5 cannot be sent in VoiceCoilCmd\.Current.*\[-1, 1\] A"):
        load_map(bad, load_dbc(dbc), dbc)


def test_safe_value_in_graph_units_through_the_map_scale(setup):  # noqa: F811
    """Map scale 1000 (graph mA -> DBC A): safe 0 mA is fine, safe -2500 mA (DBC -2.5 A) is not; the range is also given in mA."""
    m = setup / "ma.yaml"
    m.write_text(textwrap.dedent(MAP).replace("{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}",
                                              "{signal: VoiceCoilCmd.Current, scale: 0.001, clamp: [-3000, 3000], safe: -2500}"))
    with pytest.raises(GraphError) as e:
        load_map(m, load_dbc(DBC), DBC)
    assert "safe value -2500 (DBC value -2.5 A after the map's scale and offset)" in str(e.value)
    assert "[-2, 2] A, i.e. [-2000, 2000] in graph units" in str(e.value)
    m.write_text(m.read_text().replace("safe: -2500", "safe: -1999.95"))
    assert load_map(m, load_dbc(DBC), DBC).outputs["vibration"].safe.tolist() == [-1999.95]


def test_safe_value_the_bit_field_cannot_hold(setup):  # noqa: F811
    """Mode: 3 bits, scale 1, no range ([0|0]): the raw integer would wrap (9 -> 1); 7 fits."""
    dbc = _dbc(setup, ' SG_ Mode : 17|3@1+ (1,0) [0|7] ""', ' SG_ Mode : 17|3@1+ (1,0) [0|0] ""')
    db = load_dbc(dbc)
    msg = db.get_message_by_name("VoiceCoilCmd")
    sig = msg.get_signal_by_name("Mode")
    assert round_trip(msg, sig, 9.0) == 1.0 and check_value(msg, sig, 9.0) == 1.0
    assert check_value(msg, sig, 7.0) is None
    m = setup / "mode.yaml"
    m.write_text(textwrap.dedent(MAP) + "  mode: {signal: VoiceCoilCmd.Mode, clamp: [0, 10], safe: 9}\n")
    with pytest.raises(GraphError, match=r"safe value 9 cannot be sent in VoiceCoilCmd\.Mode: it would arrive as 1; .*\[0, 7\]"):
        load_map(m, db, dbc)


_FIELDS = st.tuples(st.integers(1, 24), st.booleans(), st.sampled_from([1.0, 0.5, 0.001, -0.25, 3.0]),
                    st.sampled_from([0.0, 10.0, -3.5]), st.one_of(st.none(), st.tuples(st.integers(-50, 50), st.integers(1, 60))))


@settings(max_examples=60, deadline=None)
@given(fields=_FIELDS, value=st.floats(-200, 200, allow_nan=False))
def test_check_value_agrees_with_the_analytic_range(fields, value):
    """Analytic range: the DBC [min|max] (if any) intersected with the raw bit range times scale plus offset. A value in it
    is accepted and cantools decodes it within half an LSB (round to nearest); a value more than 1.5 LSB outside it (one
    LSB of tolerance plus half an LSB of rounding at the edge) is refused."""
    length, signed, scale, offset, rng = fields
    lo_hi = "[0|0]" if rng is None else f"[{rng[0]}|{rng[0] + rng[1]}]"
    text = textwrap.dedent(f"""\
        VERSION ""
        BS_:
        BU_: A B
        BO_ 16 M: 4 A
         SG_ S : 0|{length}@1{'-' if signed else '+'} ({scale},{offset}) {lo_hi} "" B
        """)
    db = cantools.database.load_string(text, database_format="dbc", strict=True)
    msg = db.get_message_by_name("M")
    sig = msg.get_signal_by_name("S")
    rmin, rmax = (-(1 << (length - 1)), (1 << (length - 1)) - 1) if signed else (0, (1 << length) - 1)
    lo, hi = sorted((rmin * scale + offset, rmax * scale + offset))
    if rng is not None:
        lo, hi = max(lo, rng[0]), min(hi, rng[0] + rng[1])
    assume(lo <= hi)  # a DBC range the bit field cannot reach at all is another test's matter
    q = abs(scale)
    assert sendable_range(sig) == pytest.approx((lo, hi))
    got = check_value(msg, sig, value)
    if lo <= value <= hi:
        assert got is None
        assert abs(round_trip(msg, sig, value) - value) <= q / 2 * (1 + 1e-9)
    elif not lo - 1.5 * q <= value <= hi + 1.5 * q:
        assert got is not None and abs(got - value) > q


def test_two_messages_with_one_can_id_in_the_dbc(tmp_path):
    dbc = _dbc(tmp_path, "BO_ 513 ForceCmd", "BO_ 512 ForceCmd")
    with pytest.raises(DataError) as e:
        load_dbc(dbc)
    assert str(e.value) == (f"{dbc}: messages 'VoiceCoilCmd' and 'ForceCmd' both use standard CAN ID 0x200; "
                            "give each message its own ID in its BO_ line")
    # an extended frame with the same number is another CAN ID: the DBC is fine ...
    ext = _dbc(tmp_path, "BO_ 513 ForceCmd", f"BO_ {512 | 0x80000000} ForceCmd", "ext.dbc")
    db = load_dbc(ext)
    assert db.get_message_by_name("ForceCmd").is_extended_frame


def test_two_bound_messages_with_one_id_number_in_the_map(setup):  # noqa: F811
    """... but a map binding both is refused: the runtime and cantools look received frames up by ID number."""
    ext = _dbc(setup, "BO_ 513 ForceCmd", f"BO_ {512 | 0x80000000} ForceCmd", "ext.dbc")
    with pytest.raises(GraphError) as e:
        run_live(load_graph(setup / "g.yaml"), LiveConfig(ext, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=5, status=None))
    assert "\n" not in str(e.value)
    assert "'force' binds message 'ForceCmd', whose CAN ID 0x200 is also that of message 'VoiceCoilCmd'" in str(e.value)


MODE = ' SG_ Mode : 17|3@1+ (1,0) [0|7] "" HapticDevice'


@pytest.mark.parametrize("old,new,binding,arrives", [
    # a 3-bit field with scale 1 and no range: 10 (graph 1 x map scale 10) wraps to 2, 8 to 0
    (MODE, MODE.replace("[0|7]", "[0|0]"), "{signal: VoiceCoilCmd.Mode, clamp: [0, 1], safe: 0, scale: 10}",
     "clamp HIGH 1 cannot be sent in VoiceCoilCmd.Mode: it would arrive as 2: the bit field (3 bits, scale 1, no DBC range) "
     "wraps it around"),
    # the clamp fits (0-7), the peak range the guard allows for up to 5 ms ([-3, 10], the margin mirrored below) wraps:
    # its low end first (-3 arrives as 5)
    (MODE, MODE.replace("[0|7]", "[0|0]"),
     "{signal: VoiceCoilCmd.Mode, clamp: [0, 0.7], safe: 0, scale: 10, peak: {limit: 1.0, max_ms: 5}}",
     "peak range low -0.3 cannot be sent in VoiceCoilCmd.Mode: it would arrive as 5")])
def test_a_clamp_the_dbc_sends_beyond_the_clamp_is_refused(setup, old, new, binding, arrives):  # noqa: F811
    """Every frame the guard let through must arrive inside the clamp (or the peak range): their bounds, encoded by
    flowtex and decoded by cantools, are checked before the session. Before, such maps ran: commands of 0.8-1.0 sent as
    0-2 (wrapped) instead of 7. (A bound the encoder merely rounds beyond the clamp is moved inward onto the DBC's grid
    instead: test_livesafe_lsb.py.)"""
    dbc = _dbc(setup, old, new)
    bad = setup / "bad.yaml"
    text = textwrap.dedent(MAP)
    assert "{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}" in text
    bad.write_text(text.replace("{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}", binding))
    with pytest.raises(GraphError) as e:
        run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, bad, simulate=setup / "rec.npz", max_ticks=5, status=None))
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{bad}:") and "output 'vibration': " in msg and arrives in msg, msg


def test_a_dbc_range_narrower_than_the_clamp_and_fine_rounding_pass(setup):  # noqa: F811
    """The encoder's DBC range limits a clamp wider than it (monotonic, inside the clamp): not refused. Nor is the
    bundled scene map's clamp of +-10.288 m/s^2 x 0.0972 A, which would arrive 1.3e-5 m/s^2 beyond it (half an LSB at
    most: the bound is moved one LSB inward, test_livesafe_lsb.py)."""
    dbc = _dbc(setup, CURRENT, CURRENT.replace("[-2|2]", "[-0.5|0.5]"))
    load_map(setup / "m.yaml", load_dbc(dbc), dbc)
    scene_map = DBC.parent / "example_scene_map.yaml"
    load_map(scene_map, load_dbc(DBC), DBC)
