"""Map files: parsing against the DBC and the graph, and their error messages."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from flowtex.errors import FlowtexError, GraphError
from flowtex.io.canmap import load_map
from flowtex.io.dbc import load_dbc

REPO = Path(__file__).resolve().parents[2]
DBC = REPO / "graphs" / "devices" / "example.dbc"
GIN = {"position": 3, "normal_force": 1}
GOUT = {"vibration": 1, "force": 3}


def _map(tmp_path, text):
    p = tmp_path / "m.yaml"
    p.write_text(textwrap.dedent(text).lstrip("\n"))
    return p


GOOD = """
flowtex_map: 1
inputs:
  position:
    signals: [ToolPosition.PosX, ToolPosition.PosY, ToolPosition.PosZ]
    scale: 0.001
    timeout_ms: 5
  normal_force: {signal: NormalForce, timeout_ms: 3}
outputs:
  vibration: {signal: VoiceCoilCmd.Current, clamp: [-1, 1], peak: {limit: 1.5, max_ms: 20}}
  force:
    signals: [ForceCmd.Fx, ForceCmd.Fy, ForceCmd.Fz]
    clamp: [[-4, 4], [-4, 4], [0, 8]]
    safe: [0, 0, 1]
"""


def test_example_map_parses():
    m = load_map(REPO / "graphs" / "devices" / "example_map.yaml", load_dbc(DBC), DBC, GIN, GOUT)
    assert m.inputs["position"].signals == [("ToolPosition", "PosX"), ("ToolPosition", "PosY"), ("ToolPosition", "PosZ")]
    assert m.sensor_messages() == ["ToolPosition", "ToolForce"]
    assert m.actuator_messages() == ["VoiceCoilCmd", "ForceCmd"]


def test_good_map_values(tmp_path):
    m = load_map(_map(tmp_path, GOOD), load_dbc(DBC), DBC, GIN, GOUT)
    assert np.all(m.inputs["position"].scale == 0.001) and m.inputs["normal_force"].timeout_ms == 3
    assert m.inputs["normal_force"].signals == [("ToolForce", "NormalForce")]
    f = m.outputs["force"]
    assert f.lo.tolist() == [-4, -4, 0] and f.hi.tolist() == [4, 4, 8] and f.safe.tolist() == [0, 0, 1]
    v = m.outputs["vibration"]
    assert v.safe.tolist() == [0.0] and v.peak_limit.tolist() == [1.5] and v.peak_ms == 20
    assert v.recover_ms == 1200  # absent: 60 x max_ms (PEAK_RECOVER_RATIO)
    assert m.overrun_limit_ms == 2.0
    m = load_map(_map(tmp_path, GOOD.replace("max_ms: 20}", "max_ms: 20, recover_ms: 500}")), load_dbc(DBC), DBC, GIN, GOUT)
    assert m.outputs["vibration"].recover_ms == 500 and m.outputs["force"].recover_ms == 0


@pytest.mark.parametrize("old,new,expect", [
    ("ToolPosition.PosY,", "ToolPosition.PosYY,", "did you mean 'ToolPosition.PosY'"),
    ("ToolPosition.PosX,", "ToolPositon.PosX,", "did you mean 'ToolPosition'"),
    ("  normal_force: {signal: NormalForce, timeout_ms: 3}", "  normal_forse: {signal: NormalForce, timeout_ms: 3}", "did you mean 'normal_force'"),
    ("timeout_ms: 5", "timeout: 5", "did you mean 'timeout_ms'"),
    ("    timeout_ms: 5\n", "", "missing 'timeout_ms'"),
    ("clamp: [-1, 1], ", "", "missing 'clamp"),
    ("safe: [0, 0, 1]", "safe: [0, 0, 9]", "outside clamp"),
    ("  vibration:", "  vibrato:", "graph has no output 'vibrato'"),
    ("ToolPosition.PosZ]", "ToolPosition.PosX]", "already bound"),
    ("ToolPosition.PosZ]", "]", "3 component(s) but 2 signal(s)"),
    ("flowtex_map: 1", "flowtex_map: 1\nscael: 2", "unknown key 'scael'"),
    ("{limit: 1.5, max_ms: 20}", "{limit: 0.5, max_ms: 20}", "at least the clamp HIGH"),
    ("{limit: 1.5, max_ms: 20}", "{limit: 1.5, max_ms: 20, recover_ms: 0}", "peak recover_ms must be a positive number"),
    ("{limit: 1.5, max_ms: 20}", "{limit: 1.5, max_ms: 20, recover: 9}", "peak must be {limit: L, max_ms: D} or"),
    ("{limit: 1.5, max_ms: 20}", "{limit: 1.5, recover_ms: 9}", "peak must be {limit: L, max_ms: D} or"),
])
def test_errors_name_line_and_fix(tmp_path, old, new, expect):
    assert old in GOOD
    path = _map(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(FlowtexError) as e:
        load_map(path, load_dbc(DBC), DBC, GIN, GOUT)
    text = str(e.value)
    assert expect in text, text
    assert text.startswith(f"{path}:")
    line = int(text.split(":")[1])
    assert line >= 1


def test_unbound_graph_input_and_yaml_errors(tmp_path):
    with pytest.raises(GraphError, match="graph input 'extra' is not bound"):
        load_map(_map(tmp_path, GOOD), load_dbc(DBC), DBC, {**GIN, "extra": 1}, GOUT)
    with pytest.raises(GraphError, match="duplicate key"):
        load_map(_map(tmp_path, GOOD + "inputs: {}\n"), load_dbc(DBC), DBC, GIN, GOUT)
    with pytest.raises(GraphError, match="a message is either sensor or actuator"):
        load_map(_map(tmp_path, GOOD.replace("VoiceCoilCmd.Current", "ToolForce.SurfNormalX")), load_dbc(DBC), DBC, GIN, GOUT)
