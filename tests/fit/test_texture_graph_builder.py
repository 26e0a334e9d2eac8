"""The texture graph fit and datasets render through, built in Python, is the YAML TEXTURE_GRAPH."""

from __future__ import annotations

from pathlib import Path

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.fit.texture_graph import TEXTURE_GRAPH, texture_builder
from flowtex.graph.spec import parse_spec


def test_texture_builder_is_texture_graph():
    ms = cork_like_model_set()
    a = parse_spec(TEXTURE_GRAPH.format(rate=1000.0), Path("<yaml>"), {"lookup.models": "set.json", "lookup.outside": "hold"})
    b = texture_builder(ms, 1000.0, {"outside": "hold"}).spec()
    assert (a.name, a.rate, a.seed) == (b.name, b.rate, b.seed)
    assert {n: (i.shape, i.unit) for n, i in a.inputs.items()} == {n: (i.shape, i.unit) for n, i in b.inputs.items()}
    assert {n: (s.type, s.every) for n, s in a.nodes.items()} == {n: (s.type, s.every) for n, s in b.nodes.items()}
    assert a.nodes["lookup"].params == b.nodes["lookup"].params | {"models": "set.json"}
    assert b.nodes["lookup"].params["models"] is ms
    assert [e.text for e in a.edges] == [e.text for e in b.edges]
    assert {n: (o.src.node, o.src.port) for n, o in a.outputs.items()} == {n: (o.src.node, o.src.port) for n, o in b.outputs.items()}
