"""The two compile tiers (docs/engine.md) compute the same bits: every example graph, random graphs, step vs run."""

from __future__ import annotations

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


@pytest.mark.parametrize("name", sorted(EXAMPLES))
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


def test_auto_takes_fused_when_cached_and_dispatch_otherwise(tmp_path, monkeypatch):
    monkeypatch.setenv("FLOWTEX_CACHE_DIR", str(tmp_path / "cache"))
    text = (GRAPHS / "accel_preprocess.yaml").read_text()
    path = tmp_path / "g.yaml"
    path.write_text(text)
    first = load_graph(path, tier="auto")  # background compiles are off in tests (conftest)
    assert first.tier == "dispatch"
    load_graph(path, tier="fused")
    assert load_graph(path, tier="auto").tier == "fused"
    with pytest.raises(FlowtexError, match="use one of fused, dispatch, auto"):
        load_graph(path, tier="jit")


# --- random graphs over the registry's node types -------------------------------------------------------

@cache
def scalar_node_types() -> tuple[tuple[str, tuple[str, ...], tuple[str, ...]], ...]:
    """(type, inputs, outputs) of every registered node type that builds with default parameters on scalar inputs."""
    registry = load_registry(())
    found = []
    for name in registry.names():
        cls = registry.get(name)
        ins = tuple(cls.inputs)
        text = _graph_text([(name, "n0", {p: "a" for p in ins}, 1)], ["n0." + o for o in cls.outputs])
        try:
            rg = resolve_graph(parse_spec(text, Path("probe.yaml")), registry)
        except (FlowtexError, ValueError, TypeError, KeyError):
            continue
        outs = tuple(p for p, spec in rg.nodes["n0"].out_specs.items() if spec.shape == ())
        if outs:
            found.append((name, ins, outs))
    return tuple(found)


def _graph_text(nodes: list[tuple[str, str, dict[str, str], int]], outputs: list[str]) -> str:
    lines = ["flowtex: 1", "name: random", "rate: 1000", "seed: 3", "inputs:", "  a: {}", "  b: {}", "nodes:"]
    lines += [f"  {n}: {{type: {t}, every: {every}}}" for t, n, _, every in nodes]
    edges = [f"  - {src} -> {n}.{port}" for _, n, wiring, _ in nodes for port, src in wiring.items()]
    lines += ["edges:"] + edges if edges else []
    lines += ["outputs:"] + [f"  o{k}: {src}" for k, src in enumerate(outputs)]
    return "\n".join(lines) + "\n"


@st.composite
def random_graphs(draw):
    types = scalar_node_types()
    n = draw(st.integers(1, 4))
    sources = ["a", "b"]
    nodes = []
    for k in range(n):
        name, ins, outs = draw(st.sampled_from(types))
        wiring = {p: draw(st.sampled_from(sources)) for p in ins}
        nodes.append((name, f"n{k}", wiring, draw(st.sampled_from((1, 1, 2, 3)))))
        sources += [f"n{k}.{o}" for o in outs]
    if draw(st.booleans()) and nodes[0][2]:  # close a feedback loop through a delay into the first node
        port = next(iter(nodes[0][2]))
        nodes[0][2][port] = "fb.y"
        nodes.append(("delay", "fb", {"x": sources[-1]}, 1))
    outputs = sorted(set(draw(st.lists(st.sampled_from(sources[2:]), min_size=1, max_size=3))) | {sources[-1]})
    return _graph_text(nodes, outputs)


@settings(max_examples=6, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(text=random_graphs())
def test_random_graph_dispatch_equals_fused_bit_for_bit(text):
    registry = load_registry(())
    try:
        rg = resolve_graph(parse_spec(text, Path("random.yaml")), registry)
    except FlowtexError:
        assume(False)  # e.g. a feedback loop the delay does not break, or a shape a node refuses
        raise
    x = np.random.default_rng(7).standard_normal((1500, 2)) * np.array([1.0, 0.2]) + np.array([0.0, 1.0])
    inputs = {"a": x[:, 0], "b": x[:, 1]}
    outs = {}
    for tier in TIERS:
        graph = Graph(rg, 256, tier)  # 1500 ticks = 5 full blocks and a partial one
        outs[tier] = {k: v.copy() for k, v in graph.run(inputs).items()}
    assert same_bits(outs["fused"], outs["dispatch"]) == [], text
