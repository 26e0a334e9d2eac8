"""A map binding that converts no unit (scale 1, any offset) whose DBC unit differs from its graph port's unit.

flowtex converts no unit: a DBC signal in kN bound to a graph output in N with scale 1 commands 1000x the force the
graph meant. The map is refused naming the binding and the scale that converts; a pair of units no factor links warns.
The DBC is the bundled example with one SG_ line's unit edited; graph ports are PortSpecs (no graph is compiled).
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from types import SimpleNamespace

import pytest

from flowtex.cli import main
from flowtex.errors import GraphError
from flowtex.io.canmap import map_for_ports
from flowtex.io.dbc import load_dbc
from flowtex.node_decl import PortSpec
from flowtex.runtime.canio import load_io

REPO = Path(__file__).resolve().parents[2]
BASE = (REPO / "graphs" / "devices" / "example.dbc").read_text()
FX = ' SG_ Fx : 0|16@1- (0.001,0) [-10|10] "N" HapticDevice'
POSX = ' SG_ PosX : 0|20@1- (0.001,0) [-500|500] "mm" Host'
MAP = """
flowtex_map: 1
inputs:
  speed: {signal: ToolPosition.PosX, timeout_ms: 5}
outputs:
  force: {signal: ForceCmd.Fx, clamp: [-4, 4]}
"""
IN = {"speed": PortSpec((), "mm/s")}
OUT = {"force": PortSpec((), "N")}


def _files(tmp_path: Path, posx_unit: str = "mm/s", fx_unit: str = "N", map_text: str = MAP) -> tuple[Path, Path]:
    dbc = tmp_path / "dev.dbc"
    dbc.write_text(BASE.replace(POSX, POSX.replace('"mm"', f'"{posx_unit}"')).replace(FX, FX.replace('"N"', f'"{fx_unit}"')))
    m = tmp_path / "map.yaml"
    m.write_text(textwrap.dedent(map_text).lstrip("\n"))
    return dbc, m


def _graph(tmp_path: Path) -> Path:
    """A graph whose input is in mm/s and whose output is in N (the ports of IN and OUT)."""
    g = tmp_path / "g.yaml"
    g.write_text("flowtex: 1\nname: u\nrate: 1000\ninputs:\n  speed: {unit: mm/s}\nnodes:\n"
                 "  k: {type: gain, params: {k: 1.0, unit: N}}\nedges:\n  - speed -> k.x\noutputs:\n  force: k.y\n")
    return g


def _load(dbc: Path, m: Path):
    return map_for_ports(m, load_dbc(dbc), dbc, IN, OUT)


def test_output_in_n_bound_to_a_kn_signal_is_refused_with_the_scale(tmp_path):
    dbc, m = _files(tmp_path, fx_unit="kN")
    with pytest.raises(GraphError) as e:
        _load(dbc, m)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(f"{m}:5:3: outputs.force binds ForceCmd.Fx in kN"), msg
    assert "set scale: 0.001 for outputs.force (graph N -> DBC kN)" in msg, msg


def test_input_in_mm_per_s_bound_to_an_m_per_s_signal_is_refused_with_the_scale(tmp_path):
    dbc, m = _files(tmp_path, posx_unit="m/s")
    with pytest.raises(GraphError) as e:
        _load(dbc, m)
    msg = str(e.value)
    assert msg.startswith(f"{m}:3:3: inputs.speed binds ToolPosition.PosX in m/s"), msg
    assert "set scale: 1000 for inputs.speed (DBC m/s -> graph mm/s)" in msg, msg


def test_an_offset_with_scale_1_converts_no_unit(tmp_path):
    """An offset moves the zero in the same unit (a tare), so scale 1 with an offset still binds m/s to mm/s."""
    dbc, m = _files(tmp_path, posx_unit="m/s", map_text=MAP.replace("timeout_ms: 5}", "timeout_ms: 5, offset: 0.2}"))
    with pytest.raises(GraphError, match=r"set scale: 1000 for inputs\.speed \(DBC m/s -> graph mm/s\)"):
        _load(dbc, m)


def test_the_refusal_reaches_load_io_and_validate(tmp_path, capsys):
    """The runtime's loader (live, live --simulate, replay) and ``flowtex validate GRAPH --map`` both check units."""
    dbc, m = _files(tmp_path, fx_unit="mN")
    with pytest.raises(GraphError, match=r"set scale: 1000 for outputs\.force \(graph N -> DBC mN\)"):
        load_io(SimpleNamespace(inputs=IN, outputs=OUT), dbc, m)  # refused before the graph's arena is touched
    assert main(["validate", str(_graph(tmp_path)), "--dbc", str(dbc), "--map", str(m), "--no-plugins"]) == 1
    assert "set scale: 1000 for outputs.force" in capsys.readouterr().err


@pytest.mark.parametrize("posx_unit,fx_unit,scale", [
    ("mm/sec", "N", 1),          # the second spelled out is the second
    ("mm/s", "newton", 1000),    # the map's own conversion is not checked
    ("m/s", "N", 1000),          # scale 1000 converts m/s into mm/s
    ("", "-", 1),                # a unit that states nothing passes
])
def test_same_units_or_the_maps_own_scale_pass(tmp_path, posx_unit, fx_unit, scale):
    dbc, m = _files(tmp_path, posx_unit, fx_unit, MAP.replace("timeout_ms: 5}", f"timeout_ms: 5, scale: {scale}}}")
                    .replace("clamp: [-4, 4]}", f"clamp: [-4, 4], scale: {scale}}}"))
    assert _load(dbc, m).warnings == []


def test_an_unknown_unit_pair_warns_and_loads(tmp_path, capsys):
    dbc, m = _files(tmp_path, fx_unit="lbf")
    cm = _load(dbc, m)
    assert list(cm.outputs) == ["force"]
    assert len(cm.warnings) == 1 and cm.warnings[0].startswith(f"{m}:5:3: outputs.force binds ForceCmd.Fx in lbf"), cm.warnings
    assert "graph N -> DBC lbf" in cm.warnings[0]
    assert main(["validate", str(_graph(tmp_path)), "--dbc", str(dbc), "--map", str(m), "--no-plugins"]) == 0
    out = capsys.readouterr()
    assert out.out.splitlines()[-1].startswith(f"{m}: ok (device map, 1 inputs, 1 outputs")
    assert out.err.strip() == f"flowtex validate: warning: {cm.warnings[0]}"
