"""No kernel writes the caller's arrays: ``Graph.run``/``process`` and ``Node.processor`` hand kernels flowtex's copy.

A kernel that writes its input is a plugin mistake (``flowtex plugin check`` names it), but the runtime must not let
it reach the user's data: with one input, ``Graph.run`` pointed the kernels at the caller's own array (no copy), and a
processor passed the caller's (ticks, width) array straight to its kernel, so such a kernel silently changed it.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.graph.builder import GraphBuilder
from flowtex.registry import load_registry

WRITER = '''\
from numba import njit

from flowtex.node_api import Node, Port


@njit(cache=True)
def writes_input(p, s, si, x, y):
    for t in range(x.shape[0]):
        for q in range(x.shape[1]):
            y[t, q] = x[t, q]
            x[t, q] = -1.0


class WritesInput(Node):
    """Copies x to y, then writes -1 into x: a plugin mistake that plugin check names."""

    type_name = "writes_input_test"
    inputs = {"x": Port(None, "*")}
    outputs = {"y": Port("=x", "=x")}
    kernel = writes_input
'''


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    path = tmp_path_factory.mktemp("writer_plugin")
    (path / "writes_input.py").write_text(WRITER)
    return path


def _graph(folder, shape=(), tier=None):
    return (GraphBuilder("w").input("x", shape=shape).node("n", "writes_input_test").edge("x -> n.x")
            .output("y", "n.y").build(plugins=folder, tier=tier))


@pytest.mark.parametrize(("shape", "tier"), [((), "fused"), ((3,), "fused"), ((), "dispatch")])
def test_graph_run_and_process_leave_a_single_input_as_it_was(folder, shape, tier) -> None:
    g = _graph(folder, shape, tier)
    assert g.tier == tier  # both tiers' run reads the inputs in place
    x = np.random.default_rng(1).standard_normal((50, *shape))
    before = x.copy()
    y = g.run({"x": x})["y"]
    np.testing.assert_array_equal(x, before)  # was all -1.0: the kernel wrote the caller's array
    np.testing.assert_array_equal(y, before)  # and the node still read the caller's values
    g.reset()
    g.process({"x": x[:20]})
    g.process({"x": x[20:]}, nonfinite="pass")
    np.testing.assert_array_equal(x, before)


def test_graph_run_leaves_a_read_only_input_as_it_was(folder) -> None:
    # The read-only flag protects nothing from a kernel: kernels address ports through the arena's raw pointers.
    x = np.linspace(0.0, 1.0, 30)
    x.flags.writeable = False
    _graph(folder).run({"x": x})
    np.testing.assert_array_equal(x, np.linspace(0.0, 1.0, 30))


@pytest.mark.parametrize("shape", [(), (3,)])
def test_a_processor_leaves_the_callers_array_as_it_was(folder, shape) -> None:
    proc = load_registry([folder]).types["writes_input_test"].processor()
    x = np.random.default_rng(2).standard_normal((40, *shape))
    before = x.copy()
    y = proc(x=x)["y"]
    np.testing.assert_array_equal(x, before)
    np.testing.assert_array_equal(y.reshape(x.shape), before)
