"""The two compile tiers (docs/engine.md) compute the same bits: every example graph, random graphs, step vs run."""

from __future__ import annotations

import os
import subprocess
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_examples import EXAMPLES, GOLDEN, GRAPHS, SCENES

from flowtex.errors import FlowtexError
from flowtex.graph.compiled import Graph, load_graph
from flowtex.graph.resolve import resolve_graph
from flowtex.graph.spec import parse_spec
from flowtex.registry import load_registry
from flowtex.runtime.offline import run_recording
from flowtex.testing import check_golden

TIERS = ("fused", "dispatch")


def same_bits(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> list[str]:
    """Names of the outputs whose float64 bits differ (NaN payloads included)."""
    assert a.keys() == b.keys()
    return [k for k in a if a[k].shape != b[k].shape or not np.array_equal(a[k].view(np.int64), b[k].view(np.int64))]


def _tier_order(names) -> list[str]:
    """Reverse order, the graphs without a texture lookup first. test_examples.py (another xdist worker, started at the
    same time: conftest.SLOW_FIRST) compiles the same fused modules in sorted order, so each worker compiles half and
    loads the other's from the shared cache instead of waiting on the same entry's lock; and it compiles the texture
    kernels (the heaviest node kernels) third, which this file, starting elsewhere, then loads instead of compiling
    them at the same time (numba's per-function cache has no lock between processes)."""
    return sorted(sorted(names, reverse=True), key=lambda n: "type: texture_lookup" in (GRAPHS / n).read_text())


@pytest.mark.parametrize("name", _tier_order(EXAMPLES))
def test_example_graph_dispatch_equals_fused_bit_for_bit_and_golden(name, monkeypatch):
    recording, options = EXAMPLES[name]
    outs = {}
    for tier in TIERS:
        graph = load_graph(GRAPHS / name, plugins=options.get("plugins", ()), tier=tier)
        assert graph.tier == tier
        outs[tier] = run_recording(graph, GRAPHS / recording, None, progress=False)
    assert same_bits(outs["fused"], outs["dispatch"]) == []
    # the fused tier is golden-tested in test_examples.py; the dispatch tier (the default here) against the same file
    monkeypatch.setenv("FLOWTEX_COMPILE", "dispatch")
    check_golden(GRAPHS / name, GRAPHS / recording, GOLDEN / (Path(name).stem + ".npz"), **options)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_scene_example_runs_the_same_on_both_tiers(name, tmp_path, monkeypatch):
    from flowtex.scene.build import plan_to_graph

    planned = tmp_path / "planned.yaml"
    monkeypatch.chdir(GRAPHS.parent)
    plan_to_graph(GRAPHS / name, planned, (), relative=False)
    outs = {tier: run_recording(load_graph(planned, tier=tier), GRAPHS / SCENES[name], None, progress=False) for tier in TIERS}
    assert same_bits(outs["fused"], outs["dispatch"]) == []
    monkeypatch.setenv("FLOWTEX_COMPILE", "dispatch")
    check_golden(planned, GRAPHS / SCENES[name], GOLDEN / (Path(name).stem + ".npz"))


def test_dispatch_step_by_step_and_chunked_equal_one_pass():
    # a feedback loop (tick by tick, delay emit/absorb) and a multi-rate node (holds): the driver's two paths
    path = GRAPHS / "multirate_feedback.yaml"
    data = np.load(GRAPHS / "data" / "accel_demo.npz")
    fused = load_graph(path, tier="fused")
    graph = load_graph(path, tier="dispatch")
    inputs = {k: data[k][:700] for k in graph.inputs}
    whole = {k: v.copy() for k, v in graph.run(inputs).items()}
    assert same_bits(whole, fused.run(inputs)) == []
    graph.reset()
    parts = [graph.process({k: v[a:b] for k, v in inputs.items()}) for a, b in ((0, 1), (1, 300), (300, 700))]
    chunked = {k: np.concatenate([p[k] for p in parts]) for k in whole}
    assert same_bits(whole, chunked) == []
    live = graph.with_block_rows(1)  # the live runtime's layout: one row per port
    live.reset()
    steps = [live.step({k: v[t] for k, v in inputs.items()}) for t in range(700)]
    stepped = {k: np.array([s[k] for s in steps]).reshape(whole[k].shape) for k in whole}
    assert live.tier == "dispatch"
    assert same_bits(whole, stepped) == []


AUTO_SCRIPT = """
import sys, time
from flowtex.cache import cache_dir
from flowtex.compile.service import PID_FILE, background_running
from flowtex.graph.compiled import load_graph
first = load_graph(sys.argv[1], tier="auto").tier
pid_file = cache_dir() / PID_FILE
for _ in range(1200):  # the background compile: started by the call above, at nice 19
    running = background_running() or not pid_file.exists()  # running, or not started yet
    if not running:
        break
    time.sleep(0.5)
print(first, load_graph(sys.argv[1], tier="auto").tier)
"""


def test_auto_runs_dispatch_then_fused_once_the_background_compile_is_done(tmp_path):
    # a fresh cache (flowtex's and numba's): auto has no fused code yet, so it runs the dispatch tier and
    # compiles the fused one in the background; the next build of the structure finds it
    path = tmp_path / "g.yaml"
    path.write_text("flowtex: 1\nname: tiny\nrate: 1000\ninputs:\n  x: {}\nnodes:\n  g: {type: gain, params: {k: 2}}\n"
                    "edges:\n  - x -> g.x\noutputs:\n  y: g.y\n")
    env = {**os.environ, "FLOWTEX_CACHE_DIR": str(tmp_path / "cache"), "FLOWTEX_BACKGROUND": "1"}
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, "-c", AUTO_SCRIPT, str(path)], env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["dispatch", "fused"]


def test_show_code_shows_what_runs(capsys, monkeypatch):
    from flowtex.cli import main

    monkeypatch.chdir(GRAPHS.parent)
    assert main(["graph", "graphs/multirate_feedback.yaml", "--show-code", "--compile", "dispatch"]) == 0
    text = capsys.readouterr().out
    assert "Dispatch tier" in text and "def block(f, i, n):" in text and "call_pointer(" in text
    graph = load_graph(GRAPHS / "multirate_feedback.yaml", tier="dispatch")
    for k, name in enumerate(graph.resolved.nodes, start=1):
        assert f"#   {k}. {name} (" in text  # every node, in execution order, with its wrapper files
    assert text.count("w_") >= len(graph.resolved.nodes)
    assert main(["graph", "graphs/multirate_feedback.yaml", "--show-code"]) == 0
    assert "Generated by flowtex from graph" in capsys.readouterr().out  # the fused tier's generated source


def test_unknown_tier_is_refused(tmp_path):
    with pytest.raises(FlowtexError, match="use one of fused, dispatch, auto"):
        load_graph(GRAPHS / "accel_preprocess.yaml", tier="jit")


# --- random graphs over the registry's node types -------------------------------------------------------

PARAM_VALUES = {"order": 2, "cutoff_hz": 50.0, "b": [0.5, 0.25, 0.125], "low": -1.0, "high": 1.0, "value": 0.5, "k": 2.0,
                "to_hz": 500.0, "index": 0, "limit": 1.0, "b_index": 1}
"""Values for required parameters (node types that require a file are left out)."""
EXAMPLE_PLUGINS = Path(__file__).resolve().parents[1] / "plugins"
"""The repository's example plugin folder (flowtex never searches the current folder's ./plugins)."""
Kind = tuple[tuple[int, ...], str]
"""A port's (shape, unit): an edge joins ports of one kind."""


@cache
def node_types() -> tuple[tuple[str, dict, dict[str, Kind], dict[str, Kind]], ...]:
    """(type, params, input -> kind, output -> kind) of every registered type that builds without files.

    Inputs of any shape are tried scalar first, then as 3-vectors; inputs of any unit take dimensionless signals.
    """
    registry = load_registry((EXAMPLE_PLUGINS,))  # the example plugin node soft_clip is one of the types
    found = []
    for name in registry.names():
        cls = registry.get(name)
        params = {k: PARAM_VALUES[k] for k, p in cls.params.items() if p.required and k in PARAM_VALUES}
        if any(p.required and k not in params for k, p in cls.params.items()):
            continue
        for free in ((), (3,)):
            ins = {p: (port.shape if isinstance(port.shape, tuple) else free,
                       "" if port.unit == "*" or port.unit.startswith("=") else port.unit) for p, port in cls.inputs.items()}
            kinds = sorted(set(ins.values()))
            text = _graph_text(kinds, [(name, "n0", params, {p: f"in{kinds.index(k)}" for p, k in ins.items()}, 1)],
                               ["n0." + o for o in cls.outputs])
            try:
                rg = resolve_graph(parse_spec(text, Path("probe.yaml")), registry)
            except (FlowtexError, ValueError, TypeError, KeyError):
                continue
            outs = {p: (spec.shape, spec.unit) for p, spec in rg.nodes["n0"].out_specs.items() if spec.shape in ((), (3,))}
            if outs:
                found.append((name, params, ins, outs))
                break
    return tuple(found)


def input_kinds() -> list[Kind]:
    """One graph input per kind that some node type reads."""
    return sorted({k for t in node_types() for k in t[2].values()})


def test_random_graphs_cover_most_node_types():
    names = {t[0] for t in node_types()}
    assert len(names) >= 25, sorted(names)  # 29 built-in types and soft_clip; those needing a model, pattern or tap file are left out


def _graph_text(kinds: list[Kind], nodes: list[tuple[str, str, dict, dict[str, str], int]], outputs: list[str]) -> str:
    lines = ["flowtex: 1", "name: random", "rate: 1000", "seed: 3", "inputs:"]
    lines += [f"  in{j}: {{shape: {list(shape)}, unit: '{unit}'}}" for j, (shape, unit) in enumerate(kinds)]
    lines += ["nodes:"] + [f"  {n}: {{type: {t}, every: {every}, params: {params}}}" for t, n, params, _, every in nodes]
    edges = [f"  - {src} -> {n}.{port}" for _, n, _, wiring, _ in nodes for port, src in wiring.items()]
    lines += ["edges:"] + edges if edges else []
    lines += ["outputs:"] + [f"  o{k}: {src}" for k, src in enumerate(outputs)]
    return "\n".join(lines) + "\n"


@st.composite
def random_graphs(draw):
    types = node_types()
    kinds = input_kinds()
    n = draw(st.integers(1, 4))
    sources: dict[Kind, list[str]] = {k: [f"in{j}"] for j, k in enumerate(kinds)}
    nodes = []
    made = []
    first_kinds: dict[str, Kind] = {}
    for k in range(n):
        name, params, ins, outs = draw(st.sampled_from(types))
        first_kinds = first_kinds or dict(ins)
        wiring = {p: draw(st.sampled_from(sources[kind])) for p, kind in ins.items()}
        nodes.append((name, f"n{k}", params, wiring, draw(st.sampled_from((1, 1, 2, 3)))))
        for o, kind in outs.items():
            sources.setdefault(kind, []).append(f"n{k}.{o}")
            made.append(f"n{k}.{o}")
    first_in = next(iter(nodes[0][3]), None)
    if first_in is not None and draw(st.booleans()):  # close a feedback loop through a delay into the first node
        late = [src for src in sources[first_kinds[first_in]] if src.startswith(f"n{n - 1}.")]
        if late:
            nodes[0][3][first_in] = "fb.y"
            nodes.append(("delay", "fb", {}, {"x": late[0]}, 1))
    outputs = sorted(set(draw(st.lists(st.sampled_from(made), min_size=1, max_size=3))) | {made[-1]})
    return _graph_text(kinds, nodes, outputs)


def random_inputs(n: int) -> dict[str, np.ndarray]:
    """Each graph input: standard normal noise (scalars offset by 1, so forces are mostly positive)."""
    rng = np.random.default_rng(7)
    return {f"in{j}": rng.standard_normal((n, *shape)) + (1.0 if shape == () else 0.0) for j, (shape, _) in enumerate(input_kinds())}


@settings(max_examples=5, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(text=random_graphs())
def test_random_graph_dispatch_equals_fused_bit_for_bit(text):
    registry = load_registry((EXAMPLE_PLUGINS,))  # the example plugin node soft_clip is one of the types
    try:
        rg = resolve_graph(parse_spec(text, Path("random.yaml")), registry)
    except FlowtexError:
        assume(False)  # e.g. a feedback loop the delay does not break, or a shape a node refuses
        raise
    inputs = {k: v for k, v in random_inputs(1500).items() if k in rg.input_specs}
    outs = {}
    for tier in TIERS:
        graph = Graph(rg, 256, tier)  # 1500 ticks = 5 full blocks and a partial one
        outs[tier] = {k: v.copy() for k, v in graph.run(inputs).items()}
    assert same_bits(outs["fused"], outs["dispatch"]) == [], text
