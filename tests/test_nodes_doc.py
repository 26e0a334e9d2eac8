"""`flowtex nodes` tells the truth: units that depend on inputs, model-dependent shapes, citations (issue 9 item 7)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from flowtex.cli import main
from flowtex.graph.compiled import check_graph
from flowtex.node_api import simplify_unit, unit_product
from flowtex.registry import load_registry

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(("unit", "simple"), [
    ("mm/s*mm/s", "mm^2/s^2"), ("m/s/s", "m/s^2"), ("mm/s*N", "mm*N/s"), ("m/s^2", "m/s^2"), ("s/s", ""),
    ("1/s", "1/s"), ("mm*mm*mm", "mm^3"), ("m^2/m", "m"), ("N/mm/s", "N/mm/s"), ("mm/s*1/s", "mm/s^2"),
    ("", ""), ("(m/s)^2", "(m/s)^2"),  # parentheses are outside the grammar: unchanged
])
def test_simplify_unit(unit, simple):
    assert simplify_unit(unit) == simple


def test_unit_product_simplifies():
    assert unit_product("mm/s", "mm/s") == "mm^2/s^2"
    assert unit_product("", "N") == "N" and unit_product("N", "") == "N" and unit_product("", "") == ""
    assert unit_product("1/s", "s") == ""


@pytest.mark.parametrize(("node", "expected"), [
    ("differentiator", "unit of x per second"),
    ("multiply", "unit of a * unit of b"),
    ("dot", "unit of a * unit of b"),
    ("cross", "unit of a * unit of b"),
    ("texture_lookup", "vector of p+1 (AR order p of the model file)"),
])
def test_nodes_shows_input_dependent_units_and_shapes(node, expected, capsys):
    assert main(["nodes", node]) == 0
    out = capsys.readouterr().out
    assert expected in out
    outputs = out.split("  outputs:")[1].split("  params:")[0]
    if node != "texture_lookup":
        assert "dimensionless" not in outputs


def test_resolved_units_are_simplified(write_graph):
    path = write_graph("""
    flowtex: 1
    name: u
    rate: 1000
    inputs:
      v: {unit: mm/s}
      p: {shape: [3], unit: m}
    nodes:
      d: {type: differentiator}
      sq: {type: multiply}
      dd: {type: differentiator}
      acc: {type: differentiator}
    edges: [v -> d.x, v -> sq.a, v -> sq.b, p -> dd.x, dd.y -> acc.x]
    outputs: {a: d.y, s: sq.y, acc: acc.y}
    """)
    rg = check_graph(path)
    assert rg.output_specs["a"].unit == "mm/s^2"
    assert rg.output_specs["s"].unit == "mm^2/s^2"
    assert rg.output_specs["acc"].unit == "m/s^2" and rg.output_specs["acc"].shape == (3,)


# ALGORITHMS.md and the seed numbers 000-004 are not in the repository: "(000, 002)", "001 §4.1", "000/001", "002:".
CITATION = re.compile(r"ALGORITHMS|§|\bseeds? 00[0-4]|(?<![\w.,])00[0-4](?=[ )/;:,'’])")


def test_docs_cite_papers_not_internal_files():
    reg = load_registry()
    for name in reg.names():
        cls = reg.types[name]
        texts = [cls.__doc__ or ""] + [p.doc for p in cls.params.values()] + [p.doc for p in {**cls.inputs, **cls.outputs}.values()]
        for text in texts:
            assert not CITATION.search(text), f"{name}: {text!r}"
    for path in list((REPO / "flowtex").rglob("*.py")) + list((REPO / "docs").glob("*.md")):
        for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            assert not CITATION.search(line), f"{path}:{k}: {line}"


SECTION_REFERENCE = re.compile(r"(docs/[a-z0-9-]+\.md),?\s+(?:section\s+)?[\"“']([^\"”'`]{3,80})[\"”']")
"""A reference to a section of a doc file: ``docs/texture.md, "How a set renders"``."""


def test_every_named_doc_section_exists():
    """A file that sends the reader to a section of docs/ names one that is there: a heading, or a paragraph that opens
    with those words (bold or not). graphs/speed_force_texture.yaml sent its users to a section "Speed and force only"
    that docs/texture.md never had."""
    sources = [*(REPO / "docs").glob("*.md"), REPO / "README.md", *(REPO / "graphs").glob("*.yaml"),
               *(REPO / "flowtex").rglob("*.py"), *(REPO / "benchmarks").glob("*.py"), *(REPO / "tests").rglob("*.py")]
    openings: dict[str, list[str]] = {}
    missing = []
    for src in sources:
        for m in SECTION_REFERENCE.finditer(src.read_text(encoding="utf-8")):
            doc, section = m.group(1), " ".join(m.group(2).split())
            if doc not in openings:
                path = REPO / doc
                openings[doc] = ([" ".join(line.lstrip("#*- ").split()) for line in path.read_text(encoding="utf-8").splitlines()]
                                 if path.exists() else [])
            if not any(line.startswith(section) for line in openings[doc]):
                missing.append(f"{src.relative_to(REPO)}: {doc}, {section!r}")
    assert not missing, "sections named but not in the doc:\n" + "\n".join(missing)
