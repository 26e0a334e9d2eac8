"""Replay of a recorded simulated session equals the live frames byte for byte."""

from __future__ import annotations

import cantools
import numpy as np
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.runtime.live import run_live
from flowtex.runtime.replay import replay_session


def test_replay_equals_live_and_offline(setup):  # noqa: F811
    g = load_graph(setup / "g.yaml")
    live_log = setup / "live.blf"
    r = run_live(g, DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=600, record=live_log, status=None,
                 drop={"ToolPosition": (200, 260)}, seed=3)
    assert r.error is None and r.watchdog_events == 1
    g2 = load_graph(setup / "g.yaml")
    rep = replay_session(g2, live_log, DBC, setup / "m.yaml", setup / "replay.log", seed=3)
    assert rep.ticks == 600 and rep.exit_block
    # every tick the graph produced matches; the dropout ticks are explained by the watchdog
    assert rep.unexplained_ticks == []
    assert rep.mismatched_ticks == list(range(205, 260))  # last frame at tick 199, 5-tick timeout; back at 260
    live_tx = [m for m in read_session(live_log) if not m.is_rx][:-2]
    replay_tx = [m for m in read_session(setup / "replay.log")]
    assert len(live_tx) == len(replay_tx) == 1200
    for k, (a, b) in enumerate(zip(live_tx, replay_tx, strict=True)):
        if not 205 <= k // 2 < 260:
            assert (a.arbitration_id, bytes(a.data)) == (b.arbitration_id, bytes(b.data))

    # .npz outputs equal an offline run over the inputs cantools decodes from the received frames
    rep2 = replay_session(load_graph(setup / "g.yaml"), live_log, DBC, setup / "m.yaml", setup / "out.npz", seed=3)
    assert rep2.mismatched_ticks == rep.mismatched_ticks
    db = cantools.database.load_file(DBC)
    pos = np.zeros(3)
    nf = 0.0
    P, F = [], []
    frames = list(read_session(live_log))
    for m in frames:
        if m.is_rx:
            d = db.decode_message(m.arbitration_id, m.data)
            if m.arbitration_id == 0x100:
                pos = np.array([d["PosX"], d["PosY"], d["PosZ"]], dtype=float)
            else:
                nf = float(d["NormalForce"])
        elif m.arbitration_id == 0x201:
            P.append(pos)
            F.append(nf)
    P, F = np.array(P[:600]), np.array(F[:600])
    ref = load_graph(setup / "g.yaml").run({"position": P, "normal_force": F}, seed=3)
    out = np.load(setup / "out.npz")
    np.testing.assert_array_equal(out["force"], ref["force"])
    np.testing.assert_array_equal(out["vibration"], ref["vibration"])
