"""JSON Schemas (draft 2020-12) from the declarations that ``validate`` uses, for editors (docs/editing.md).

:func:`field_schema` / :func:`record_schema` translate :mod:`flowtex.schema.core` declarations; :func:`graph_schema`
adds every node type of a registry (each parameter's kind, bounds, choices, default, unit and doc, from its
``Param``) and the port names edges and outputs may use; :func:`node_facts` gives the same facts as plain data
(``flowtex nodes --json``). Nothing here imports a JSON Schema validator.
"""

from __future__ import annotations

import re
from typing import Any

from ..limits import MAX_INT_PARAM
from ..node_api import Node, Param, Port
from ..yamlsource import YAML11_BOOLS
from .core import NO_DEFAULT, Field, Record

DIALECT = "https://json-schema.org/draft/2020-12/schema"


def _description(doc: str, unit: str = "", default: Any = NO_DEFAULT) -> str:
    parts = [doc.strip()] if doc.strip() else []
    if unit:
        parts.append(f"Unit: {unit}.")
    if default is not NO_DEFAULT and default is not None:
        parts.append(f"Default: {default}.")
    return " ".join(parts)


def _bounds(out: dict[str, Any], lo: float | None, hi: float | None, lo_ex: bool, hi_ex: bool) -> None:
    if lo is not None:
        out["exclusiveMinimum" if lo_ex else "minimum"] = lo
    if hi is not None:
        out["exclusiveMaximum" if hi_ex else "maximum"] = hi


def bool_schema() -> dict[str, Any]:
    """A bool: true or false, or a YAML 1.1 spelling flowtex still takes where a bool is expected (yes, off, ...; an
    editor reading YAML 1.2 sees those as strings)."""
    return {"anyOf": [{"type": "boolean"}, {"enum": list(YAML11_BOOLS)}]}


def field_schema(f: Field) -> dict[str, Any]:
    """The JSON Schema of one declared value."""
    k = f.kind
    out: dict[str, Any]
    if k in ("number", "int"):
        out = {"type": "number" if k == "number" else "integer"}
        _bounds(out, f.min, f.max, f.min_exclusive, f.max_exclusive)
    elif k == "bool":
        out = bool_schema()
    elif k == "str":
        out = {"type": "string"}
        if f.pattern:
            out["pattern"] = f.pattern
        if f.length is not None and f.length[0]:
            out["minLength"] = f.length[0]
    elif k == "choice":
        out = {"enum": list(f.choices)}
    elif k == "const":
        out = {"const": f.const}
    elif k == "list":
        out = {"type": "array"}
        if f.items is not None:
            out["items"] = field_schema(f.items)
        if f.length is not None:
            if f.length[0]:
                out["minItems"] = f.length[0]
            if f.length[1] is not None:
                out["maxItems"] = f.length[1]
    elif k == "map":
        out = {"type": "object"}
        if f.names:
            out["propertyNames"] = {"pattern": f.names}
        if f.values is not None:
            out["additionalProperties"] = field_schema(f.values)
        if f.length is not None and f.length[0]:
            out["minProperties"] = f.length[0]
    elif k == "record":
        out = record_schema(f.record) if f.record is not None else {"type": "object"}
    elif k == "any_of":
        out = {"anyOf": [field_schema(o) for o in f.of]}
    else:
        out = {}
    text = _description(f.doc, f.unit, f.default)
    if text:
        out["description"] = text
    if f.default is not NO_DEFAULT:
        out["default"] = f.default
    if f.json:
        out.update(f.json)
    return out


def record_schema(r: Record) -> dict[str, Any]:
    """The JSON Schema of a declared mapping (unknown keys refused unless the record is open)."""
    props = {key: field_schema(f) for key, f in r.keys.items()}
    for old, new in r.legacy.items():
        props[old] = {**props[new], "deprecated": True, "description": f"Old spelling of {new!r}, still read."}
    out: dict[str, Any] = {"type": "object", "properties": props}
    required = [k for k in r.required if not any(new == k for new in r.legacy.values())]
    if required:
        out["required"] = required
    legacy_required = [k for k in r.required if k not in required]
    if legacy_required:  # either spelling, not both
        out["allOf"] = [{"oneOf": [{"required": [k]}, {"required": [o]}]} for k in legacy_required
                        for o, n in r.legacy.items() if n == k]
    if not r.open:
        out["additionalProperties"] = False
    if r.doc:
        out["description"] = r.doc
    if r.json:
        out.update(r.json)
    return out


def document_schema(r: Record, kind: str, title: str) -> dict[str, Any]:
    """A top-level schema for file kind ``kind``."""
    return {"$schema": DIALECT, "$id": f"https://flowtex.invalid/schema/{kind}.schema.json", "title": title, **record_schema(r)}


def param_schema(p: Param) -> dict[str, Any]:
    """JSON Schema of one node parameter, from its ``Param`` declaration (what ``Param.coerce`` accepts)."""
    out: dict[str, Any]
    if p.kind in ("float", "int"):
        out = {"type": "number" if p.kind == "float" else "integer"}
        _bounds(out, p.min, p.max, p.min_exclusive, p.max_exclusive)
        if p.kind == "int" and p.max is None:
            out["maximum"] = MAX_INT_PARAM  # Param.coerce's ceiling for an unbounded integer
    elif p.kind == "bool":
        out = bool_schema()
    elif p.kind in ("str", "path"):
        out = {"type": "string", "minLength": 1}
    elif p.kind == "choice":
        out = {"enum": list(p.choices)}
    else:  # floats: a number or a list of numbers
        one: dict[str, Any] = {"type": "number"}
        _bounds(one, p.min, p.max, p.min_exclusive, p.max_exclusive)
        many: dict[str, Any] = {"type": "array", "items": one}
        if p.length is not None:
            many["minItems"], many["maxItems"] = p.length
        out = {"anyOf": [one, many]} if p.length is None or p.length[0] <= 1 else many
    desc = f"{p.doc.strip()} ({p.describe_type()})"
    if p.unit:
        desc += f" Unit: {p.unit}."
    desc += " Required." if p.required else f" Default: {p.default!r}."
    out["description"] = desc
    if not p.required and p.default is not None:
        out["default"] = list(p.default) if isinstance(p.default, tuple) else p.default
    return out


def _port(name: str, port: Port) -> dict[str, Any]:
    return {"name": name, "shape": port.describe(), "unit": port.unit, "doc": port.doc,
            **({"optional": True} if port.optional else {})}


def node_facts(types: dict[str, type[Node]], origins: dict[str, str]) -> list[dict[str, Any]]:
    """Every node type as plain data: summary, origin, ports and parameters with kind, bounds, choices, default,
    unit and doc (``flowtex nodes --json``)."""
    out = []
    for name in sorted(types):
        cls = types[name]
        params = {}
        for pname, p in cls.params.items():
            params[pname] = {"kind": p.kind, "required": p.required,
                             "default": None if p.required else (list(p.default) if isinstance(p.default, tuple) else p.default),
                             "unit": p.unit, "doc": p.doc, "min": p.min, "max": p.max,
                             "min_exclusive": p.min_exclusive, "max_exclusive": p.max_exclusive,
                             "choices": list(p.choices), "length": list(p.length) if p.length else None,
                             "type": p.describe_type()}
        out.append({"type": name, "summary": cls.summary(), "origin": origins.get(name, ""),
                    "inputs": [_port(n, p) for n, p in cls.inputs.items()],
                    "outputs": [_port(n, p) for n, p in cls.outputs.items()],
                    "params": params, "json_schema": {"params": params_schema(cls)}})
    return out


def params_schema(cls: type[Node]) -> dict[str, Any]:
    """The ``params`` mapping of a node of type ``cls``: declared names only, required ones required."""
    out: dict[str, Any] = {"type": "object", "properties": {k: param_schema(p) for k, p in cls.params.items()},
                           "additionalProperties": False}
    required = [k for k, p in cls.params.items() if p.required]
    if required:
        out["required"] = required
    return out


def _alternation(names: set[str]) -> str:
    return "|".join(re.escape(n) for n in sorted(names))


def graph_schema(types: dict[str, type[Node]]) -> dict[str, Any]:
    """The graph file's JSON Schema with the node types ``types`` (built-ins and loaded plugins)."""
    from .graph import GRAPH, NODE

    schema = document_schema(GRAPH, "graph", "flowtex graph")
    node = record_schema(NODE)
    node["properties"]["type"] = {"enum": sorted(types), "description": NODE.keys["type"].doc}
    node["allOf"] = [{"if": {"properties": {"type": {"const": name}}, "required": ["type"]},
                      "then": {"properties": {"params": params_schema(cls)},
                               "description": f"{name}: {cls.summary()}"}}
                     for name, cls in sorted(types.items())]
    schema["properties"]["nodes"]["additionalProperties"] = node
    outs = {p for cls in types.values() for p in cls.outputs}
    ins = {p for cls in types.values() for p in cls.inputs}
    name = r"[A-Za-z_][A-Za-z0-9_]*"
    edge = rf"^\s*{name}(\.({_alternation(outs)}))?\s*->\s*{name}\.({_alternation(ins)})\s*$"
    schema["properties"]["edges"]["items"]["pattern"] = edge
    schema["properties"]["edges"]["items"]["description"] += (
        " Output ports: " + ", ".join(sorted(outs)) + ". Input ports: " + ", ".join(sorted(ins)) + ".")
    schema["properties"]["outputs"]["additionalProperties"] = {
        "type": "string", "pattern": rf"^\s*{name}(\.({_alternation(outs)}))?\s*$",
        "description": "A node output as node.port, or a graph input by its bare name."}
    return schema


def scene_schema() -> dict[str, Any]:
    from .scene import SCENE

    return document_schema(SCENE, "scene", "flowtex scene")


def map_schema() -> dict[str, Any]:
    from .devmap import MAP

    return document_schema(MAP, "map", "flowtex device map")
