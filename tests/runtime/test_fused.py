"""The fused live tick (one compiled call) against the separate calls; warming has no effect; one-row layouts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

import flowtex.runtime.live as live
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.io.recordings import load_recording
from flowtex.runtime.canio import tick_out
from flowtex.runtime.fused import fuse_tick
from flowtex.runtime.tick import rx_decoder, warmer

REPO = Path(__file__).resolve().parents[2]
TEXTURE = REPO / "graphs" / "live_texture.yaml"
MAP = REPO / "graphs" / "devices" / "example_map.yaml"
RECORDING = REPO / "graphs" / "data" / "exploration.npz"


def _frames(path):
    return [(m.is_rx, m.arbitration_id, bytes(m.data)) for m in read_session(path)]


@pytest.mark.parametrize("graph_file", ["passthrough", "texture"])
def test_fused_tick_sends_the_frames_of_the_separate_calls(setup, monkeypatch, graph_file):  # noqa: F811
    """Same session three ways: fused + warming, fused without warming, separate compiled calls.

    The dropout makes the watchdog trip and recover, so the fused call's -1 path
    (Watchdog.check + guard_and_encode in Python) is part of the comparison.
    """
    graph, canmap, ticks, drop, recording = setup / "g.yaml", setup / "m.yaml", 800, 300, setup / "rec.npz"
    if graph_file == "texture":  # the example map, with an overrun limit a loaded test machine does not reach
        graph, canmap = TEXTURE, setup / "example_map.yaml"
        canmap.write_text(MAP.read_text().replace("overrun_limit_ms: 2 ", "overrun_limit_ms: 100000 "))
        # the bundled recording from 2 s on: its tool slides in contact from sample 2247, here tick 247 (the session runs
        # in real time: 1 s instead of the 3 s the whole recording's first contact would take)
        recording = setup / "strokes.npz"
        with np.load(RECORDING) as d:
            np.savez(recording, **{k: d[k][2000:3200] if d[k].ndim else d[k] for k in d.files})
        ticks, drop = 1000, 500
    kw = dict(simulate=recording, max_ticks=ticks, status=None, seed=5, drop={"ToolPosition": (drop, drop + 40)})
    g = load_graph(graph, block_rows=1)
    io = live.load_io(g, DBC, canmap)
    assert fuse_tick(g, io, tick_out, io.new_watchdog(1).last) is not None  # the first two runs take the fused path
    logs = []
    for name, fused, warm in [("fused", True, True), ("cold", True, False), ("separate", False, True)]:
        if not fused:
            monkeypatch.setattr(live, "fuse_tick", lambda *a: None)
        log = setup / f"{name}.log"
        r = live.run_live(load_graph(graph), live.LiveConfig(DBC, canmap, record=log, warm=warm, **kw))
        assert r.error is None and r.ticks == ticks and r.watchdog_events == 1
        logs.append(_frames(log))
    assert len(logs[0]) == ticks * 2 + (ticks * 2 - 40) + 2  # actuator frames, sensor frames (minus 40 ToolPosition), safe values
    assert logs[0] == logs[1] == logs[2]
    commands = {(fid, data) for is_rx, fid, data in logs[0] if not is_rx}
    assert len(commands) > 100  # the graph really drove the actuators


def test_warming_has_no_observable_effect():
    g = load_graph(TEXTURE, block_rows=1)
    io = live.load_io(g, DBC, MAP)
    wd = io.new_watchdog(2_000_000)
    g.input_view("position")[:] = [12.0, -3.0, 0.0]
    g.input_view("normal_force")[:] = 1.5
    for _ in range(50):
        g.step_block(1)
    io.guard_and_encode(False)
    fused = fuse_tick(g, io, tick_out, wd.last)
    assert fused is not None
    warm = warmer(io, wd, fused, rx_decoder(io, wd))
    before = (g.f.copy(), g.i.copy(), wd.last.copy(), io.table_decoder.words.copy(), bytes(io.table_encoder.payload),
              [bytes(m.data) for m in io.tx], io.codec.out_floats.copy(), io.codec.out_ints.copy())
    for _ in range(5):
        warm()
    after = (g.f, g.i, wd.last, io.table_decoder.words, bytes(io.table_encoder.payload), [bytes(m.data) for m in io.tx],
             io.codec.out_floats, io.codec.out_ints)
    for a, b in zip(before, after, strict=True):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        else:
            assert a == b


def test_frames_written_by_compiled_code_cannot_be_resized():
    g = load_graph(TEXTURE, block_rows=1)
    io = live.load_io(g, DBC, MAP)
    wd = io.new_watchdog(2_000_000)
    fused = fuse_tick(g, io, tick_out, wd.last)
    assert fused.arrays["frames"].shape == (len(io.tx), 3)
    with pytest.raises(BufferError):
        io.tx[0].data.append(0)  # the address the compiled copy writes to must stay valid


def test_the_fused_tick_holds_the_graph_body_and_compiles_no_separate_block():
    """On the fused tier the live tick holds ``block``'s lines: a session compiles the graph's body once, inside the
    tick, not ``block`` and then ``block``'s code again inside the tick (seconds of CPU at every first live start)."""
    g = load_graph(TEXTURE, block_rows=1)
    assert g.tier == "fused"
    io = live.load_io(g, DBC, MAP)
    assert fuse_tick(g, io, tick_out, io.new_watchdog(2_000_000).last) is not None
    assert not g._code.compiled("block")


def test_the_dispatch_tiers_tick_calls_block_for_one_signature():
    """A dispatch-tier graph's live tick calls its ``block`` with the int64 row count that ``step_block`` uses: numba
    compiles no second ``block`` for the literal ``1``."""
    g = load_graph(TEXTURE, block_rows=1, tier="dispatch")
    io = live.load_io(g, DBC, MAP)
    g.step_block(1)
    assert fuse_tick(g, io, tick_out, io.new_watchdog(2_000_000).last) is not None
    signatures = g.block_function.signatures
    assert len(signatures) == 1 and str(signatures[0][2]) == "int64", signatures


def test_one_row_layout_gives_the_same_outputs_and_keeps_the_seed():
    rec = load_recording(RECORDING)
    inputs = {k: v[:3000] for k, v in rec.arrays.items() if k in ("position", "normal_force")}
    g = load_graph(TEXTURE)
    ref = g.run(inputs, seed=11)
    one = g.with_block_rows(1)
    assert one is not g and one.layout.block_rows == 1 and one.seed == 11
    assert one.f.nbytes < g.f.nbytes / 10
    out = one.run(inputs)
    for name in ref:
        np.testing.assert_array_equal(out[name], ref[name])
    assert one.with_block_rows(1) is one


def test_pointer_table_refuses_arrays_the_generated_views_would_misread():
    from flowtex.runtime.fused import POINTER_ORDER, pointer_table

    good = {name: np.zeros((2, 3) if name in ("gip", "frames") else 4,
                           dtype=np.float64 if name in ("f", "d_fb", "o_fb") else np.uint8 if name == "payload" else np.int64)
            for name in POINTER_ORDER}
    table = pointer_table(good)
    assert table.shape == (3 * len(POINTER_ORDER),)
    assert table[0] == good["f"].ctypes.data and table[1:3].tolist() == [4, 1]
    k = POINTER_ORDER.index("gip")
    assert table[3 * k + 1:3 * k + 3].tolist() == [2, 3]
    for name, bad in [("f", np.zeros(4, dtype=np.float32)), ("i", np.zeros(8, dtype=np.int64)[::2]), ("gip", np.zeros(6, dtype=np.int64))]:
        with pytest.raises(ValueError, match=f"fused tick: {name} must be"):
            pointer_table({**good, name: bad})


def test_a_map_the_tick_cannot_fuse_runs_the_general_steps_and_replays_byte_for_byte(setup):  # noqa: F811
    """Actuator messages the compiled encoder cannot take (an integer scale whose products pass 2^53): no compiled
    output call, so the loop makes the general calls one by one (tick.py's second way); the replay, built from the
    Python decoders, the graph and CanIO's own guard and encoders, gives the same bytes every tick."""
    import cantools

    from flowtex.io.codec import MessageCodec
    from flowtex.io.codec_tables import fast_ok

    pad = ' SG_ Pad : {} (35184372088832,0) [0|0] "" HapticDevice\n'
    dbc = setup / "wide.dbc"
    dbc.write_text(DBC.read_text()
                   .replace("BO_ 512 VoiceCoilCmd: 4 Host\n", "BO_ 512 VoiceCoilCmd: 4 Host\n" + pad.format("20|12@1+"))
                   .replace("BO_ 513 ForceCmd: 6 Host\n", "BO_ 513 ForceCmd: 8 Host\n" + pad.format("48|16@1+")))
    db = cantools.database.load_file(dbc)
    assert not any(fast_ok(MessageCodec(db.get_message_by_name(m))) for m in ("VoiceCoilCmd", "ForceCmd"))
    g = load_graph(setup / "g.yaml", block_rows=1)
    io = live.load_io(g, dbc, setup / "m.yaml")
    assert io.codec.out_ints is None and io.codec.encoder is None and len(io.codec.python_frames) == 2
    assert fuse_tick(g, io, tick_out, io.new_watchdog(1).last) is None
    log = setup / "wide.log"
    r = live.run_live(load_graph(setup / "g.yaml"), live.LiveConfig(dbc, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=400,
                                                                     record=log, status=None, seed=4))
    assert r.error is None and r.ticks == 400 and r.watchdog_events == 0
    from flowtex.runtime.replay import replay_session

    rep = replay_session(load_graph(setup / "g.yaml"), log, dbc, setup / "m.yaml", seed=4)
    assert rep.ticks == 400 and rep.mismatched_ticks == []
    # the frames carry the graph's values (vibration = 0.25 x normal force), not safe values
    frames = list(read_session(log))
    rx = [m for m in frames if m.is_rx]
    tx = [m for m in frames if not m.is_rx]
    nf = db.decode_message(rx[2 * 100 + 1].arbitration_id, rx[2 * 100 + 1].data)["NormalForce"]
    assert db.decode_message(0x200, tx[2 * 100].data)["Current"] == pytest.approx(0.25 * nf, abs=1e-4) and nf > 1.0
