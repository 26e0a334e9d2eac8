"""Booleans as YAML 1.2 writes them: only true/false. PyYAML's YAML 1.1 rules read on/off/yes/no as booleans too, so a
node named ``on`` or a choice value ``no`` became True/False; they are the words now (every flowtex YAML file is read by
flowtex.yamlsource.load_yaml). Where a bool is expected, the 1.1 spellings still mean true/false, so old files work."""

from __future__ import annotations

import pytest

from flowtex.errors import GraphError
from flowtex.graph.compiled import check_graph
from flowtex.graph.spec import parse_override
from flowtex.node_decl import Param
from flowtex.schema.core import INVALID, Collector, Field, check_value
from flowtex.yamlsource import load_yaml

YAML11_WORDS = ["on", "On", "ON", "off", "Off", "OFF", "yes", "Yes", "YES", "no", "No", "NO"]


@pytest.mark.parametrize("word", [*YAML11_WORDS, "y", "n", "Y", "N", "yEs", "oN"])
def test_yaml11_boolean_words_are_strings_as_values_keys_and_items(word):
    doc = load_yaml(f"v: {word}\n{word}: 1\nl: [{word}]\n", "t.yaml")
    assert doc["v"] == word and doc[word] == 1 and doc["l"] == [word]
    assert doc.key_pos[word] == (2, 1) and doc.value_pos["v"] == (1, 4)  # positions as before


@pytest.mark.parametrize("word, value", [("true", True), ("True", True), ("TRUE", True), ("false", False), ("False", False),
                                         ("FALSE", False), ("!!bool yes", True)])
def test_true_and_false_stay_booleans(word, value):
    got = load_yaml(f"v: {word}", "t.yaml")["v"]
    assert got is value


GRAPH = """flowtex: 1
name: t
rate: 1000
nodes:
  {name}: {{type: constant, params: {{value: [2.5], vector: {vector}}}}}
outputs:
  y: {name}.y
"""


@pytest.mark.parametrize("name", ["on", "off", "yes", "no", "ON"])
def test_a_node_named_like_a_yaml11_boolean_needs_no_quotes(write_graph, name):
    rg = check_graph(write_graph(GRAPH.format(name=name, vector="false")))
    assert list(rg.nodes) == [name]


@pytest.mark.parametrize("spelling, shape", [("yes", (1,)), ("on", (1,)), ("YES", (1,)), ("true", (1,)),
                                             ("no", ()), ("off", ()), ("Off", ()), ("false", ())])
def test_a_bool_parameter_takes_the_yaml11_spellings(write_graph, spelling, shape):
    """constant's ``vector``: a one-element value is a 1-vector when true, a scalar when false."""
    rg = check_graph(write_graph(GRAPH.format(name="c", vector=spelling)))
    assert rg.output_specs["y"].shape == shape and rg.nodes["c"].params["vector"] is (shape == (1,))


def test_a_bool_parameter_set_on_the_command_line_with_a_yaml11_spelling(write_graph):
    key, value = parse_override("c.vector=on")
    assert (key, value) == ("c.vector", "on")
    assert check_graph(write_graph(GRAPH.format(name="c", vector="false")), {key: value}).output_specs["y"].shape == (1,)


@pytest.mark.parametrize("spelling", ["maybe", "y", "1", "'yes '"])
def test_other_words_for_a_bool_are_refused_at_their_line(write_graph, spelling):
    path = write_graph(GRAPH.format(name="c", vector=spelling))
    with pytest.raises(GraphError) as e:
        check_graph(path)
    msgs = [str(d) for d in e.value.diagnostics]
    assert len(msgs) == 1 and msgs[0].startswith(f"{path}:5:") and "vector" in msgs[0] and "true or false" in msgs[0], msgs


def test_a_choice_value_no_is_the_word_no():
    """A choice whose values are words YAML 1.1 reads as booleans (a plugin's ``mode: on|off|auto``) takes them as written,
    and a wrong choice is named as written (``got 'no'``, not ``got false``) at its line."""
    mode = Param("choice", default="auto", choices=("on", "off", "auto"))
    doc = load_yaml("mode: off\nkind: no\n", "t.yaml")
    assert mode.coerce(doc["mode"]) == "off"
    c = Collector("t.yaml")
    assert check_value(c, doc["kind"], doc.value_pos["kind"], Field("choice", choices=("lowpass", "highpass")), key="kind") is INVALID
    assert [str(d) for d in c.diagnostics] == ["t.yaml:2:7: kind: expected one of lowpass, highpass, got 'no'"]


def test_a_bool_field_of_a_file_schema_takes_yaml11_spellings_and_lists_of_them():
    c = Collector("t.yaml")
    doc = load_yaml("a: off\nb: [yes, No, true]\n", "t.yaml")
    assert check_value(c, doc["a"], doc.value_pos["a"], Field("bool"), key="a") is False
    assert check_value(c, doc["b"], doc.value_pos["b"], Field("list", items=Field("bool")), key="b") == [True, False, True]
    assert not c.diagnostics
