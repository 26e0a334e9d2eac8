"""Numbers as people write them (YAML 1.2 / JSON exponents) and format versions that are exactly 1, not true."""

from __future__ import annotations

import pytest

from flowtex.errors import GraphError
from flowtex.graph.compiled import check_graph
from flowtex.graph.spec import parse_override, parse_spec
from flowtex.scene.file import parse_scene
from flowtex.yamlsource import load_yaml

GRAPH = """flowtex: 1
rate: {rate}
inputs:
  x: {{unit: N}}
nodes:
  lp: {{type: butterworth, params: {{kind: lowpass, order: 2, cutoff_hz: {cutoff}}}}}
  g: {{type: gain, params: {{k: 2}}}}
edges:
  - x -> lp.x
  - lp.y -> g.x
outputs:
  y: g.y
"""


@pytest.mark.parametrize("text, value", [
    ("1e6", 1e6), ("3e2", 300.0), ("-3E2", -300.0), ("3.0e2", 300.0), ("3.0e+2", 300.0), (".5e-3", 0.0005), ("1e+03", 1000.0),
    ("12", 12), ("1.5", 1.5),
])
def test_exponent_numbers_are_numbers(text, value):
    got = load_yaml(f"v: {text}", "t.yaml")["v"]
    assert got == value and type(got) is type(value)


@pytest.mark.parametrize("text", ["e5", "1e", "1e3x", "1e3.5", "'1e3'"])
def test_text_that_is_not_a_number_stays_text(text):
    assert isinstance(load_yaml(f"v: {text}", "t.yaml")["v"], str)


def test_graph_rate_and_params_in_exponent_form(write_graph):
    rg = check_graph(write_graph(GRAPH.format(rate="1e3", cutoff="5e1")))
    assert rg.spec.rate == 1000.0 and rg.nodes["lp"].params["cutoff_hz"] in (50.0, (50.0,))  # a float or floats param


def test_set_takes_exponent_numbers():
    assert parse_override("g.k=1e3") == ("g.k", 1000.0)
    assert parse_override("rate=2e3") == ("rate", 2000.0)


@pytest.mark.parametrize("version", ["true", "'1'", "2", "1.5"])
def test_graph_version_must_be_the_integer_1(tmp_path, version):
    text = GRAPH.format(rate=1000, cutoff=50).replace("flowtex: 1", f"flowtex: {version}")
    with pytest.raises(GraphError, match=r"g.yaml:1:10: unsupported format version"):
        parse_spec(text, tmp_path / "g.yaml")


def test_scene_version_must_be_the_integer_1(tmp_path):
    body = "flowtex: true\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nsurfaces:\n  a: {models: m.json}\n"
    with pytest.raises(GraphError, match=r"s.yaml:1:10: unsupported format version true"):
        parse_scene(body, tmp_path / "s.yaml")
    scene = parse_scene(body.replace("true", "1").replace("250", "2.5e2"), tmp_path / "s.yaml")
    assert scene.speed_range == (50.0, 250.0)


def test_plugins_key_lists_folders_relative_to_the_graph(tmp_path):
    (tmp_path / "nodes").mkdir()
    (tmp_path / "g").mkdir()
    text = GRAPH.format(rate=1000, cutoff=50) + "plugins: [nodes, g/../nodes]\n"
    assert parse_spec(text, tmp_path / "g.yaml").plugins == [tmp_path / "nodes", tmp_path / "g/../nodes"]
    with pytest.raises(GraphError, match="plugins must be a list of folders"):
        parse_spec(GRAPH.format(rate=1000, cutoff=50) + "plugins: nodes\n", tmp_path / "g.yaml")


def test_whole_numbers_written_as_floats_are_integers(tmp_path):
    text = GRAPH.format(rate=1000, cutoff=50).replace("flowtex: 1", "flowtex: 1.0\nseed: 1e3").replace(
        "x: {unit: N}", "x: {unit: N, shape: [3.0]}\n  w: {shape: 2e0}").replace("g: {type: gain,", "g: {every: 4.0, type: gain,")
    spec = parse_spec(text, tmp_path / "g.yaml")
    assert spec.seed == 1000 and type(spec.seed) is int
    assert spec.nodes["g"].every == 4 and type(spec.nodes["g"].every) is int
    assert spec.inputs["x"].shape == (3,) and type(spec.inputs["x"].shape[0]) is int and spec.inputs["w"].shape == (2,)
    with pytest.raises(GraphError, match="seed must be a non-negative integer, got 2.5"):
        parse_spec(text.replace("seed: 1e3", "seed: 2.5"), tmp_path / "g.yaml")
