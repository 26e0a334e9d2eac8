"""Plugins written to the positional API keep working beside plugins that declare their memory (issue 24 item 1)."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

import flowtex
from flowtex.errors import FlowtexError
from tests.plugin_files import plugin_project, plugin_source

POSITIONAL = plugin_source("positional_sum", "_kernel", """
for t in range(x.shape[0]):
    s[0] += p[0] * x[t, 0]
    si[0] += 1
    y[t, 0] = s[0] + si[0]
""", doc="Running sum of k x plus the tick count, p/s/si indexed by position.", cls="Positional",
    params='{"k": Param("float", default=2.0, min=-10.0, max=10.0)}', outputs='{"y": Port((), "")}',
    build='NodeState(params=np.array([self.p["k"]]), state=np.zeros(1), istate=np.zeros(1, np.int64))')

DECLARED = '''
from numba import njit
from flowtex.node_api import Field, Layout, Memory, Node, Param, Port

MEMORY = Memory(params=Layout("float", [Field("k")]), state=Layout("float", [Field("acc")]),
                istate=Layout("int", [Field("ticks")]))
P_K = MEMORY.params.const("k")
S_ACC = MEMORY.state.const("acc")
SI_TICKS = MEMORY.istate.const("ticks")


@njit(cache=True)
def _kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        s[S_ACC] += p[P_K] * x[t, 0]
        si[SI_TICKS] += 1
        y[t, 0] = s[S_ACC] + si[SI_TICKS]


class Declared(Node):
    """The same node, its memory declared."""
    type_name = "declared_sum"
    params = {"k": Param("float", default=2.0, min=-10.0, max=10.0)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "")}
    kernel = _kernel
    memory = MEMORY

    def build(self, inputs, outputs):
        return self.pack_state(params={"k": self.p["k"]})
'''

GRAPH = '''
flowtex: 1
name: sums
rate: 1000
inputs: {x: {}}
nodes:
  a: {type: positional_sum}
  b: {type: declared_sum}
edges: [x -> a.x, x -> b.x]
outputs: {a: a.y, b: b.y}
'''


@pytest.fixture
def graph_path(tmp_path):
    return plugin_project(tmp_path, {"positional.py": POSITIONAL, "declared.py": DECLARED}, textwrap.dedent(GRAPH)) / "g.yaml"


def test_positional_and_declared_plugins_give_the_reference(graph_path):
    x = np.random.default_rng(1).standard_normal(300)
    graph = flowtex.load_graph(graph_path)
    out = graph.run({"x": x})
    want = np.cumsum(2.0 * x) + np.arange(1, x.size + 1)  # the running sum, each tick's own addition order
    np.testing.assert_allclose(out["a"].ravel(), want, rtol=1e-12, atol=1e-9)  # a sum of 300 terms: rounding only
    assert np.array_equal(out["a"], out["b"])  # the same operations in the same order: identical bits


def test_a_declared_plugin_packing_the_wrong_size_is_refused(graph_path):
    text = (graph_path.parent / "plugins" / "declared.py").read_text()
    (graph_path.parent / "plugins" / "declared.py").write_text(
        text.replace('return self.pack_state(params={"k": self.p["k"]})',
                     'return self.pack_state(params=np.array([1.0, 2.0]))').replace("from numba", "import numpy as np\nfrom numba"))
    with pytest.raises(FlowtexError, match="declared layout holds 1"):
        flowtex.load_graph(graph_path)
