"""Live safety at the clamp bound: what the guard lets through arrives inside the clamp, rounding to the LSB included.

The output guard clamps in graph units and the encoder then rounds to the DBC signal's LSB; a bound off the LSB grid
would arrive up to half an LSB beyond the clamp. The map loader moves such bounds inward onto the grid
(flowtex.io.mapsafety.check_clamps). cantools, an independent decoder, reads every frame here; both encoding paths of
:class:`~flowtex.runtime.canio.CanIO` (the compiled tables and the generated Python encoders) are checked.
"""

from __future__ import annotations

import tempfile
import textwrap
from pathlib import Path

import cantools
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from test_live import DBC, MAP, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.errors import GraphError
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.io.canmap import load_map
from flowtex.io.codec import MessageCodec
from flowtex.io.dbc import load_dbc
from flowtex.runtime.canio import CanIO
from flowtex.runtime.live import LiveConfig, run_live

EPS = 2.0**-52


def _inside(physical: float, lo: float, hi: float, scale: float, offset: float, dbc_offset: float) -> bool:
    """``physical`` (decoded, DBC unit) lies in ``[lo, hi]`` (graph units; graph = (physical - offset) / scale) up to
    float64 rounding: the decoder's ``raw * scale + offset`` and this conversion round to the nearest double (a few
    EPS of the magnitudes involved), while the rounding to the LSB this file is about is at least 1e-6 of the clamp."""
    g = (physical - offset) / scale
    noise = 8 * EPS * ((abs(physical) + abs(dbc_offset) + abs(offset)) / abs(scale) + max(abs(lo), abs(hi)))
    return lo - noise <= g <= hi + noise


GRAPH = """
flowtex: 1
name: one_output
rate: 1000
inputs:
  x: {unit: N}
nodes:
  v: {type: gain, params: {k: 1.0}}
edges:
  - x -> v.x
outputs:
  y: v.y
"""


@pytest.fixture(scope="module")
def one_output(tmp_path_factory):
    """One compiled graph (output ``y`` = input ``x``) that every map below is bound to."""
    path = tmp_path_factory.mktemp("lsb") / "g.yaml"
    path.write_text(textwrap.dedent(GRAPH))
    return load_graph(path, block_rows=1)


def _dbc_text(length: int, signed: bool, is_float: bool, scale: str, offset: str, rng: str) -> str:
    text = f"""\
        VERSION ""
        BS_:
        BU_: Host Dev
        BO_ 257 Sense: 2 Dev
         SG_ F : 0|16@1- (0.001,0) [0|0] "N" Host
        BO_ 512 Cmd: {8 if is_float or length > 24 else 4} Host
         SG_ C : 8|{length}@1{'-' if signed or is_float else '+'} ({scale},{offset}) {rng} "A" Dev
         SG_ Enable : 0|1@1+ (1,0) [0|1] "" Dev
        """
    if is_float:
        text += "        SIG_VALTYPE_ 512 C : 1;\n"
    return textwrap.dedent(text)


def _frames(io: CanIO, value: float) -> list[bytes]:
    """The payloads of the Cmd message for graph output ``value``: compiled tables and Python encoder."""
    io.graph.output_view("y")[:] = value
    io.guard_and_encode(False)
    compiled = bytes(io.tx[0].data)
    python = bytearray(len(compiled))
    io.encoders[0](python)
    return [compiled, bytes(python)]


# LSB and clamp: an LSB of 1e-4 to 5 % of the clamp's width, bounds anywhere on or off the grid
_SIGNAL = st.tuples(st.integers(8, 20), st.booleans(), st.sampled_from(["0.0001", "0.001", "0.015", "0.6", "0.25", "3",
                                                                        "0.0972", "1"]),
                    st.sampled_from(["0", "0.5", "-3.25", "10"]), st.booleans())
_MAP = st.tuples(st.sampled_from([1.0, 0.5, -2.0, 0.0972, 1000.0, -0.001]), st.sampled_from([0.0, 1.5, -0.25]))


@settings(max_examples=150, deadline=None)
@given(signal=_SIGNAL, conv=_MAP, width_lsb=st.floats(20, 10_000), centre=st.floats(-0.4, 0.4),
       is_float=st.booleans(), peak=st.one_of(st.none(), st.floats(0.0, 0.3)),
       probes=st.lists(st.floats(-2.0, 2.0), min_size=1, max_size=6))
@example(signal=(16, True, "0.015", "0", False), conv=(1.0, 0.0), width_lsb=133.0, centre=0.0, is_float=False, peak=None,
         probes=[2.0])  # clamp [-0.9975, 0.9975] A on a 0.015 A LSB: the bound arrived as 1.005 A, in the old 1 % slack
def test_what_the_guard_lets_through_arrives_inside_the_clamp(one_output, signal, conv, width_lsb, centre, is_float, peak,
                                                             probes):
    """Any DBC scale/offset/length, map scale/offset, clamp (and peak range) and graph value: the frame both encoders
    send decodes (cantools) inside the clamp, or inside the peak range while the peak allowance lasts. Before, the
    bound was sent rounded to the nearest LSB, up to half an LSB beyond (accepted when within 1 % of the clamp width)."""
    length, signed, scale_text, offset_text, ranged = signal
    k, c = conv
    s, o = float(scale_text), float(offset_text)
    if is_float:
        length = 32
    raw_lo, raw_hi = (-(1 << (length - 1)), (1 << (length - 1)) - 1) if signed else (0, (1 << length) - 1)
    if is_float:
        raw_lo, raw_hi = -1e6, 1e6
    p_lo, p_hi = sorted((raw_lo * s + o, raw_hi * s + o))
    rng = f"[{p_lo + (p_hi - p_lo) / 8:.6g}|{p_hi - (p_hi - p_lo) / 8:.6g}]" if ranged else "[0|0]"
    lsb_g = s / abs(k) if not is_float else abs(p_hi) * 2.0**-23 / abs(k)  # the float32 spacing at the range's end
    mid = ((p_lo + p_hi) / 2 + centre * (p_hi - p_lo) - c) / k  # graph units
    half = width_lsb * lsb_g / 2
    lo, hi = mid - half, mid + half
    safe_phys = round(((mid * k + c) - o) / s) * s + o if not is_float else mid * k + c
    safe = (safe_phys - c) / k
    limit = None if peak is None else hi + peak * (hi - lo)
    binding = f"{{signal: Cmd.C, scale: {k!r}, offset: {c!r}, clamp: [{lo!r}, {hi!r}], safe: {safe!r}"
    binding += "}" if limit is None else f", peak: {{limit: {limit!r}, max_ms: 3}}}}"
    text = f"flowtex_map: 1\ninputs:\n  x: {{signal: Sense.F, timeout_ms: 5}}\noutputs:\n  y: {binding}\n"
    db = cantools.database.load_string(_dbc_text(length, signed, is_float, scale_text, offset_text, rng), database_format="dbc")
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "m.yaml").write_text(text)
        try:
            canmap = load_map(Path(tmp) / "m.yaml", db, "d.dbc", {"x": 1}, {"y": 1})
        except GraphError:  # a clamp the bit field wraps, a safe value outside the DBC range: other tests' matter
            assume(False)
    io = CanIO(one_output, canmap, {m.name: MessageCodec(m) for m in db.messages}, 1000.0)
    msg = db.get_message_by_name("Cmd")
    wide = (lo, hi) if limit is None else (lo - (limit - hi), limit)
    span = hi - lo
    for g in [hi, lo, *(mid + p * span for p in probes), 1e12, -1e12, hi + lsb_g / 2, lo - lsb_g / 2]:
        payloads = _frames(io, g)
        assert payloads[0] == payloads[1]  # the compiled tables and the Python encoder send the same bytes
        got = msg.decode(payloads[0], decode_choices=False)["C"]
        assert _inside(got, *wide, k, c, o), (g, got, wide, canmap.outputs["y"].guard)
    # with the peak allowance spent (or without peak), the clamp itself holds
    got = [msg.decode(_frames(io, g)[0], decode_choices=False)["C"] for g in [1e12] * 5 + [-1e12] * 5 + [hi, lo]]
    assert all(_inside(p, lo, hi, k, c, o) for p in got[-2:]), (got, lo, hi, canmap.outputs["y"].guard)


def test_a_bound_on_the_grid_is_kept_and_one_off_it_moves_one_step_at_most(setup):  # noqa: F811
    """The bundled DBC's 0.0001 A: the example map's clamp [-1, 1] A is on the grid and kept bit for bit; the scene map's
    +-10.288 m/s^2 x 0.0972 = +-0.99999 A arrived as 1.0000 A (1.3e-5 m/s^2 beyond) and is now 0.9999 A, one LSB in."""
    db = load_dbc(DBC)
    g = load_map(DBC.parent / "example_map.yaml", db, DBC).outputs["vibration"].guard
    assert (g.lo.tolist(), g.hi.tolist(), g.peak_lo.tolist(), g.peak_hi.tolist()) == ([-1.0], [1.0], [-1.5], [1.5])
    g = load_map(DBC.parent / "example_scene_map.yaml", db, DBC).outputs["vibration"].guard
    assert g.hi[0] == pytest.approx(0.9999 / 0.0972, rel=1e-12) and g.lo[0] == -g.hi[0]
    assert g.peak_hi[0] == pytest.approx(1.4999 / 0.0972, rel=1e-12)  # 15.432 x 0.0972 = 1.49999 A -> 1.5000 A before


def test_a_bound_on_the_grid_that_decodes_an_ulp_beyond_is_kept(setup):  # noqa: F811
    """A 0.1 A LSB and a clamp of [-0.3, 0.3] A: cantools decodes raw 3 as 3 * 0.1 = 0.30000000000000004 A, beyond 0.3 by
    float64 rounding only. The bound is on the grid and kept (a strict comparison would have moved it to 0.2 A)."""
    text = DBC.read_text()
    line = ' SG_ Current : 0|16@1- (0.0001,0) [-2|2] "A" HapticDevice'
    dbc = setup / "tenth.dbc"
    dbc.write_text(text.replace(line, line.replace("(0.0001,0) [-2|2]", "(0.1,0) [0|0]")))
    m = setup / "tenth.yaml"
    m.write_text(textwrap.dedent(MAP).replace("clamp: [-1, 1], safe: 0}", "clamp: [-0.3, 0.3], safe: 0}"))
    db = load_dbc(dbc)
    cmd = db.get_message_by_name("VoiceCoilCmd")
    assert cmd.decode(cmd.encode({"Current": 0.3, "Enable": 0, "Mode": 0}))["Current"] == 0.30000000000000004
    g = load_map(m, db, dbc).outputs["vibration"].guard
    assert (g.lo.tolist(), g.hi.tolist()) == ([-0.3], [0.3])


def test_a_coarse_lsb_runs_with_the_clamp_moved_inward(setup):  # noqa: F811
    """End to end (live, simulated device, recorded session): a 0.6 A LSB and a clamp of [-1, 1] A. The map was refused
    (1.2 A would have been sent); the guard now clamps to +-0.6 A and every recorded frame decodes inside the clamp."""
    text = DBC.read_text()
    line = ' SG_ Current : 0|16@1- (0.0001,0) [-2|2] "A" HapticDevice'
    assert line in text
    dbc = setup / "coarse.dbc"
    dbc.write_text(text.replace(line, line.replace("(0.0001,0) [-2|2]", "(0.6,0) [0|0]")))
    m = setup / "coarse.yaml"  # vibration = 0.25 x 2..4 N = 0.5..1 A wanted, x 4 (map scale): up to 4 A
    m.write_text(textwrap.dedent(MAP).replace("{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}",
                                              "{signal: VoiceCoilCmd.Current, scale: 4, clamp: [-0.25, 0.25], safe: 0}"))
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, m, simulate=setup / "rec.npz", max_ticks=300, status=None,
                                                          record=setup / "s.blf"))
    assert r.error is None
    db = cantools.database.load_file(dbc)
    cmd = db.get_message_by_name("VoiceCoilCmd")
    sent = [cmd.decode(f.data, decode_choices=False)["Current"] for f in read_session(setup / "s.blf")
            if not f.is_rx and f.arbitration_id == cmd.frame_id]
    assert len(sent) >= 300 and max(sent) == pytest.approx(0.6) and min(sent) >= 0.0  # 0.6 A: the clamp is reached


def test_a_clamp_with_no_step_inside_and_a_safe_value_sent_beyond_are_refused(setup):  # noqa: F811
    """A clamp narrower than the LSB between two steps holds nothing the DBC can send; a safe value at an off-grid
    bound would arrive beyond it at every safe frame. One line each, naming the file, the output and the fix."""
    text = DBC.read_text()
    line = ' SG_ Current : 0|16@1- (0.0001,0) [-2|2] "A" HapticDevice'
    dbc = setup / "coarse.dbc"
    dbc.write_text(text.replace(line, line.replace("(0.0001,0) [-2|2]", "(0.6,0) [0|0]")))
    db = load_dbc(dbc)
    for binding, expected in [
            ("{signal: VoiceCoilCmd.Current, clamp: [-0.2, 0.9], safe: 0.9}",
             "safe value 0.9 cannot be sent in VoiceCoilCmd.Current: it would arrive as 1.2 A"),
            ("{signal: VoiceCoilCmd.Current, clamp: [0.1, 0.5], safe: 0.3}", "no value it sends arrives inside [0.1, 0.5]"),
            ("{signal: VoiceCoilCmd.Current, clamp: [-0.5, 0.5], safe: 0.5}", "safe value 0.5 cannot be sent")]:
        m = setup / "bad.yaml"
        m.write_text(textwrap.dedent(MAP).replace("{signal: VoiceCoilCmd.Current, clamp: [-1, 1], safe: 0}", binding))
        with pytest.raises(GraphError) as e:
            load_map(m, db, dbc)
        msg = str(e.value)
        assert "\n" not in msg and msg.startswith(f"{m}:") and "output 'vibration'" in msg and expected in msg, msg


def test_validate_says_which_bounds_moved(capsys):
    """A bound moved inward changes what reaches the device (a 0.6 A LSB turns +-1 A into +-0.6 A): `flowtex validate`
    names it; a map whose bounds are all on the grid says nothing more."""
    from flowtex.cli import main

    assert main(["validate", str(DBC.parent / "example_scene_map.yaml"), "--dbc", str(DBC)]) == 0
    out = capsys.readouterr().out
    assert ("moved onto the DBC's LSB grid: vibration: clamp [-10.288, 10.288] guarded as [-10.287, 10.287]; "
            "peak range [-15.432, 15.432] guarded as [-15.4311, 15.4311])") in out, out
    assert main(["validate", str(DBC.parent / "example_map.yaml"), "--dbc", str(DBC)]) == 0
    assert "moved" not in capsys.readouterr().out


def test_a_clamp_the_grid_narrows_is_named_when_the_session_starts(setup):  # noqa: F811
    """The coarse LSB above turns a +-1 A clamp into +-0.6 A: the session says so before it runs (status stream) and in
    its report's warnings; the bundled scene map's half-LSB moves (0.0001 A of a 20 A-wide range) stay quiet."""
    import io

    from flowtex.io.mapsafety import shrunk_bounds

    text = DBC.read_text()
    line = ' SG_ Current : 0|16@1- (0.0001,0) [-2|2] "A" HapticDevice'
    dbc = setup / "coarse.dbc"
    dbc.write_text(text.replace(line, line.replace("(0.0001,0) [-2|2]", "(0.6,0) [0|0]")))
    m = setup / "coarse.yaml"
    m.write_text(textwrap.dedent(MAP))  # clamp [-1, 1] A, safe 0
    status = io.StringIO()
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, m, simulate=setup / "rec.npz", max_ticks=50, status=status))
    assert r.error is None
    first = status.getvalue().splitlines()[0]
    assert first.startswith("flowtex live: warning: vibration: clamp [-1, 1] guarded as [-0.6, 0.6]") and "too coarse" in first
    assert r.warnings[0] == first.removeprefix("flowtex live: warning: ")
    assert shrunk_bounds(load_map(DBC.parent / "example_scene_map.yaml", load_dbc(DBC), DBC).outputs.values()) == []


def test_a_dbc_unit_no_factor_relates_to_the_graphs_is_named_when_the_session_starts(setup):  # noqa: F811
    """The map's unit check (flowtex.io.mapunits): a pass-through binding whose DBC unit differs from its graph
    port's by no known factor ("Amp" for the graph's "A") is a warning, not a refusal: the session runs and says so
    before it starts (status stream) and among its report's warnings, naming the map's line and the binding."""
    import io

    line = ' SG_ Current : 0|16@1- (0.0001,0) [-2|2] "A" HapticDevice'
    dbc = setup / "amp.dbc"
    dbc.write_text(DBC.read_text().replace(line, line.replace('"A"', '"Amp"')))
    status = io.StringIO()
    r = run_live(load_graph(setup / "g.yaml"), LiveConfig(dbc, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=20,
                                                          status=status))
    assert r.error is None and r.ticks == 20
    named = [w for w in r.warnings if "VoiceCoilCmd.Current in Amp" in w]
    assert len(named) == 1 and named[0].startswith(f"{setup / 'm.yaml'}:") and "outputs.vibration" in named[0], r.warnings
    assert f"flowtex live: warning: {named[0]}" in status.getvalue().splitlines()
