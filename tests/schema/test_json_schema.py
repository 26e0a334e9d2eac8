"""The JSON Schemas editors use come from the declarations validate uses: every bundled file passes them, the four
errors validate refuses (unknown node type, unknown parameter, value out of bounds, wrong choice) fail them, and
docs/schema/ holds exactly what `flowtex schema` prints."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import jsonschema
import pytest

from flowtex.cli import main
from flowtex.cli.schema import schema_text
from flowtex.filecheck import DEVICE_MAP, GRAPH, SCENE, file_kind
from flowtex.registry import load_registry
from flowtex.schema.jsonschema import graph_schema
from flowtex.yamlsource import load_yaml

REPO = Path(__file__).resolve().parents[2]
BUNDLED = sorted((REPO / "graphs").glob("*.yaml")) + sorted((REPO / "graphs" / "devices").glob("*.yaml"))


def _validator(schema: dict) -> jsonschema.Draft202012Validator:
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


COMMITTED = {GRAPH: "graph", SCENE: "scene", DEVICE_MAP: "map"}
PLUGINS = (str(REPO / "plugins"),)
"""The committed graph schema holds the built-in node types and the repository's plugins/ (actuator_drive.yaml uses soft_clip)."""


@pytest.fixture(scope="module")
def schemas():
    """The committed schema files (test_committed_schema_files_are_up_to_date: what `flowtex schema` generates)."""
    return {kind: _validator(json.loads((REPO / "docs" / "schema" / f"{name}.schema.json").read_text(encoding="utf-8")))
            for kind, name in COMMITTED.items()}


def _load(path: Path):
    return load_yaml(path.read_text(encoding="utf-8"), str(path))


def test_bundled_files_cover_every_kind():
    kinds = {file_kind(p) for p in BUNDLED}
    assert kinds == {GRAPH, SCENE, DEVICE_MAP}


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_every_bundled_file_passes_its_schema(schemas, path):
    errors = [e.message for e in schemas[file_kind(path)].iter_errors(_load(path))]
    assert errors == []


GOOD = {"flowtex": 1, "rate": 1000, "inputs": {"x": {"unit": "N"}},
        "nodes": {"lp": {"type": "butterworth", "params": {"kind": "lowpass", "order": 2, "cutoff_hz": 50}},
                  "g": {"type": "gain", "params": {"k": 2}}},
        "edges": ["x -> lp.x", "lp.y -> g.x"], "outputs": {"y": "g.y"}}


def _graph(change):
    doc = copy.deepcopy(GOOD)
    change(doc)
    return doc


@pytest.mark.parametrize("doc", [
    _graph(lambda d: d["nodes"]["lp"].update(type="buterworth")),              # unknown node type
    _graph(lambda d: d["nodes"]["lp"]["params"].update(ordr=2)),               # unknown parameter
    _graph(lambda d: d["nodes"]["lp"]["params"].update(order=0)),              # out of bounds (order >= 1)
    _graph(lambda d: d["nodes"]["lp"]["params"].update(kind="lowpas")),        # wrong choice
    _graph(lambda d: d["nodes"]["g"]["params"].pop("k")),                      # missing required parameter
    _graph(lambda d: d["edges"].append("lp.out -> g.x")),                      # no such port name anywhere
    _graph(lambda d: d.update(flowtex=True)),                                  # true is not version 1
    _graph(lambda d: d.update(rat=1000)),                                      # unknown top-level key
], ids=["type", "param", "bounds", "choice", "required", "port", "version", "key"])
def test_what_validate_refuses_the_schema_refuses(schemas, doc, write_graph):
    assert not schemas[GRAPH].is_valid(doc)
    from flowtex.errors import GraphError
    from flowtex.graph.compiled import check_graph

    with pytest.raises(GraphError):  # and validate refuses it too
        check_graph(write_graph(json.dumps(doc)))


def test_good_graph_passes_the_schema_and_validate(schemas, write_graph):
    from flowtex.graph.compiled import check_graph

    assert schemas[GRAPH].is_valid(GOOD)
    check_graph(write_graph(json.dumps(GOOD)))


def test_scene_and_map_errors_are_schema_errors(schemas):
    scene = _load(REPO / "graphs" / "scene_two_surfaces.yaml")
    bad = copy.deepcopy(scene)
    next(iter(bad["surfaces"].values()))["tapps"] = "x.json"
    assert not schemas[SCENE].is_valid(bad)
    bad = copy.deepcopy(scene)
    next(iter(bad["surfaces"].values()))["drop"] = ["texure"]
    assert not schemas[SCENE].is_valid(bad)
    amap = _load(REPO / "graphs" / "devices" / "example_audio_map.yaml")
    bad = copy.deepcopy(amap)
    bad["audio"]["rate"] = 4000  # below the 5 kHz floor
    assert not schemas[DEVICE_MAP].is_valid(bad)
    bad = copy.deepcopy(amap)
    next(iter(bad["outputs"].values())).pop("clamp")
    assert not schemas[DEVICE_MAP].is_valid(bad)


def test_parameter_facts_reach_the_schema():
    schema = graph_schema(load_registry().types)
    rule = next(r for r in schema["properties"]["nodes"]["additionalProperties"]["allOf"]
                if r["if"]["properties"]["type"]["const"] == "butterworth")
    params = rule["then"]["properties"]["params"]
    assert params["additionalProperties"] is False
    assert {"lowpass", "highpass"} <= set(params["properties"]["kind"]["enum"])
    assert params["properties"]["order"]["minimum"] == 1 and params["properties"]["order"]["type"] == "integer"
    assert "Hz" in params["properties"]["cutoff_hz"]["description"]


def test_plugin_node_types_are_in_the_schema_when_loaded(tmp_path, capsys):
    assert main(["schema", "graph"]) == 0
    assert "soft_clip" not in capsys.readouterr().out
    out = tmp_path / "g.schema.json"
    assert main(["schema", "graph", "--plugins", str(REPO / "plugins"), "-o", str(out)]) == 0
    assert out.read_text(encoding="utf-8") == (REPO / "docs" / "schema" / "graph.schema.json").read_text(encoding="utf-8")
    types = json.loads(out.read_text())["properties"]["nodes"]["additionalProperties"]["properties"]["type"]["enum"]
    assert "soft_clip" in types and "gain" in types


def test_nodes_json_gives_the_same_facts(capsys):
    assert main(["nodes", "--json"]) == 0
    facts = {n["type"]: n for n in json.loads(capsys.readouterr().out)}
    assert set(facts) == set(load_registry().types)
    order = facts["butterworth"]["params"]["order"]
    assert order["kind"] == "int" and order["min"] == 1 and order["required"]
    assert [p["name"] for p in facts["butterworth"]["outputs"]] == ["y"]


@pytest.mark.parametrize("kind", ["graph", "scene", "map"])
def test_committed_schema_files_are_up_to_date(kind):
    committed = (REPO / "docs" / "schema" / f"{kind}.schema.json").read_text(encoding="utf-8")
    assert committed == schema_text(kind, PLUGINS if kind == "graph" else ()), (
        f"docs/schema/{kind}.schema.json is stale: run 'python3 -m flowtex schema {kind} --plugins plugins "
        f"-o docs/schema/{kind}.schema.json'")


@pytest.mark.parametrize("path", BUNDLED, ids=lambda p: p.name)
def test_bundled_files_carry_the_schema_modeline(path):
    first = path.read_text(encoding="utf-8").splitlines()[0]
    kind = {GRAPH: "graph", SCENE: "scene", DEVICE_MAP: "map"}[file_kind(path)]
    prefix, target = first.split("$schema=")
    assert prefix == "# yaml-language-server: "
    assert (path.parent / target).resolve() == REPO / "docs" / "schema" / f"{kind}.schema.json"
