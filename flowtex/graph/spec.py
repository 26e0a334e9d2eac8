"""Graph files: YAML text -> :class:`GraphSpec` with a source location for everything.

This module checks the *shape* of the file (keys, types, edge syntax). Checks
that need node types (parameters, ports, units) live in ``resolve.py``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import Diagnostic, GraphError, Location
from ..limits import MAX_EVERY, MAX_RATE_HZ, excerpt, port_values_problem
from ..node_api import suggest
from ..yamlsource import LocDict, LocList, load_yaml, parse_value, read_source

FORMAT_VERSION = 1
TOP_KEYS = ("flowtex", "name", "rate", "seed", "inputs", "nodes", "edges", "outputs", "description")
NODE_KEYS = ("type", "params", "every", "doc")
INPUT_KEYS = ("shape", "unit", "doc")
NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
EDGE_RE = re.compile(r"^\s*(?P<src>[^\s>-][^\s]*)\s*->\s*(?P<dst>[^\s]+)\s*$")


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


class Collector:
    """Gathers :class:`Diagnostic` lines (file:line:col) while checking a YAML document; raise them all at the end."""

    def __init__(self, path: str):
        self.path = path
        self.diagnostics: list[Diagnostic] = []

    def loc(self, pos: tuple[int, int] | None) -> Location:
        if pos is None:
            return Location(self.path)
        return Location(self.path, pos[0], pos[1])

    def error(self, pos: tuple[int, int] | Location | None, message: str) -> None:
        loc = pos if isinstance(pos, Location) else self.loc(pos)
        self.diagnostics.append(Diagnostic(loc, message))


def load_spec(path: str | Path, overrides: dict[str, Any] | None = None) -> GraphSpec:
    """Read and shape-check a graph file. Raises :class:`GraphError`."""
    path = Path(path)
    return parse_spec(read_source(path, "graph file"), path, overrides)


def parse_spec(text: str, path: Path, overrides: dict[str, Any] | None = None) -> GraphSpec:
    c = Collector(str(path))
    data = load_yaml(text, str(path))
    if not isinstance(data, LocDict):
        message = "a graph file must be a mapping with keys flowtex, name, rate, nodes, edges, outputs"
        raise GraphError([Diagnostic(Location(str(path), 1, 1), message)])
    for key in data:
        if key not in TOP_KEYS:
            c.error(data.key_pos[key], f"unknown top-level key {excerpt(key)}{suggest(str(key), TOP_KEYS)}")
    for key in ("flowtex", "rate", "nodes", "outputs"):
        if key not in data:
            c.error(data.pos, f"missing top-level key {key!r}" + (" (the format version; write 'flowtex: 1')" if key == "flowtex" else ""))
    version = data.get("flowtex", FORMAT_VERSION)
    if "flowtex" in data and version != FORMAT_VERSION:
        c.error(data.value_pos["flowtex"], f"unsupported format version {excerpt(version)}; this flowtex reads version {FORMAT_VERSION}")
    name = data.get("name", path.stem)
    if not isinstance(name, str):
        c.error(data.value_pos.get("name"), "name must be a string")
        name = path.stem
    rate = _rate(c, data)
    seed = _seed(c, data)
    spec = GraphSpec(path=path, name=name, rate=rate, seed=seed, description=str(data.get("description", "")))
    spec.inputs = _inputs(c, data)
    spec.nodes = _nodes(c, data, spec.inputs)
    if overrides:
        _apply_overrides(c, spec, overrides)
    spec.edges = _edges(c, data)
    spec.outputs = _outputs(c, data)
    if c.diagnostics:
        raise GraphError(c.diagnostics)
    return spec


def _valid_rate(rate: Any) -> bool:
    """A graph rate: a number of Hz in (0, MAX_RATE_HZ]."""
    return not isinstance(rate, bool) and isinstance(rate, (int, float)) and math.isfinite(rate) and 0 < rate <= MAX_RATE_HZ


def _rate(c: Collector, data: LocDict) -> float:
    rate = data.get("rate", 1000.0)
    if not _valid_rate(rate):
        c.error(data.value_pos.get("rate"), f"rate must be a number of Hz in (0, {MAX_RATE_HZ:g}], got {excerpt(rate)}")
        return 1000.0
    return float(rate)


def _seed(c: Collector, data: LocDict) -> int:
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        c.error(data.value_pos.get("seed"), f"seed must be a non-negative integer, got {excerpt(seed)}")
        return 0
    return seed


def _check_name(c: Collector, name: Any, pos: tuple[int, int], what: str) -> bool:
    if not isinstance(name, str) or not NAME_RE.match(name):
        c.error(pos, f"{what} name {excerpt(name)} is not valid: use letters, digits and '_', not starting with a digit")
        return False
    return True


def _inputs(c: Collector, data: LocDict) -> dict[str, InputSpec]:
    raw = data.get("inputs")
    if raw is None:
        return {}
    if not isinstance(raw, LocDict):
        c.error(data.value_pos.get("inputs"), "inputs must be a mapping of name: {shape, unit}")
        return {}
    out: dict[str, InputSpec] = {}
    for name, value in raw.items():
        if not _check_name(c, name, raw.key_pos[name], "input"):
            continue
        shape: tuple[int, ...] = ()
        unit = ""
        if value is None:
            value = LocDict()
        if not isinstance(value, LocDict):
            c.error(raw.value_pos[name], f"input {name!r}: expected a mapping like {{shape: [3], unit: mm}} or nothing")
            continue
        for key in value:
            if key not in INPUT_KEYS:
                c.error(value.key_pos[key], f"input {name!r}: unknown key {excerpt(key)}{suggest(str(key), INPUT_KEYS)}")
        if "shape" in value:
            shape_raw = value["shape"]
            if isinstance(shape_raw, int) and not isinstance(shape_raw, bool):
                shape_raw = [shape_raw]
            if not isinstance(shape_raw, list) or not all(
                isinstance(s, int) and not isinstance(s, bool) and s > 0 for s in shape_raw
            ):
                c.error(value.value_pos["shape"], f"input {name!r}: shape must be a list of positive integers such as [3], or [] for a scalar")
            elif (problem := port_values_problem(shape_raw)) is not None:
                c.error(value.value_pos["shape"], f"input {name!r}: {problem}")
            else:
                shape = tuple(shape_raw)
        if "unit" in value:
            if not isinstance(value["unit"], str):
                c.error(value.value_pos["unit"], f"input {name!r}: unit must be a string such as 'mm' or 'N'")
            else:
                unit = "" if value["unit"] == "-" else value["unit"]  # '-' means dimensionless, as in node params
        out[name] = InputSpec(name, shape, unit, c.loc(raw.key_pos[name]))
    return out


def _nodes(c: Collector, data: LocDict, inputs: dict[str, InputSpec]) -> dict[str, NodeSpec]:
    raw = data.get("nodes")
    if raw is None:
        return {}
    if not isinstance(raw, LocDict):
        c.error(data.value_pos.get("nodes"), "nodes must be a mapping of name: {type, params}")
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
        for key in value:
            if key not in NODE_KEYS:
                c.error(value.key_pos[key], f"node {name!r}: unknown key {excerpt(key)}{suggest(str(key), NODE_KEYS)}")
        if "type" not in value or not isinstance(value["type"], str):
            c.error(value.value_pos.get("type", pos), f"node {name!r}: missing 'type' (run 'flowtex nodes' to list node types)")
            continue
        params = value.get("params")
        if params is None:
            params = LocDict()
            params.pos = value.value_pos.get("params", pos)
        if not isinstance(params, LocDict):
            c.error(value.value_pos.get("params"), f"node {name!r}: params must be a mapping of name: value")
            continue
        every = value.get("every", 1)
        if isinstance(every, bool) or not isinstance(every, int) or not 1 <= every <= MAX_EVERY:
            c.error(value.value_pos.get("every"), f"node {name!r}: every must be a positive integer up to {MAX_EVERY:,} "
                                                  f"(run every k ticks), got {excerpt(every)}")
            every = 1
        out[name] = NodeSpec(
            name=name,
            type=value["type"],
            params=dict(params),
            param_locs={k: c.loc(params.key_pos[k]) for k in params},
            every=every,
            loc=c.loc(pos),
            type_loc=c.loc(value.value_pos["type"]),
            params_loc=c.loc(value.key_pos.get("params", pos)),
        )
    return out


def _apply_overrides(c: Collector, spec: GraphSpec, overrides: dict[str, Any]) -> None:
    """Apply ``--set`` values: ``rate`` (the graph's base rate, Hz) or ``NODE.PARAM``."""
    for key, value in overrides.items():
        where = Location(f"--set {key}")
        if key == "rate":
            if not _valid_rate(value):
                c.error(where, f"rate must be a number of Hz in (0, {MAX_RATE_HZ:g}], got {excerpt(value)}")
            else:
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
        spec.nodes[node].params[param] = value
        spec.nodes[node].param_locs[param] = where


def parse_override(text: str) -> tuple[str, Any]:
    """``"lookup.models=x.xml"`` -> ``("lookup.models", "x.xml")`` (value read as YAML); ``"rate=2000"`` -> ``("rate", 2000)``."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise GraphError([Diagnostic(Location(f"--set {text}"), "expected --set NODE.PARAM=VALUE or --set rate=HZ")])
    return key.strip(), parse_value(value, f"--set {key.strip()}")


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
        c.error(data.value_pos.get("edges"), 'edges must be a list of "producer.port -> consumer.port" strings')
        return []
    out: list[EdgeSpec] = []
    for item, pos in zip(raw, raw.item_pos, strict=False):
        if not isinstance(item, str):
            c.error(pos, f'edge must be a string "producer.port -> consumer.port", got {excerpt(item)}')
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
        c.error(data.value_pos.get("outputs"), "outputs must be a non-empty mapping of name: node.port")
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
