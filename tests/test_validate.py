"""`flowtex validate` and the checks behind it: one precise line per problem."""

from __future__ import annotations

import pytest

from flowtex.cli import main
from flowtex.errors import GraphError
from flowtex.graph.compiled import check_graph

GOOD = """
flowtex: 1
name: t
rate: 1000
inputs:
  x: {unit: N}
nodes:
  lp: {type: butterworth, params: {kind: lowpass, order: 2, cutoff_hz: 50}}
  g: {type: gain, params: {k: 2}}
edges:
  - x -> lp.x
  - lp.y -> g.x
outputs:
  y: g.y
"""


def problems(write_graph, text):
    path = write_graph(text)
    with pytest.raises(GraphError) as info:
        check_graph(path)
    return [str(d) for d in info.value.diagnostics], path


def test_good_graph_validates(write_graph, capsys):
    path = write_graph(GOOD)
    assert main(["validate", str(path)]) == 0
    assert "ok" in capsys.readouterr().out


@pytest.mark.parametrize("word", ["true", "False", "null"])
def test_a_node_named_like_a_yaml_boolean_says_to_quote_it(write_graph, word):
    """YAML reads an unquoted key true/false as a boolean (null as None): 'node name False is not valid: use letters,
    digits and _' named neither the word written nor the fix. (on/off/yes/no are names: tests/schema/test_yaml_booleans.py.)"""
    text = GOOD.replace("  g: {type", f"  {word}: {{type").replace("lp.y -> g.x", f"lp.y -> {word}.x").replace(
        "y: g.y", f"y: {word}.y")
    msgs, path = problems(write_graph, text)
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}:8:3: ") and "YAML reads an unquoted" in msgs[0], msgs
    assert "quote it (e.g. 'true': ...)" in msgs[0], msgs
    assert check_graph(write_graph(text.replace(f"  {word}: {{type", f"  '{word}': {{type")))


def test_yaml_syntax_error_has_line_and_column(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("  g: {type: gain, params: {k: 2}}", "  g: {type: gain, params: {k: 2}"))
    assert len(msgs) == 1
    assert msgs[0].startswith(f"{path}:")
    assert "YAML syntax error" in msgs[0]


def test_duplicate_key_is_an_error(write_graph):
    text = GOOD.replace("  g: {type: gain, params: {k: 2}}", "  g: {type: gain, params: {k: 2}}\n  g: {type: gain, params: {k: 3}}")
    msgs, path = problems(write_graph, text)
    assert msgs == [f"{path}:9:3: duplicate key 'g' (first defined at line 8); remove or rename one of them"]


def test_python_object_tags_are_refused(write_graph):
    text = GOOD.replace("name: t", "name: !!python/object/apply:os.system ['echo pwned']")
    msgs, path = problems(write_graph, text)
    assert msgs[0].startswith(f"{path}:2:7:")
    assert "not allowed" in msgs[0]


def test_unknown_node_type_suggests_close_names(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("type: butterworth", "type: buterworth"))
    assert msgs == [f"{path}:7:14: node 'lp': unknown node type 'buterworth' (did you mean 'butterworth'?); "
                    "run 'flowtex nodes' to list them (plugin nodes are found in the graph file's plugins/ "
                    "folder, the folders of its plugins: key, $FLOWTEX_PLUGINS and --plugins DIR)"]


def test_unknown_parameter_suggests(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("order: 2", "ordr: 2"))
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}:7:")
    assert "unknown parameter 'ordr' (did you mean 'order'?)" in msgs[0]


def test_missing_parameter(write_graph):
    msgs, _ = problems(write_graph, GOOD.replace("{k: 2}", "{}"))
    assert len(msgs) == 1 and "missing required parameter 'k'" in msgs[0]


@pytest.mark.parametrize("value, fragment", [
    ("'two'", "expected an integer"),
    ("2.5", "expected an integer"),
    ("0", "must be >= 1"),
    ("true", "expected an integer"),
])
def test_ill_typed_or_out_of_range_parameter(write_graph, value, fragment):
    msgs, path = problems(write_graph, GOOD.replace("order: 2", f"order: {value}"))
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}:7:") and fragment in msgs[0]


def test_cutoff_above_nyquist_points_at_the_parameter(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("cutoff_hz: 50", "cutoff_hz: 600"))
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}:7:")
    assert "Nyquist" in msgs[0]


def test_unknown_port_names_ports(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("lp.y -> g.x", "lp.out -> g.x"))
    assert msgs == [f"{path}:11:5: node 'lp' (butterworth) has no output 'out'; its outputs are: y"]


def test_unknown_input_port_suggests(write_graph):
    msgs, _ = problems(write_graph, GOOD.replace("x -> lp.x", "x -> lp.xx"))
    assert any("has no input 'xx' (did you mean 'x'?)" in m for m in msgs)


def test_unconnected_input(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("  - lp.y -> g.x\n", ""))
    assert msgs == [f"{path}:8:3: node 'g' (gain): input 'x' is not connected; add an edge '... -> g.x'"]


def test_input_connected_twice(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("  - lp.y -> g.x\n", "  - lp.y -> g.x\n  - x -> g.x\n"))
    assert msgs == [f"{path}:12:5: input g.x is connected twice (also at line 11); an input takes exactly one edge"]


def test_unit_mismatch(write_graph):
    text = GOOD.replace("x: {unit: N}", "x: {unit: N}\n  p: {shape: [3], unit: mm}").replace("x -> lp.x", "p -> lp.x")
    text = text.replace("  g: {type: gain, params: {k: 2}}", "  g: {type: gain, params: {k: 2}}\n  s: {type: add}")
    text = text.replace("  - lp.y -> g.x\n", "  - lp.y -> g.x\n  - x -> s.a\n  - p -> s.b\n")
    msgs, _ = problems(write_graph, text)
    assert any("shape mismatch: 3 arrives at input 'b', which takes scalar" in m for m in msgs)


def test_unit_mismatch_across_edge(write_graph):
    text = GOOD.replace("x: {unit: N}", "x: {unit: N}\n  v: {unit: mm}")
    text = text.replace("  g: {type: gain, params: {k: 2}}", "  g: {type: gain, params: {k: 2}}\n  s: {type: add}")
    text = text.replace("  - lp.y -> g.x\n", "  - lp.y -> g.x\n  - x -> s.a\n  - v -> s.b\n")
    text = text.replace("  y: g.y", "  y: g.y\n  s: s.y")
    msgs, _ = problems(write_graph, text)
    assert len(msgs) == 1
    assert "unit mismatch: 'mm' arrives at input 'b', which takes 'N'" in msgs[0]


def test_cycle_without_delay(write_graph):
    text = """
    flowtex: 1
    name: loop
    rate: 1000
    inputs: {x: {}}
    nodes:
      s: {type: add}
      g: {type: gain, params: {k: 0.5}}
    edges:
      - x -> s.a
      - g.y -> s.b
      - s.y -> g.x
    outputs: {y: s.y}
    """
    msgs, _ = problems(write_graph, text)
    assert len(msgs) == 1 and "does not pass through a delay node; insert a 'delay' node" in msgs[0]


def test_output_naming_unknown_node_or_port(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("  y: g.y", "  y: gg.y\n  z: g.yy"))
    assert f"{path}:13:6: no node 'gg' (did you mean 'g'?)" in msgs
    assert any(m.startswith(f"{path}:14:6:") and "has no output 'yy'" in m for m in msgs)


@pytest.mark.parametrize("every", ["0", "-2", "1.5", "'4'"])
def test_every_must_be_positive_integer(write_graph, every):
    msgs, path = problems(write_graph, GOOD.replace("g: {type: gain, params: {k: 2}}", f"g: {{type: gain, every: {every}, params: {{k: 2}}}}"))
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}:8:") and "every must be a positive integer" in msgs[0]


def test_several_problems_reported_together(write_graph):
    text = GOOD.replace("type: butterworth", "type: nope").replace("{k: 2}", "{k: two}")
    msgs, _ = problems(write_graph, text)
    assert len(msgs) == 2


def test_rate_must_be_positive(write_graph):
    msgs, path = problems(write_graph, GOOD.replace("rate: 1000", "rate: -5"))
    assert msgs[0].startswith(f"{path}:3:7:") and "rate must be a number of Hz in (0, 1e+06]" in msgs[0]


def test_non_integer_rate_is_fine(write_graph):
    path = write_graph(GOOD.replace("rate: 1000", "rate: 1234.5"))
    assert check_graph(path).spec.rate == 1234.5


def test_cli_prints_one_line_per_problem_and_no_traceback(write_graph, capsys):
    path = write_graph(GOOD.replace("type: butterworth", "type: nope").replace("{k: 2}", "{k: two}"))
    assert main(["validate", str(path)]) == 1
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 2 and all(line.startswith(f"{path}:") for line in lines)
    assert "Traceback" not in err


def test_missing_file_is_a_clean_error(tmp_path, capsys):
    assert main(["validate", str(tmp_path / "nope.yaml")]) == 1
    assert "graph file not found" in capsys.readouterr().err


def test_set_override_is_validated(write_graph, capsys):
    path = write_graph(GOOD)
    assert main(["validate", str(path), "--set", "lp.order=0"]) == 1
    assert "--set lp.order: node 'lp' (butterworth): parameter 'order' must be >= 1" in capsys.readouterr().err


def test_no_follow_on_errors_after_a_failed_node(write_graph):
    text = GOOD.replace("cutoff_hz: 50", "cutoff_hz: 900")
    msgs, _ = problems(write_graph, text)
    assert len(msgs) == 1 and "Nyquist" in msgs[0]


def test_dash_unit_on_an_input_means_dimensionless(write_graph):
    path = write_graph(GOOD.replace("x: {unit: N}", "x: {unit: '-'}"))
    assert check_graph(path).input_specs["x"].unit == ""


@pytest.mark.parametrize("suffix", [".blf", ".log", ".asc"])
def test_validate_reads_a_can_session_log_as_a_replay_does(tmp_path, capsys, suffix):
    """validate checks any flowtex file; a BLF was 'not a text file' and a .log/.asc 'a graph file must be a mapping'."""
    import can

    from flowtex.io.canlog import SessionWriter

    path = tmp_path / f"s{suffix}"
    w = SessionWriter(path)
    for i in range(6):
        w.write(can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100, data=bytes([i] * 8), is_extended_id=False), i < 4)
    w.close()
    assert main(["validate", str(path)]) == 0
    assert capsys.readouterr().out.strip() == f"{path}: ok (CAN session log, 6 frames, 4 received and 2 sent)"
    if suffix != ".blf":
        text = path.read_text().splitlines()
        number = next(i for i, line in enumerate(text) if " 100#" in line or " 100 " in line) + 1
        text[number - 1] = text[number - 1].replace(" 100#", " FFF#").replace(" 100 ", " FFF ")
        path.write_text("\n".join(text) + "\n")
        assert main(["validate", str(path)]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"{path}:{number}:") and "standard CAN ID FFF is above 7FF" in err[0], err
