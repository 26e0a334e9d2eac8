"""``flowtex bench SCENE.yaml --knob plan=planned,all``: the planner's decisions swept like node parameters.

The 'all' configuration is checked against an independent path: the same
scene written with every threshold at 0, planned by ``flowtex scene plan`` and
run with Graph.run on the same input and seed; its error against the planned
graph must be the one the bench reports (same machine: identical runs).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from flowtex.bench.sweep import parse_knob
from flowtex.cli import main
from flowtex.datasets.study import write_study_scene
from flowtex.dsp.errors import signal_error
from flowtex.errors import FlowtexError
from flowtex.graph.compiled import load_graph
from flowtex.scene.build import plan_to_graph

REPO = Path(__file__).resolve().parents[2]
SURFACES = ("EPDM_Foam", "Whiteboard")  # EPDM keeps friction (mu 1.39); Whiteboard drops texture and friction


@pytest.fixture(scope="module")
def scene_and_input(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plan_knob")
    scene = write_study_scene(folder, SURFACES)
    rec = dict(np.load(REPO / "graphs/data/exploration.npz"))
    n = 3000
    inputs = {k: rec[k][2500:2500 + n] for k in ("position", "normal_force", "normal")}  # in contact, 30-190 mm/s
    inputs["surface"] = (np.arange(n) // 1500 % 2).astype(np.float64)  # Whiteboard from 1.5 s, mid-stroke
    np.savez(folder / "in.npz", **inputs)
    return folder, scene, inputs


def test_plan_all_against_independently_planned_graph(scene_and_input, capsys):
    folder, scene, inputs = scene_and_input
    table = folder / "t.csv"
    assert main(["bench", str(scene), "--input", str(folder / "in.npz"), "--knob", "plan=planned,all", "--outputs", "force",
                 "--repeats", "1", "-o", str(table)]) == 0
    rows = list(csv.reader(open(table)))
    assert rows[0] == ["plan", "ns/tick (local, dispatch tier)", "force rms", "pareto"]
    assert [r[0] for r in rows[1:]] == ["planned", "all"]
    assert float(rows[1][2]) == 0.0
    # independent: thresholds 0 in the scene file itself, planned and run outside the bench
    all_on = folder / "all_on.yaml"
    all_on.write_text(scene.read_text().replace("surfaces:", "thresholds: {texture: 0, friction: 0, taps: 0}\nsurfaces:"))
    for src, out in ((scene, "planned.yaml"), (all_on, "all.yaml")):
        plan_to_graph(src, folder / out, relative=False)  # absolute paths, as the bench writes: the compiled code is shared
    planned = load_graph(folder / "planned.yaml").run(inputs)["force"]
    every = load_graph(folder / "all.yaml").run(inputs)["force"]
    expected = signal_error("rms", planned, every, 1000.0)
    assert expected > 1e-3  # Whiteboard's friction and texture do change the force (N)
    assert float(rows[2][2]) == pytest.approx(expected, rel=1e-3)  # the CSV keeps 4 digits
    assert "Pareto front" in capsys.readouterr().out


def test_component_knob_drops_friction_everywhere(scene_and_input):
    folder, scene, inputs = scene_and_input
    table = folder / "f.csv"
    assert main(["bench", str(scene), "--input", str(folder / "in.npz"), "--knob", "plan.friction=auto,drop",
                 "--outputs", "friction_force", "--repeats", "1", "-o", str(table)]) == 0
    rows = list(csv.reader(open(table)))
    assert [r[0] for r in rows[1:]] == ["auto", "drop"]
    # dropped friction renders nothing: its error is the RMS of the planned friction force itself
    plan_to_graph(scene, folder / "friction_planned.yaml", relative=False)
    planned = load_graph(folder / "friction_planned.yaml").run(inputs)["friction_force"]
    rms = float(np.sqrt(np.mean(planned ** 2)))
    assert rms > 0.05  # EPDM's friction is there to drop (N)
    assert float(rows[2][2]) == pytest.approx(rms, rel=1e-3)


def test_plan_knob_errors(tmp_path, capsys):
    with pytest.raises(FlowtexError, match="use planned,all"):
        parse_knob("plan=everything")
    with pytest.raises(FlowtexError, match="no component 'colour'"):
        parse_knob("plan.colour=keep")
    with pytest.raises(FlowtexError, match="use auto,keep,drop"):
        parse_knob("plan.taps=maybe")
    np.savez(tmp_path / "in.npz", x=np.zeros(100))
    graph = REPO / "graphs" / "accel_preprocess.yaml"
    assert main(["bench", str(graph), "--input", str(tmp_path / "in.npz"), "--knob", "plan=planned,all"]) == 1
    assert "plan knobs need a scene file" in capsys.readouterr().err
