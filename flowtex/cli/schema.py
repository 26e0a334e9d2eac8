"""``flowtex schema graph|scene|map``: the JSON Schema (draft 2020-12) editors use for a file kind (docs/editing.md)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from .options import add_plugin_options
from .output import say

KINDS = ("graph", "scene", "map")


def register(sub: Any) -> None:
    p = sub.add_parser("schema", help="print the JSON Schema of a file kind for editors (graph, scene, map)")
    p.add_argument("kind", choices=KINDS, help="graph (with every loaded node type), scene, or map (a device map with its audio section)")
    p.add_argument("-o", "--output", metavar="FILE.json", help="write the schema to FILE.json instead of stdout")
    add_plugin_options(p, no_plugins=False)  # a schema reads no graph: no graph folders to skip
    p.set_defaults(func=cmd_schema)


def schema_text(kind: str, plugins: tuple[str, ...] = ()) -> str:
    """The schema of ``kind`` as indented JSON text (what ``flowtex schema KIND`` prints and docs/schema/ holds)."""
    from ..schema import jsonschema

    if kind == "graph":
        from ..registry import load_registry

        registry = load_registry(plugins)
        registry.load_all()  # the schema lists every type: installed packages are imported
        doc = jsonschema.graph_schema(registry.types)
    else:
        doc = jsonschema.scene_schema() if kind == "scene" else jsonschema.map_schema()
    return json.dumps(doc, indent=1, ensure_ascii=False) + "\n"


def cmd_schema(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output, write_text_atomic

    out = check_output(args.output, option="-o", suffixes=(".json",))
    text = schema_text(args.kind, tuple(args.plugins))
    if out is None:
        say(text.rstrip("\n"))
    else:
        write_text_atomic(out, text)
    return 0
