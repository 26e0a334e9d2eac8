"""``flowtex scene live`` on the example device (simulated, virtual bus), switching surfaces mid-stroke.

The bundled scene (graphs/scene_two_surfaces.yaml) runs live against the
in-process simulated device playing a stroke whose `surface` input switches
from `rough` (texture, taps) to `rubber` (friction) while the tool slides at
180 mm/s and 1.5 N. Checked: actuator frames go out every tick; the session,
replayed from its log, computes exactly the outputs of an offline
``flowtex scene run`` of the same recording (same machine, same inputs on the
device's grid, same seed: bit for bit, as tests/test_texture_examples.py checks
graphs/live_texture.yaml); the live frames are those outputs byte for byte
apart from ticks a watchdog explains; and at the switch nothing exceeds the
larger of the two surfaces rendered alone (no burst), in the graph outputs and
in the force commands actually sent.
"""

from __future__ import annotations

import cantools
import numpy as np
import pytest

from flowtex.cli import main
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import read_session
from flowtex.runtime.replay import replay_session
from flowtex.scene.build import plan_to_graph
from tests.conftest import REPO

SCENE = REPO / "graphs" / "scene_two_surfaces.yaml"
DBC = REPO / "graphs" / "devices" / "example.dbc"
MAP = REPO / "graphs" / "devices" / "example_scene_map.yaml"
START = 5800  # 5.8 s into graphs/data/scene_strokes.npz: a 180 mm/s stroke at 1.5 N
SWITCH = 200  # the recording switches rough (0) -> rubber (1) at 6.0 s, i.e. 200 ticks into the slice


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scenelive")
    with np.load(REPO / "graphs" / "data" / "scene_strokes.npz") as d:
        part = {k: d[k][START:START + 600] for k in ("position", "normal_force", "normal", "surface")}
    assert part["surface"][SWITCH - 1] == 0.0 and part["surface"][SWITCH] == 1.0
    rec = folder / "strokes.npz"
    np.savez(rec, **part, rate=np.float64(1000.0))
    log = folder / "session.log"
    assert main(["scene", "live", str(SCENE), "--bus", "virtual", "--simulate", str(rec), "--duration", "0.4", "--quiet",
                 "--record", str(log)]) == 0
    offline = folder / "offline.npz"
    assert main(["scene", "run", str(SCENE), "--input", str(rec), "-o", str(offline)]) == 0
    plan_to_graph(SCENE, folder / "graph.yaml", relative=False)  # the graph 'scene live' planned and ran
    graph = load_graph(folder / "graph.yaml")
    report = replay_session(graph, log, DBC, MAP, folder / "replay.npz")
    with np.load(folder / "replay.npz") as d:
        replayed = {k: d[k] for k in d.files if k != "rate"}
    with np.load(offline) as d:
        off = {k: d[k] for k in d.files if k not in ("rate", "units")}
    alone = [graph.run({**part, "surface": np.full(600, float(i))}) for i in (0, 1)]
    return {"log": log, "report": report, "replayed": replayed, "offline": off, "alone": alone, "part": part}


def test_actuator_frames_are_sent_every_tick(session):
    report = session["report"]
    assert report.ticks > SWITCH + 50  # the session covered the switch (0.4 s at 1 kHz is 400 ticks)
    tx = [m for m in read_session(session["log"]) if not m.is_rx]
    # one VoiceCoilCmd and one ForceCmd per tick, plus the exit block of safe values
    assert [m.arbitration_id for m in tx] == [0x200, 0x201] * (report.ticks + 1)
    rx = [m for m in read_session(session["log"]) if m.is_rx]
    assert {m.arbitration_id for m in rx} == {0x100, 0x101, 0x102}  # position, force + normal, surface index
    db = cantools.database.load_file(DBC)
    current = np.array([db.decode_message(0x200, m.data)["Current"] for m in tx[:-2:2]])
    fx = np.array([db.decode_message(0x201, m.data)["Fx"] for m in tx[1:-2:2]])
    assert np.sum(current[:SWITCH] != 0) > 100  # rough's texture drove the coil before the switch ...
    assert np.sum(np.abs(fx[SWITCH + 20:report.ticks]) > 0.1) > 50  # ... rubber's friction the force after it


def test_session_outputs_equal_the_offline_scene_run(session):
    replayed, off, report = session["replayed"], session["offline"], session["report"]
    n = report.ticks
    assert set(replayed) == set(off) and replayed["force"].shape[0] == n
    for name in off:  # same machine, same decoded inputs (the recording lies on the DBC's grid), same seed: identical
        np.testing.assert_array_equal(replayed[name], off[name][:n], err_msg=name)
    # every live frame equals the replayed one byte for byte, except ticks a watchdog forced to safe values
    # (a loaded machine may start a tick more than overrun_limit_ms late); none is unexplained
    assert report.unexplained_ticks == []
    assert len(report.mismatched_ticks) < n // 2


def test_switching_mid_stroke_makes_no_burst(session):
    replayed, alone, part, n = session["replayed"], session["alone"], session["part"], session["report"].ticks
    assert np.all(part["normal_force"][SWITCH - 50:SWITCH + 50] > 1.0)  # really mid-stroke, in contact
    window = slice(SWITCH - 10, min(n, SWITCH + 40))
    # the crossfade is convex: element by element never above the larger of the two surfaces rendered alone
    # (1e-12: rounding of the (1 - w) a + w b mix)
    for name in ("vibration", "friction_force", "tap_force", "force"):
        bound = np.maximum(np.abs(alone[0][name][window]), np.abs(alone[1][name][window]))
        assert np.all(np.abs(replayed[name][window]) <= bound + 1e-12), name
    # the rubber's friction spring ran before it was chosen: already loaded at the switch, not stale
    assert np.abs(alone[1]["friction_force"][SWITCH]).max() > 0.5
    # and the force commands the device received: within the same bound, plus half a DBC step (0.0005 N)
    db = cantools.database.load_file(DBC)
    tx = [m for m in read_session(session["log"]) if not m.is_rx and m.arbitration_id == 0x201][:n]
    sent = np.array([[db.decode_message(0x201, m.data)[k] for k in ("Fx", "Fy")] for m in tx])
    bound = np.maximum(np.abs(alone[0]["force"][window, :2]), np.abs(alone[1]["force"][window, :2]))
    forced = set(session["report"].mismatched_ticks)  # safe values (0 N) there: inside any bound
    ok = [k for k in range(window.start, window.stop) if k not in forced]
    assert np.all(np.abs(sent[ok]) <= bound[[k - window.start for k in ok]] + 0.0005 + 1e-12)


def test_scene_example_data_regenerates(tmp_path):
    # graphs/data/make_scene_examples.py derives its files from committed ones by exact operations
    # (x 16, rounding to the device grid): rerunning it reproduces them (floats to 1e-12: JSON number printing)
    import importlib.util
    import json

    spec = importlib.util.spec_from_file_location("make_scene_examples", REPO / "graphs" / "data" / "make_scene_examples.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(tmp_path)
    new, old = (json.loads((d / "rough_texture.json").read_text()) for d in (tmp_path, REPO / "graphs" / "data"))
    assert sorted(new) == sorted(old) and new["material"] == old["material"]
    for a, b in zip(new["models"], old["models"], strict=True):
        assert sorted(a) == sorted(b)
        for key in a:
            np.testing.assert_allclose(np.asarray(a[key], dtype=float), np.asarray(b[key], dtype=float), rtol=1e-12, atol=0, err_msg=key)
    with np.load(tmp_path / "scene_strokes.npz") as n, np.load(REPO / "graphs" / "data" / "scene_strokes.npz") as o:
        assert sorted(n.files) == sorted(o.files)
        for k in o.files:
            np.testing.assert_array_equal(n[k], o[k], err_msg=k)
        # the switches fall where the generator says, in contact, and every value is on the example device's grid
        assert np.flatnonzero(np.diff(o["surface"])).tolist() == [5999, 8499, 11199]
        assert np.all(o["normal_force"][[5999, 8499, 11199]] > 1.0)
        assert np.array_equal(np.round(o["penetration"] / 0.001) * 0.001, o["penetration"])
