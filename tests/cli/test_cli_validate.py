"""``flowtex validate FILE`` reads any flowtex file by its content (issue 17); every bundled file passes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.filecheck import COMPLIANCE, DEVICE_MAP, FRICTION, GRAPH, MODEL_SET, PATTERN, SCENE, TAP_LIBRARY, file_kind
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import save_model_set
from tests.conftest import REPO

DBC = REPO / "graphs" / "devices" / "example.dbc"


def _ok(capsys, *argv) -> str:
    code = main(["validate", *map(str, argv), "--no-plugins"])
    out = capsys.readouterr()
    assert code == 0, out.err
    return out.out.strip()


@pytest.mark.parametrize("path", sorted((REPO / "graphs").rglob("*.yaml")), ids=lambda p: p.name)
def test_every_bundled_yaml_passes_validate(path, capsys):
    line = _ok(capsys, path, "--dbc", DBC, "--plugins", REPO / "plugins")  # actuator_drive.yaml uses plugins/soft_clip.py
    assert line.startswith(f"{path}: ok (")


def test_the_kind_is_read_from_the_content_not_the_name(tmp_path):
    ms = synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2)
    save_model_set(ms, tmp_path / "set.dat")
    write_hatt_xml(ms, tmp_path / "set.txt")
    (tmp_path / "map.yml").write_text((REPO / "graphs" / "devices" / "example_map.yaml").read_text())
    (tmp_path / "scene.txt").write_text((REPO / "graphs" / "scene_two_surfaces.yaml").read_text())
    (tmp_path / "graph.txt").write_text((REPO / "graphs" / "accel_preprocess.yaml").read_text())
    (tmp_path / "p.x").write_text((REPO / "graphs" / "data" / "synthetic_pattern.json").read_text())
    (tmp_path / "t.x").write_text((REPO / "graphs" / "data" / "synthetic_taps.json").read_text())
    (tmp_path / "f.x").write_text(json.dumps({"format": "flowtex-friction", "version": 1, "mu": 0.4, "mu_ci": [0.39, 0.41]}))
    (tmp_path / "c.x").write_text(json.dumps({"format": "flowtex-compliance", "version": 1, "k_c": 0.7, "valid": True}))
    kinds = {name: file_kind(tmp_path / name) for name in ("set.dat", "set.txt", "map.yml", "scene.txt", "graph.txt", "p.x", "t.x",
                                                          "f.x", "c.x")}
    assert kinds == {"set.dat": MODEL_SET, "set.txt": MODEL_SET, "map.yml": DEVICE_MAP, "scene.txt": SCENE, "graph.txt": GRAPH,
                     "p.x": PATTERN, "t.x": TAP_LIBRARY, "f.x": FRICTION, "c.x": COMPLIANCE}


def test_each_kind_is_checked_by_its_reader(tmp_path, capsys):
    ms = synthetic_model_set([60.0, 120.0], [0.5, 1.5], ar_order=4, ma_order=2)
    save_model_set(ms, tmp_path / "set.json")
    write_hatt_xml(ms, tmp_path / "set.xml")
    assert _ok(capsys, tmp_path / "set.json") == f"{tmp_path / 'set.json'}: ok (texture model set, {ms.num_models} models at " \
                                                 f"{ms.sample_rate:g} Hz, orders 4/2)"
    assert "texture model set" in _ok(capsys, tmp_path / "set.xml")
    assert "pattern, 60 features" in _ok(capsys, REPO / "graphs" / "data" / "synthetic_pattern.json")
    assert "tap library, 4 taps" in _ok(capsys, REPO / "graphs" / "data" / "synthetic_taps.json")
    (tmp_path / "mu.json").write_text(json.dumps({"format": "flowtex-friction", "version": 1, "mu": 0.4, "mu_ci": [0.39, 0.41]}))
    assert _ok(capsys, tmp_path / "mu.json").endswith("ok (friction estimate, mu 0.4)")
    (tmp_path / "kc.json").write_text(json.dumps({"format": "flowtex-compliance", "version": 1, "k_c": None, "valid": False,
                                                  "reason": "smooth surface"}))
    assert _ok(capsys, tmp_path / "kc.json").endswith("ok (compliance estimate, not valid: smooth surface)")
    assert "DBC, 6 messages" in _ok(capsys, DBC)
    np.savez(tmp_path / "r.npz", x=np.zeros(10), rate=np.float64(500.0))
    assert _ok(capsys, tmp_path / "r.npz").endswith("ok (recording, 1 signals, 10 samples at 500 Hz)")


@pytest.mark.parametrize("name, text, message", [
    ("mu.json", {"format": "flowtex-friction", "version": 1, "mu": -0.4, "mu_ci": [0, 1]}, "key 'mu' must be a number from 0 to inf"),
    ("mu.json", {"format": "flowtex-friction", "version": 1, "mu": 0.4}, "key 'mu_ci' must be [low, high]"),
    ("kc.json", {"format": "flowtex-compliance", "version": 1, "k_c": 1.5, "valid": True}, "key 'k_c' must be a number from 0 to 1"),
    ("x.json", {"format": "something-else"}, "key 'format' is 'something-else', not a flowtex file format"),
    ("x.json", [1, 2], "holds an array, not a JSON object with a 'format' key"),
    # a compare --json report: the key is missing, not None as it said
    ("cv.json", {"lsd_db": 1.2, "gfc": 0.99}, "no 'format' key: not a file flowtex reads"),
])
def test_broken_files_get_one_line(tmp_path, capsys, name, text, message):
    (tmp_path / name).write_text(json.dumps(text))
    assert main(["validate", str(tmp_path / name)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{tmp_path / name}: ") and message in err[0], err


def test_a_map_needs_its_dbc_and_set_needs_a_graph(capsys):
    assert main(["validate", str(REPO / "graphs" / "devices" / "example_map.yaml")]) == 1
    assert "give --dbc DEVICE.dbc" in capsys.readouterr().err
    assert main(["validate", str(DBC), "--set", "a.b=1"]) == 1
    assert "--set applies to graphs only" in capsys.readouterr().err


@pytest.mark.parametrize("name, text, where, message", [
    ("cut.json", '\n\n{"format": "flowtex-friction",\n "mu": 0.3 "mu_ci"}\n', ":4:12: ", "not valid JSON (Expecting ',' delimiter)"),
    ("empty.json", "", ":1:1: ", "not valid JSON (Expecting value)"),
    ("cut.yaml", "\n\n\nflowtex: 1\nname: x\nnodes: {a: [\n", ":7:1: ", "YAML syntax error"),
])
def test_broken_json_and_yaml_name_the_files_own_line(tmp_path, capsys, name, text, where, message):
    """validate points at the line and column in the file, as run and every reader do, blank lines before it included."""
    (tmp_path / name).write_text(text)
    assert main(["validate", str(tmp_path / name)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"{tmp_path / name}{where}") and message in err[0], err
