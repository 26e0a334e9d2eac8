"""GraphBuilder gives the graph its YAML twin gives: same spec, same output bit for bit, same error messages."""

from __future__ import annotations

import numpy as np
import pytest

import flowtex
from flowtex.errors import GraphError
from flowtex.graph.builder import GraphBuilder

YAML = """
flowtex: 1
name: twin
rate: 2000
seed: 7
inputs:
  x: {unit: N}
nodes:
  smooth: {type: butterworth, params: {order: 2, cutoff_hz: 100.0}}
  noise: {type: white_noise, every: 2, params: {variance: 0.25, unit: N}}
  mix: {type: add}
edges:
  - x -> smooth.x
  - smooth.y -> mix.a
  - noise.y -> mix.b
outputs:
  y: mix.y
  slow: noise.y
"""


def builder(mix_b: str = "mix.b", **smooth) -> GraphBuilder:
    return (GraphBuilder("twin", rate=2000, seed=7)
            .input("x", unit="N")
            .node("smooth", "butterworth", **({"order": 2, "cutoff_hz": 100.0} | smooth))
            .node("noise", "white_noise", every=2, variance=0.25, unit="N")
            .node("mix", "add")
            .edge("x -> smooth.x").edge("smooth.y -> mix.a").edge(f"noise.y -> {mix_b}")
            .output("y", "mix.y").output("slow", "noise.y"))


def test_builder_spec_is_the_yaml_spec(tmp_path):
    path = tmp_path / "twin.yaml"
    path.write_text(YAML)
    from flowtex.graph.spec import load_spec

    a, b = load_spec(path), builder().spec()
    assert (a.name, a.rate, a.seed) == (b.name, b.rate, b.seed)
    assert {n: (i.shape, i.unit) for n, i in a.inputs.items()} == {n: (i.shape, i.unit) for n, i in b.inputs.items()}
    assert {n: (s.type, s.params, s.every) for n, s in a.nodes.items()} == {n: (s.type, s.params, s.every) for n, s in b.nodes.items()}
    assert [e.text for e in a.edges] == [e.text for e in b.edges]
    assert {n: (o.src.node, o.src.port) for n, o in a.outputs.items()} == {n: (o.src.node, o.src.port) for n, o in b.outputs.items()}


def test_builder_graph_runs_bit_for_bit_as_yaml(tmp_path):
    path = tmp_path / "twin.yaml"
    path.write_text(YAML)
    x = np.random.default_rng(3).normal(size=3000)
    want = flowtex.load_graph(path, tier="dispatch").run({"x": x}, seed=11)
    got = builder().build(tier="dispatch").run({"x": x}, seed=11)
    assert set(got) == set(want) == {"y", "slow"}
    for name in want:
        assert np.array_equal(got[name], want[name]), name
    assert np.any(want["y"] != 0.0)


def _messages(exc: GraphError) -> list[str]:
    return [d.message for d in exc.diagnostics]


@pytest.mark.parametrize(("yaml_from", "yaml_to", "bad"), [
    ("cutoff_hz: 100.0}", "cutoff_hz: 100.0, cutof: 3}", lambda: builder(cutof=3)),
    ("noise.y -> mix.b", "noise.y -> mix.bb", lambda: builder(mix_b="mix.bb")),
    ("order: 2,", "order: 0,", lambda: builder(order=0)),
])
def test_builder_errors_are_the_yaml_errors_at_the_call(tmp_path, yaml_from, yaml_to, bad):
    path = tmp_path / "twin.yaml"
    assert yaml_from in YAML
    path.write_text(YAML.replace(yaml_from, yaml_to))
    with pytest.raises(GraphError) as from_yaml:
        flowtex.check_graph(path)
    with pytest.raises(GraphError) as from_builder:
        bad().resolve()
    assert _messages(from_builder.value) == _messages(from_yaml.value)
    assert all(str(d.location).startswith("GraphBuilder") for d in from_builder.value.diagnostics)
    assert all(str(d.location).startswith(str(path)) for d in from_yaml.value.diagnostics)


def test_builder_shape_errors_name_the_call():
    with pytest.raises(GraphError) as exc:
        GraphBuilder("g").input("x").node("2bad", "gain").edge("x > y").spec()
    text = str(exc.value)
    assert "GraphBuilder.node('2bad', 'gain'): node name '2bad' is not valid" in text
    assert "GraphBuilder.edge('x > y'): cannot read edge" in text
    assert "GraphBuilder('g'): outputs must be a non-empty mapping" in text


def test_a_node_given_a_loaded_model_set_reads_no_file():
    """files_read (what -o and --plot are checked against) lists the files a graph's path parameters name; a builder
    graph given the loaded object names none (it raised TypeError on the object)."""
    from flowtex.graph.resolved import files_read
    from flowtex.io.modelset import load_model_set
    from tests.conftest import REPO

    path = REPO / "graphs" / "data" / "synthetic_texture.json"
    for models, expected in ((load_model_set(path), set()), (str(path), {path.resolve()})):
        resolved = (GraphBuilder("t").input("speed", unit="mm/s").input("f", unit="N")
                    .node("lu", "texture_lookup", models=models).edge("speed -> lu.speed").edge("f -> lu.force")
                    .output("v", "lu.variance").resolve())
        assert files_read(resolved) == expected


def test_a_graph_without_inputs_continues_in_blocks_as_one_run():
    """A graph without inputs (a noise source, a 3-tick decimated noise feeding a filter) could only run_ticks, which
    resets: it could not be rendered in blocks. process_ticks continues, and blocks equal one run bit for bit."""
    graph = (GraphBuilder("blocks", rate=1000, seed=4)
             .node("w", "white_noise", every=3, variance=0.5)
             .node("lp", "butterworth", order=2, cutoff_hz=40.0)
             .edge("w.y -> lp.x").output("y", "lp.y").output("raw", "w.y").build())
    whole = graph.run_ticks(1000)
    first = graph.run_ticks(301)
    parts = [first] + [graph.process_ticks(n) for n in (1, 0, 97, 601)]
    for name in ("y", "raw"):
        np.testing.assert_array_equal(np.concatenate([p[name] for p in parts]), whole[name])
    again = graph.run_ticks(1000)  # run_ticks still starts over
    np.testing.assert_array_equal(again["y"], whole["y"])
    with pytest.raises(flowtex.errors.InputError, match=r"^n must be an integer >= 0, got -1"):
        graph.process_ticks(-1)
