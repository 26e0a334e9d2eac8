"""Declaration mistakes are the plugin's: one line at its file and line, exit 1, in validate and run (issues 25 and 27 §5)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from tests.plugin_files import chain_graph, plugin_project, plugin_source

PLUGIN = plugin_source("decl_TAG", "decl_kernel", """
for t in range(x.shape[0]):
    y[t, 0] = p[0] * x[t, 0]
""", doc="Gain.", cls="Decl", params='{"k": Param("float", default=1.0)}', build='NodeState(params=np.array([self.p["k"]]))')

GRAPH = chain_graph("d: {type: decl_TAG}")

# (case, edit of the plugin, text of the line the error must point at, words of the message)
CASES = [
    ("missing_ref", ('Port((), "=x")', 'Port("=nope", "=x")'), "outputs = ", "shape '=nope' names no input; inputs are: x"),
    ("not_a_shape", ('Port((), "=x")', 'Port("abc", "=x")'), "outputs = ", "shape 'abc' is not a shape"),
    ("negative", ('Port((), "=x")', 'Port((-1,), "=x")'), "outputs = ", "shape (-1,) has a size below 1"),
    ("huge", ('Port((), "=x")', 'Port((10**9,), "=x")'), "outputs = ", "1,000,000,000 values per tick, more than the limit of 65,536"),
    ("unit_ref", ('Port((), "=x")', 'Port((), "=z")'), "outputs = ", "unit '=z' names no input"),
    ("min_max", ('Param("float", default=1.0)', 'Param("float", default=1.0, min=5, max=1)'), "params = ",
     "plugin failed to load: ValueError: Param min=5 and max=1 leave no allowed value"),
    ("kind", ('Param("float", default=1.0)', 'Param("floaty", default=1.0)'), "params = ",
     "plugin failed to load: ValueError: unknown parameter kind 'floaty'"),
    ("build_none", ('return NodeState(params=np.array([self.p["k"]]))', 'pass'), "def build",
     "build() of graph node 'd' returned None, not a NodeState"),
    ("build_raises", ('return NodeState(params=np.array([self.p["k"]]))', 'return NodeState(params=np.array([self.p["k"]]) / {}[0])'),
     "/ {}[0]", "build() of graph node 'd' raised KeyError: 0"),
]


def _line(text: str, needle: str) -> int:
    return next(k for k, line in enumerate(text.splitlines(), start=1) if needle in line)


def _setup(tmp_path, case: str, edit: tuple[str, str]) -> str:
    tag = case
    text = PLUGIN.replace("TAG", tag).replace(*edit)
    assert text != PLUGIN.replace("TAG", tag)
    plugin_project(tmp_path, {f"decl_{tag}.py": text}, GRAPH.replace("TAG", tag), np.arange(5.0))
    return text


def _errors(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if not line.startswith("flowtex: ")]


@pytest.mark.parametrize(("case", "edit", "at", "words"), CASES, ids=[c[0] for c in CASES])
def test_declaration_mistake_is_reported_at_the_plugin_line(tmp_path, monkeypatch, capsys, case, edit, at, words):
    text = _setup(tmp_path, case, edit)
    monkeypatch.chdir(tmp_path)
    for argv in (["validate", "g.yaml"], ["run", "g.yaml", "-i", "r.npz", "-o", "out.npz"]):
        assert main(argv) == 1
        err = _errors(capsys)
        assert len(err) == 1, err
        assert err[0].startswith(f"plugins/decl_{case}.py:{_line(text, at)}: "), err[0]
        assert words in err[0] and "internal error" not in err[0]
    assert not (tmp_path / "out.npz").exists()


def test_a_node_with_too_many_ports_is_refused_with_the_limit(tmp_path, monkeypatch, capsys):
    names = [f"x{k}" for k in range(500)]
    text = PLUGIN.replace("TAG", "many").replace('inputs = {"x": Port((), "*")}', "inputs = {" + ", ".join(
        f'"{n}": Port((), "*", optional=True)' for n in ["x", *names]) + "}").replace(
        "def decl_kernel(p, s, si, x, y)", f"def decl_kernel(p, s, si, x, {', '.join(names)}, y)")
    plugin_project(tmp_path, {"decl_many.py": text}, GRAPH.replace("TAG", "many"))
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "g.yaml"]) == 1
    err = _errors(capsys)
    assert err == [f"plugins/decl_many.py:{_line(text, 'inputs = ')}: node 'decl_many': 501 inputs and 1 outputs are 502 ports, "
                   "more than the limit of 27; take a vector input (Port((n,))) instead of many scalar ones"]


def test_a_node_at_the_port_limit_runs_on_both_tiers(tmp_path):
    # MAX_NODE_PORTS is a limit flowtex keeps, not one it merely states: 26 optional inputs and one output compile and run
    from flowtex.graph.compiled import load_graph
    from flowtex.limits import MAX_NODE_PORTS

    names = [f"x{k}" for k in range(MAX_NODE_PORTS - 1)]
    text = PLUGIN.replace("TAG", "limit").replace('inputs = {"x": Port((), "*")}', "inputs = {" + ", ".join(
        f'"{n}": Port((), "*", optional=True, default={k}.0)' for k, n in enumerate(names)) + "}").replace(
        'outputs = {"y": Port((), "=x")}', 'outputs = {"y": Port((), "")}').replace(
        "def decl_kernel(p, s, si, x, y)", f"def decl_kernel(p, s, si, {', '.join(names)}, y)").replace(
        "y[t, 0] = p[0] * x[t, 0]", f"y[t, 0] = p[0] * x0[t, 0] + {names[-1]}[t, 0]").replace(
        "range(x.shape[0])", "range(y.shape[0])")
    plugin_project(tmp_path, {"decl_limit.py": text}, GRAPH.replace("TAG", "limit").replace("x -> d.x", "x -> d.x0"))
    x = np.arange(5.0)
    for tier in ("dispatch", "fused"):
        y = load_graph(tmp_path / "g.yaml", tier=tier).run({"x": x})["y"]
        np.testing.assert_array_equal(y, x + (MAX_NODE_PORTS - 2))  # k = 1; the last input reads its default 62.0
