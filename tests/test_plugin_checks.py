"""Mistakes in a plugin are reported as the plugin's, at its file and line, with the fix (issue 9 item 1)."""

from __future__ import annotations

import textwrap

from flowtex.cli import main

PLUGIN = '''
import numpy as np
from numba import njit

from flowtex.node_api import Node, NodeState, Param, Port


@njit(cache=True)
def ema_kernel({args}):
    a = p[0]
    for t in range(x.shape[0]):
        s[0] = s[0] + a * (x[t, 0] * x[t, 0] - s[0])
        y[t, 0] = {result}


class EmaRms(Node):
    """Exponential moving RMS."""

    type_name = "ema_rms"
    params = {{"alpha": Param("float", default=0.01)}}
    inputs = {{"x": Port((), "*")}}
    outputs = {{"y": Port((), "=x")}}
    kernel = ema_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["alpha"]]), state=np.zeros(1))
'''

GRAPH = """
flowtex: 1
name: t
rate: 1000
inputs: {x: {unit: m/s^2}}
nodes:
  e: {type: ema_rms}
edges: [x -> e.x]
outputs: {y: e.y}
"""


def _run(tmp_path, monkeypatch, capsys, text: str, plugin_name: str) -> tuple[int, str, str]:
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / f"{plugin_name}.py").write_text(textwrap.dedent(text))
    (tmp_path / "g.yaml").write_text(GRAPH)
    monkeypatch.chdir(tmp_path)  # the graph folder's plugins/ is searched; errors show the path as typed
    code = main(["validate", "g.yaml"])
    out = capsys.readouterr()
    return code, out.out, out.err.strip()


def _line_of(text: str, needle: str) -> int:
    return next(k for k, line in enumerate(textwrap.dedent(text).splitlines(), start=1) if needle in line)


# Each plugin file gets its own name: a loaded plugin module is cached per path in one process.
def test_kernel_missing_si(tmp_path, monkeypatch, capsys):
    text = PLUGIN.format(args="p, s, x, y", result="np.sqrt(s[0])")
    code, _, err = _run(tmp_path, monkeypatch, capsys, text, "ema_a")
    assert code == 1
    assert err == (f"plugins/ema_a.py:{_line_of(text, 'def ema_kernel')}: node 'ema_rms': kernel ema_kernel(p, s, x, y) "
                   "takes 4 arguments but the node's ports need 5: ema_kernel(p, s, si, x, y) -- p (params), s (float state), "
                   "si (int state), then the inputs (x) and the outputs (y) in declaration order")


def test_kernel_without_njit(tmp_path, monkeypatch, capsys):
    text = PLUGIN.format(args="p, s, si, x, y", result="np.sqrt(s[0])").replace("@njit(cache=True)\n", "")
    code, _, err = _run(tmp_path, monkeypatch, capsys, text, "ema_b")
    assert code == 1
    assert err.startswith(f"plugins/ema_b.py:{_line_of(text, 'def ema_kernel')}: node 'ema_rms': kernel ema_kernel is a plain "
                          "Python function; decorate it with @njit(cache=True)")
    assert "internal error" not in err


def test_kernel_typing_error_points_at_the_plugin_line(tmp_path, monkeypatch, capsys):
    text = PLUGIN.format(args="p, s, si, x, y", result="np.sqrt(s)")  # assigns an array to a float element
    folder = tmp_path / "plugins"
    folder.mkdir()
    (folder / "ema_c.py").write_text(textwrap.dedent(text))
    (tmp_path / "g.yaml").write_text(GRAPH)
    (tmp_path / "r.csv").write_text("x\n1\n2\n")
    monkeypatch.chdir(tmp_path)
    want = f"plugins/ema_c.py:{_line_of(text, 'np.sqrt(s)')}: node 'ema_rms': kernel ema_kernel does not compile"
    for argv in (["validate", "g.yaml"], ["run", "g.yaml", "-i", "r.csv"]):  # validate compiles what it validates (issue 25)
        assert main(argv) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith(want)
        assert "internal error" not in err and "\n" not in err


def test_missing_kernel(tmp_path, monkeypatch, capsys):
    text = PLUGIN.format(args="p, s, si, x, y", result="np.sqrt(s[0])").replace("    kernel = ema_kernel\n", "")
    code, _, err = _run(tmp_path, monkeypatch, capsys, text, "ema_d")
    assert code == 1
    assert err.startswith(f"plugins/ema_d.py:{_line_of(text, 'class EmaRms')}: node 'ema_rms': defines no kernel")


def test_graph_folder_plugins_are_found_from_anywhere(tmp_path, monkeypatch, capsys):
    project = tmp_path / "project"
    (project / "plugins").mkdir(parents=True)
    (project / "plugins" / "ema_e.py").write_text(textwrap.dedent(PLUGIN.format(args="p, s, si, x, y", result="np.sqrt(s[0])")))
    (project / "g.yaml").write_text(GRAPH)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["validate", str(project / "g.yaml")]) == 0
    assert "ok" in capsys.readouterr().out
    (elsewhere / "g.yaml").write_text(GRAPH)  # a graph without plugins/ beside it: the error says where to look
    assert main(["validate", "g.yaml"]) == 1
    err = capsys.readouterr().err
    assert "unknown node type 'ema_rms'" in err and "--plugins DIR" in err and "$FLOWTEX_PLUGINS" in err
