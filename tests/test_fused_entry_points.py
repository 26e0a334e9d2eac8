"""The fused tier compiles only the entry points a use needs, each sealed and loaded from the cache by the next process.

An offline ``run()`` compiles ``run`` alone (it holds ``block``'s body, it does not call ``block``); ``step()``
compiles ``step`` alone (likewise); ``step_block()`` and live code compile ``block``. Whatever order they compile in,
the outputs are the same bits, and a second process compiles none of them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from types import FunctionType

import numpy as np
import pytest

from flowtex.graph.compiled import load_graph
from flowtex.graph.kcache import entry_ok

GRAPH = """
flowtex: 1
name: fused-entry-points
rate: 1000
inputs:
  x: {}
nodes:
  g: {type: gain, params: {k: 2}}
  h: {type: gain, every: 3, params: {k: 3}}
  s: {type: add}
edges:
  - x -> g.x
  - g.y -> h.x
  - h.y -> s.a
  - x -> s.b
outputs:
  y: s.y
  z: h.y
"""
"""Every node runs block-wise except ``h``, which runs every third tick and holds its output between (the guarded
path of the generated body), so ``run``'s copy of ``block``'s body is exercised on both paths."""

X = np.sin(np.arange(50) * 0.37) * 5.0


def _module(graph):
    """The generated module of ``graph``'s structure (its ``block``, ``run`` and ``step`` numba functions)."""
    return sys.modules[f"flowtex_generated_{graph.fused_plan.digest}"]


def _signatures(graph) -> dict[str, int]:
    module = _module(graph)
    return {name: len(getattr(module, name).signatures) for name in ("run", "block", "step")}


@pytest.fixture
def graph_file(write_graph):
    return write_graph(GRAPH)


def test_an_offline_run_compiles_run_alone_and_step_later_gives_the_same_bits(graph_file):
    graph = load_graph(graph_file, tier="fused")
    assert graph.tier == "fused"
    assert _signatures(graph) == {"run": 0, "block": 0, "step": 0}  # building compiles nothing yet
    offline = graph.run({"x": X})
    assert _signatures(graph) == {"run": 1, "block": 0, "step": 0}  # run holds block's body: no separate block
    # expected values from the graph's arithmetic: h = 3 * 2x sampled every third tick and held, y = h + x
    held = 6.0 * X[(np.arange(X.size) // 3) * 3]
    np.testing.assert_array_equal(offline["z"], held)
    np.testing.assert_array_equal(offline["y"], held + X)

    graph.reset()
    step = graph.step  # taken before its first call, as a caller's loop takes it
    stepped = [step({"x": float(v)}) for v in X]  # compiles step, which holds block's body too
    assert _signatures(graph) == {"run": 1, "block": 0, "step": 1}
    # the compiled entry point has replaced its Python stand-in: later calls pay nothing for the lazy compile
    assert not isinstance(step.__globals__["STEP"], FunctionType)
    assert [s["y"] for s in stepped] == offline["y"].tolist()  # bit for bit
    assert [s["z"] for s in stepped] == offline["z"].tolist()

    live = graph.with_block_rows(1)  # the live layout: step_block, the loaded block
    step_block, ys = live.step_block, []
    for v in X:
        live.input_view("x")[:] = v
        step_block(1)
        ys.append(float(live.output_view("y")[0]))
    assert ys == offline["y"].tolist()
    assert not isinstance(live._block_entry, FunctionType)  # likewise block's
    assert _signatures(graph) == {"run": 1, "block": 1, "step": 1}

    plan = graph.fused_plan  # one seal covers every file of the module, whichever entry point compiled it
    files = sorted(Path(_module(graph).block._cache._cache_path).glob(f"g_{plan.digest}.*.nb[ic]"))
    assert {f.name.split(".")[1].split("-")[0] for f in files} == {"run", "block", "step"}
    assert entry_ok(plan.seal_path(), files)
    assert plan.cached("run") and plan.cached("block") and plan.cached("step")


SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np
    from flowtex.graph.compiled import load_graph
    graph = load_graph(sys.argv[1], tier="fused").prepare("run", "block", "step")
    module = sys.modules[f"flowtex_generated_{graph.fused_plan.digest}"]
    stats = {name: getattr(module, name).stats for name in ("run", "block", "step")}
    x = np.array(json.loads(sys.argv[2]))
    print(json.dumps({"hits": {n: sum(s.cache_hits.values()) for n, s in stats.items()},
                      "misses": {n: sum(s.cache_misses.values()) for n, s in stats.items()},
                      "rebuilt": graph.rebuilt_cache_entries, "y": graph.run({"x": x})["y"].tolist(),
                      "step": graph.reset() or graph.step({"x": 1.5})["y"]}))
""")


def test_a_second_process_loads_every_entry_point_without_compiling(graph_file):
    graph = load_graph(graph_file, tier="fused").prepare("run", "block", "step")  # compiled (or loaded) here
    expected = graph.run({"x": X})["y"].tolist()
    graph.reset()
    first_step = graph.step({"x": 1.5})["y"]
    assert first_step == 6.0 * 1.5 + 1.5  # tick 0 is one of h's ticks
    env = {**os.environ, "FLOWTEX_BACKGROUND": "0"}
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(graph_file), json.dumps(X.tolist())], env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["misses"] == {"run": 0, "block": 0, "step": 0}
    assert result["hits"] == {"run": 1, "block": 1, "step": 1}
    assert result["rebuilt"] == []
    assert result["y"] == expected and result["step"] == first_step  # the loaded code gives the same bits


def test_prepare_names_the_entry_points(graph_file):
    from flowtex.errors import FlowtexError

    graph = load_graph(graph_file, tier="dispatch")
    with pytest.raises(FlowtexError, match="unknown entry point 'tick'; use one of run, block, step"):
        graph.prepare("tick")
