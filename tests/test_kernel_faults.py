"""A kernel that raises ends the run on every tier with one line naming the node; nothing is written (issue 27 §5)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.graph.arena import FAULT
from flowtex.graph.compiled import load_graph
from flowtex.graph.faults import KernelError
from tests.plugin_files import chain_graph, plugin_project, plugin_source

PLUGIN = plugin_source("boom_fault", "boom_kernel", """
for t in range(x.shape[0]):
    if x[t, 0] > 99.5:
        raise ValueError("x too large")
    y[t, 0] = x[t, 0]
""", doc="Copies x; raises above 99.5.", cls="Boom")

GRAPH = chain_graph("b: {type: boom_fault}", "g: {type: gain, params: {k: 2.0}}")


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """The plugin, graph and recording, shared by the tests (they read them and must write nothing): one plugin file
    compiles its kernel once, and the fused structure once."""
    return plugin_project(tmp_path_factory.mktemp("faults"), {"boom_fault.py": PLUGIN}, GRAPH, np.arange(300.0))


def _raise_line() -> int:
    return next(k for k, line in enumerate(PLUGIN.splitlines(), start=1) if "raise ValueError" in line)


@pytest.mark.parametrize("tier", ["dispatch", "fused"])
def test_run_refuses_and_writes_nothing(project, capsys, tier):
    out = project / "out.npz"
    code = main(["run", str(project / "g.yaml"), "-i", str(project / "r.npz"), "-o", str(out), "--compile", tier])
    err = [line for line in capsys.readouterr().err.splitlines() if "kernel raised" in line]
    assert code == 1
    assert len(err) == 1 and "node 'b' (boom_fault)" in err[0] and "internal error" not in err[0]
    assert err[0].startswith(str(project / "plugins" / "boom_fault.py") + ":")
    if tier == "fused":  # the exception's own message and line
        assert f"boom_fault.py:{_raise_line()}:" in err[0] and "ValueError: x too large" in err[0]
    else:  # the block of ticks that raised (one block: ticks 0..299)
        assert "ticks 0..299" in err[0]
    assert not out.exists() and list(project.glob("out*")) == []


@pytest.mark.parametrize("tier", ["dispatch", "fused"])
def test_step_raises_and_the_graph_is_reset(project, tier):
    graph = load_graph(project / "g.yaml", tier=tier)
    assert graph.step({"x": 3.0})["y"] == 6.0
    with pytest.raises(KernelError, match="node 'b' \\(boom_fault\\)"):
        graph.step({"x": 100.0})
    assert graph.i[FAULT] == 0 and graph.ticks == 0  # reset: usable again
    assert graph.step({"x": 1.0})["y"] == 2.0
    ok = graph.run({"x": np.arange(50.0)})["y"]
    np.testing.assert_array_equal(ok, 2.0 * np.arange(50.0))
    graph.input_view("x")[:] = 100.0  # the live path: input views, then step_block
    with pytest.raises(KernelError, match="node 'b' \\(boom_fault\\)"):
        graph.step_block(1)
    assert graph.i[FAULT] == 0
