"""Graph files: YAML text -> :class:`GraphSpec` with a source location for everything.

This module checks the *shape* of the file (keys, types, edge syntax). Checks
that need node types (parameters, ports, units) live in ``wiring.py`` and ``ports.py``, run by ``resolve.py``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import Diagnostic, GraphError, Location
from ..limits import excerpt, port_values_problem
from ..node_api import suggest
from ..pyvalues import plain
from ..schema.core import INVALID, Collector, check_keys, check_value, fits, value_of
from ..schema.graph import EDGE_PATTERN, FORMAT_VERSION, GRAPH, INPUT, NAME_PATTERN, NODE, RATE
from ..yamlsource import LocDict, LocList, load_yaml, parse_value, read_source

__all__ = ["FORMAT_VERSION", "Collector", "GraphSpec", "load_spec", "parse_spec", "parse_override", "spec_from_data"]

NAME_RE = re.compile(NAME_PATTERN)
EDGE_RE = re.compile(EDGE_PATTERN)
TOP_KEYS = tuple(GRAPH.keys)


@dataclass
class InputSpec:
    name: str
    shape: tuple[int, ...]
    unit: str
    loc: Location


@dataclass
class NodeSpec:
    name: str
    type: str
    params: dict[str, Any]
    param_locs: dict[str, Location]
    every: int
    loc: Location
    type_loc: Location
    params_loc: Location
    command_line: set[str] = field(default_factory=set)
    """Parameters given by ``--set``: a relative path among them is read from the current folder, as every path given
    on the command line is (the file's own paths are read from its folder)."""


@dataclass
class Endpoint:
    node: str | None
    """Node name, or None for a graph input."""
    port: str


@dataclass
class EdgeSpec:
    src: Endpoint
    dst: Endpoint
    loc: Location
    text: str


@dataclass
class OutputSpec:
    name: str
    src: Endpoint
    loc: Location


@dataclass
class GraphSpec:
    path: Path
    name: str
    rate: float
    seed: int
    inputs: dict[str, InputSpec] = field(default_factory=dict)
    nodes: dict[str, NodeSpec] = field(default_factory=dict)
    edges: list[EdgeSpec] = field(default_factory=list)
    outputs: dict[str, OutputSpec] = field(default_factory=dict)
    description: str = ""
    plugins: list[Path] = field(default_factory=list)
    """Folders of plugin node files named by the top-level ``plugins:`` key, resolved against the graph file's folder."""


def load_spec(path: str | Path, overrides: dict[str, Any] | None = None) -> GraphSpec:
    """Read and shape-check a graph file. Raises :class:`GraphError`."""
    if not isinstance(path, (str, os.PathLike)):
        raise GraphError([Diagnostic(Location(repr(path)), f"a graph file is named by a path (str or pathlib.Path), got "
                                                           f"{type(path).__name__} {excerpt(path)}")])
    path = Path(path)
    return parse_spec(read_source(path, "graph file"), path, overrides)


def parse_spec(text: str, path: Path, overrides: dict[str, Any] | None = None) -> GraphSpec:
    """Check ``text`` (graph file ``path``) against :data:`flowtex.schema.graph.GRAPH`; every problem in one GraphError."""
    data = load_yaml(text, str(path))
    if not isinstance(data, LocDict):
        message = "a graph file must be a mapping with keys flowtex, name, rate, nodes, edges, outputs"
        raise GraphError([Diagnostic(Location(str(path), 1, 1), message)])
    return spec_from_data(data, path, overrides)


def spec_from_data(data: LocDict, path: Path, overrides: dict[str, Any] | None = None) -> GraphSpec:
    """The checks of :func:`parse_spec` on an already-read mapping: from YAML (positions are (line, column)) or from
    :class:`flowtex.graph.builder.GraphBuilder` (positions are Locations naming the builder call)."""
    c = Collector(str(path))
    check_keys(c, data, GRAPH)
    value_of(c, data, GRAPH, "flowtex")
    name = value_of(c, data, GRAPH, "name")
    if name is INVALID or "name" not in data:
        name = path.stem
    rate = value_of(c, data, GRAPH, "rate")
    seed = value_of(c, data, GRAPH, "seed")
    spec = GraphSpec(path=path, name=name, rate=1000.0 if rate is INVALID else float(rate), seed=0 if seed is INVALID else seed,
                     description=str(data.get("description", "")))
    plugins = value_of(c, data, GRAPH, "plugins")
    if "plugins" in data and plugins is not INVALID:
        spec.plugins = existing_plugin_folders(c, data, path)
    spec.inputs = _inputs(c, data)
    spec.nodes = _nodes(c, data, spec.inputs)
    if overrides:
        _apply_overrides(c, spec, overrides)
    spec.edges = _edges(c, data)
    spec.outputs = _outputs(c, data)
    c.raise_if_any()
    return spec


def existing_plugin_folders(c: Collector, data: LocDict, path: Path) -> list[Path]:
    """The folders of the ``plugins:`` key (its type checked by the schema) resolved against the graph file's folder;
    a folder that does not exist is an error at its line."""
    raw = data["plugins"]
    folders = []
    for item, pos in zip(raw, raw.item_pos, strict=False):
        folder = Path(item).expanduser()
        folder = folder if folder.is_absolute() else path.parent / folder
        if folder.is_dir():
            folders.append(folder)
        else:
            c.error(pos, f"plugins: folder {item!r} does not exist (looked for {folder}); folders are relative to the graph file")
    return folders


def read_plugin_folders(path: str | Path) -> list[Path]:
    """Only the ``plugins:`` key of the graph file at ``path``, checked as :func:`load_spec` checks it."""
    path = Path(path)
    data = load_yaml(read_source(path, "graph file"), str(path))
    if not isinstance(data, LocDict) or "plugins" not in data:
        return []
    c = Collector(str(path))
    plugins = value_of(c, data, GRAPH, "plugins")
    folders = [] if plugins is INVALID else existing_plugin_folders(c, data, path)
    c.raise_if_any()
    return folders


def _check_name(c: Collector, name: Any, pos: tuple[int, int], what: str) -> bool:
    if isinstance(name, bool) or name is None:  # an unquoted true/false, or null/~ (on/off/yes/no are names: yamlsource)
        c.error(pos, f"{what} name {excerpt(name)} is not valid: YAML reads an unquoted true, false as a boolean (and "
                     "null, ~ as nothing); quote it (e.g. 'true': ...) or choose another name")
        return False
    if not isinstance(name, str) or not NAME_RE.match(name):
        c.error(pos, f"{what} name {excerpt(name)} is not valid: use letters, digits and '_', not starting with a digit")
        return False
    return True


def _inputs(c: Collector, data: LocDict) -> dict[str, InputSpec]:
    raw = data.get("inputs")
    if raw is None:
        return {}
    if not isinstance(raw, LocDict):
        value_of(c, data, GRAPH, "inputs")
        return {}
    out: dict[str, InputSpec] = {}
    for name, value in raw.items():
        if not _check_name(c, name, raw.key_pos[name], "input"):
            continue
        if value is None:
            value = LocDict()
        if not isinstance(value, LocDict):
            c.error(raw.value_pos[name], f"input {name!r}: expected a mapping like {{shape: [3], unit: mm}} or nothing")
            continue
        check_keys(c, value, INPUT, what=name)
        shape = value_of(c, value, INPUT, "shape", name=name)
        unit = value_of(c, value, INPUT, "unit", name=name)
        shape = () if shape is INVALID else (shape,) if isinstance(shape, int) else tuple(shape)
        if (problem := port_values_problem(shape)) is not None:  # before anything allocates the port's buffers
            c.error(value.value_pos.get("shape"), f"input {name!r}: {problem}")
            shape = ()
        unit = "" if unit in (INVALID, "-") else unit  # '-' means dimensionless, as in node params
        out[name] = InputSpec(name, shape, unit, c.loc(raw.key_pos[name]))
    return out


def _nodes(c: Collector, data: LocDict, inputs: dict[str, InputSpec]) -> dict[str, NodeSpec]:
    raw = data.get("nodes")
    if raw is None:
        return {}
    if not isinstance(raw, LocDict):
        value_of(c, data, GRAPH, "nodes")
        return {}
    out: dict[str, NodeSpec] = {}
    for name, value in raw.items():
        pos = raw.key_pos[name]
        if not _check_name(c, name, pos, "node"):
            continue
        if name in inputs:
            c.error(pos, f"node {name!r} has the same name as a graph input; rename one of them")
        if not isinstance(value, LocDict):
            c.error(raw.value_pos[name], f"node {name!r}: expected a mapping with at least 'type'")
            continue
        if not check_keys(c, value, NODE, pos=pos, what=name) and "type" not in value:
            continue
        if not fits(value["type"], NODE.keys["type"]):
            c.error(value.value_pos["type"], NODE.missing.format(what=name))
            continue
        params = value.get("params")
        if params is None:
            params = LocDict()
            params.pos = value.value_pos.get("params", pos)
        if not isinstance(params, LocDict):
            check_value(c, params, value.value_pos.get("params"), NODE.keys["params"], name=name)
            continue
        every = value_of(c, value, NODE, "every", name=name)
        out[name] = NodeSpec(
            name=name,
            type=value["type"],
            params=dict(params),
            param_locs={k: c.loc(params.key_pos[k]) for k in params},
            every=1 if every is INVALID else every,
            loc=c.loc(pos),
            type_loc=c.loc(value.value_pos["type"]),
            params_loc=c.loc(value.key_pos.get("params", pos)),
        )
    return out


def _apply_overrides(c: Collector, spec: GraphSpec, overrides: dict[str, Any]) -> None:
    """Apply ``--set`` values: ``rate`` (the graph's base rate, Hz), ``NODE.every`` (the node's rate divider) or
    ``NODE.PARAM``; ``NODE.PARAM=null`` removes the file's value, so that a parameter that excludes another
    (coulomb_friction's ``models`` and ``mu``) can be swapped from the command line."""
    if not isinstance(overrides, Mapping):
        c.error(Location("--set"), f"overrides must be a mapping of 'NODE.PARAM' or 'rate' to a value, got {excerpt(overrides)}")
        return
    for key, value in overrides.items():
        where = Location(f"--set {key}")
        value = plain(value)  # numpy scalars and arrays, paths from Python code: as the command line's values
        if not isinstance(key, str):
            c.error(where, f"an override's key is 'NODE.PARAM' or 'rate', got {excerpt(key)}")
            continue
        if key == "rate":
            if check_value(c, value, where, RATE) is not INVALID:
                spec.rate = float(value)
            continue
        node, _, param = key.partition(".")
        if not param:
            c.error(where, "expected --set NODE.PARAM=VALUE or --set rate=HZ")
            continue
        if node not in spec.nodes:
            hint = suggest(node, list(spec.nodes))
            having = [name for name, ns in spec.nodes.items() if param in ns.params]
            if not hint and having:
                hint = " (did you mean " + " or ".join(f"'{n}.{param}'" for n in having) + "?)"
            c.error(where, f"no node {node!r} in the graph{hint}; nodes are: {', '.join(spec.nodes) or 'none'}")
            continue
        if param == "every":  # the node's rate divider, a node key beside params (as bench's knob NODE.every)
            every = check_value(c, 1 if value is None else value, where, NODE.keys["every"], name=node)
            if every is not INVALID:
                spec.nodes[node].every = every
            continue
        if value is None:  # --set NODE.PARAM=null: as if the file did not give it (its default applies)
            spec.nodes[node].params.pop(param, None)
            spec.nodes[node].param_locs.pop(param, None)
            spec.nodes[node].command_line.discard(param)
            continue
        spec.nodes[node].params[param] = value
        spec.nodes[node].param_locs[param] = where
        spec.nodes[node].command_line.add(param)


def parse_override(text: str, option: str = "--set") -> tuple[str, Any]:
    """``"lookup.models=x.xml"`` -> ``("lookup.models", "x.xml")`` (value read as YAML); ``"rate=2000"`` -> ``("rate", 2000)``.

    ``option`` names the command-line option the text came from in an error (``bench --reference`` takes the same form).
    """
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise GraphError([Diagnostic(Location(f"{option} {text}"), f"expected {option} NODE.PARAM=VALUE or {option} rate=HZ")])
    return key.strip(), parse_value(value, f"{option} {key.strip()}")


def _endpoint(c: Collector, text: str, pos: tuple[int, int], side: str) -> Endpoint | None:
    node, dot, port = text.partition(".")
    if not dot:
        if side == "consumer":
            c.error(pos, f"edge target {excerpt(text)} must name a node input as node.port")
            return None
        return Endpoint(None, text)
    if not node or not port or "." in port:
        c.error(pos, f"{excerpt(text)} is not node.port")
        return None
    return Endpoint(node, port)


def _edges(c: Collector, data: LocDict) -> list[EdgeSpec]:
    raw = data.get("edges")
    if raw is None:
        return []
    if not isinstance(raw, LocList):
        value_of(c, data, GRAPH, "edges")
        return []
    out: list[EdgeSpec] = []
    for item, pos in zip(raw, raw.item_pos, strict=False):
        if check_value(c, item, pos, GRAPH.keys["edges"].items) is INVALID:
            continue
        m = EDGE_RE.match(item)
        if not m:
            c.error(pos, f'cannot read edge {excerpt(item)}: write "producer.port -> consumer.port" (a graph input by its bare name)')
            continue
        src = _endpoint(c, m.group("src"), pos, "producer")
        dst = _endpoint(c, m.group("dst"), pos, "consumer")
        if src is not None and dst is not None:
            out.append(EdgeSpec(src, dst, c.loc(pos), item))
    return out


def _outputs(c: Collector, data: LocDict) -> dict[str, OutputSpec]:
    raw = data.get("outputs")
    if raw is None:
        return {}
    if not isinstance(raw, LocDict) or not raw:
        c.error(data.value_pos.get("outputs"), GRAPH.keys["outputs"].message)
        return {}
    out: dict[str, OutputSpec] = {}
    for name, value in raw.items():
        pos = raw.value_pos[name]
        if not _check_name(c, name, raw.key_pos[name], "output"):
            continue
        if not isinstance(value, str):
            c.error(pos, f"output {name!r}: expected node.port, got {excerpt(value)}")
            continue
        src = _endpoint(c, value.strip(), pos, "producer")
        if src is not None:
            out[name] = OutputSpec(name, src, c.loc(pos))
    return out
