"""Layers point down: every import inside flowtex goes to its own layer or a lower one (docs/engine.md, DESIGN.md).

The walk reads every module's source with ``ast`` (imports inside functions count too: a lazy import is still a
dependency) and checks it against :data:`LAYERS`. An upward import that is not fixed yet is listed in
:data:`ALLOWED` with the reason; an entry that no longer matches any import fails the test, so the list only
shrinks.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

from tests.conftest import REPO

PACKAGE = REPO / "flowtex"

LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("package", ("flowtex", "flowtex.__main__")),
    ("cli", ("flowtex.cli",)),
    # Not in DESIGN.md's list: what only the CLI and the tests use. Generators and oracles users want too
    # (datasets), the golden fixture (testing), the any-file checker behind `flowtex validate` (it reads scenes), and
    # the plugin author's tools (scaffold, plugin check and its kernel probe), and the editors' JSON Schemas made from the
    # file declarations and the node types' Param declarations (`flowtex schema`).
    ("tools", ("flowtex.datasets", "flowtex.testing", "flowtex.filecheck", "flowtex.scaffold", "flowtex.plugincheck",
               "flowtex.kernelprobe", "flowtex.schema.jsonschema")),
    ("scene, bench", ("flowtex.scene", "flowtex.bench")),
    ("fit", ("flowtex.fit",)),
    ("runtime", ("flowtex.runtime",)),
    ("io", ("flowtex.io", "flowtex.plotting")),  # plotting: a recording's figures, written through io.figures
    # The compile service, and the compiled Graph it produces (kept at its historical import path flowtex.graph.compiled,
    # which users and plugins import; pystep generates its step(); describe prints a compiled Graph; builder compiles a
    # graph built in Python, as load_graph does a file).
    ("compile", ("flowtex.compile", "flowtex.graph.compiled", "flowtex.graph.pystep", "flowtex.graph.describe",
                 "flowtex.graph.builder")),
    ("graph", ("flowtex.graph",)),
    ("nodes", ("flowtex.nodes",)),
    ("node API", ("flowtex.node_api", "flowtex.node_decl", "flowtex.node_params", "flowtex.node_processor", "flowtex.nodecheck",
                  "flowtex.registry")),
    # The declarative schema of every file kind (keys, kinds, bounds, units, docs) sits under graph, io and scene, which
    # declare their files with it, and under the node API, whose processor checks its graph settings (rate, seed,
    # every) against the graph file's declarations.
    ("schema", ("flowtex.schema",)),
    # The format registry is a table of names (suffix or content -> kind, "module:function" readers and writers, imported
    # only when used, as the node registry imports node modules), so it sits under the graph/io boundary that uses it:
    # flowtex.node_params reads a path parameter into its object with it, for the graph's resolver and Node.processor.
    ("format registry", ("flowtex.io.formats",)),
    ("models", ("flowtex.models",)),
    ("dsp", ("flowtex.dsp",)),
    # config, and what every layer uses: error classes, input limits, the YAML reader with positions, cache folders
    # (numba's cache folder must be chosen before any kernel module, dsp's included, decorates its kernels), the old import
    # paths of names that moved (flowtex.moved), values handed in from Python code (flowtex.pyvalues).
    ("config", ("flowtex.config", "flowtex.version", "flowtex.errors", "flowtex.limits", "flowtex.yamlsource", "flowtex.cache",
                "flowtex.plugincode", "flowtex.interrupts", "flowtex.moved", "flowtex.pyvalues")),
]
"""Top to bottom. A module belongs to the layer of its longest matching prefix."""

ALLOWED: dict[tuple[str, str], str] = {}
"""(importer, imported module) -> why this upward import stays for now."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def layer_of(module: str) -> int:
    best, rank = -1, -1
    for k, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best:
                best, rank = len(prefix), k
    assert rank >= 0, f"{module} is in no layer: add it to LAYERS"
    return rank


def imports_of(path: Path, module: str) -> set[str]:
    """flowtex modules ``module`` (at ``path``) imports, absolute, with ``from X import name`` resolved to X.name
    when X.name is a module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] == "flowtex")
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "flowtex":
                continue
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                found.add(sub if _is_module(sub) else target)
    return found


def _is_module(name: str) -> bool:
    rel = Path(*name.split("."))
    return (REPO / rel).with_suffix(".py").is_file() or (REPO / rel / "__init__.py").is_file()


@functools.lru_cache(maxsize=1)  # two tests walk the same files: parse them once per worker
def _import_edges() -> tuple[tuple[tuple[str, str], tuple[int, int]], ...]:
    edges = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        module = module_name(path)
        for target in imports_of(path, module):
            edges[(module, target)] = (layer_of(module), layer_of(target))
    return tuple(edges.items())


def all_imports() -> dict[tuple[str, str], tuple[int, int]]:
    """(importing module, imported module) -> (their layers), for every flowtex module's flowtex imports."""
    return dict(_import_edges())


def test_every_module_has_a_layer_and_imports_point_down():
    upward = {edge: f"{LAYERS[a][0]} -> {LAYERS[b][0]}" for edge, (a, b) in all_imports().items() if b < a}
    unexplained = {f"{src} -> {dst}": what for (src, dst), what in upward.items() if (src, dst) not in ALLOWED}
    assert unexplained == {}
    stale = [edge for edge in ALLOWED if edge not in upward]
    assert stale == [], "these allowed upward imports are gone: remove them from ALLOWED"


def test_no_import_circle_between_modules():
    import networkx as nx

    g = nx.DiGraph([edge for edge in all_imports() if edge[0] != edge[1]])
    for name in list(g):  # a package's __init__ importing its own submodules is not a circle between modules
        for succ in list(g.successors(name)):
            if succ.startswith(name + "."):
                g.remove_edge(name, succ)
    cycles = sorted(sorted(c) for c in nx.simple_cycles(g))
    assert cycles == []


def test_the_walk_sees_upward_imports():
    # the checker itself: a relative import two levels up, inside a function, is found and ranked
    src = PACKAGE / "dsp" / "filters.py"
    assert layer_of("flowtex.dsp.filters") > layer_of("flowtex.graph.spec") > layer_of("flowtex.graph.compiled")
    assert "flowtex.dsp.fastmath" in imports_of(src, "flowtex.dsp.filters")
