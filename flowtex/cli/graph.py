"""``flowtex validate``, ``flowtex graph`` and ``flowtex nodes``: check, describe and list."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..errors import FlowtexError
from .options import add_compile_option, add_graph_options, add_plugin_options, overrides
from .output import note, say


def register(sub: Any) -> None:
    p = sub.add_parser("validate", help="check any flowtex file (graph, scene, device map, model set, pattern, tap library, "
                                        "friction, compliance); one line per problem")
    p.add_argument("graph", metavar="FILE", help="any flowtex file; its kind is read from its content")
    p.add_argument("--dbc", metavar="DEVICE.dbc", help="the device a map file is checked against")
    p.add_argument("--map", metavar="MAP.yaml", help="with a graph and --dbc: check this device map against the graph as "
                                                     "'flowtex live' loads it (port names, widths and units)")
    add_graph_options(p)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("graph", help="show execution order, buffers and dropped nodes")
    p.add_argument("graph")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--dot", action="store_true", help="print Graphviz source")
    group.add_argument("--show-code", action="store_true",
                       help="print what runs: the fused tier's generated tick source, or the dispatch tier's node order and driver")
    add_compile_option(p, "fused")
    add_graph_options(p)
    p.set_defaults(func=cmd_graph)

    p = sub.add_parser("nodes", help="list node types with ports, parameters and docs")
    p.add_argument("type", nargs="?", help="show only this node type")
    p.add_argument("--json", action="store_true", help="print the node types as JSON (ports, parameters with kind, bounds, "
                                                      "choices, default, unit, doc) for other tools")
    add_plugin_options(p, no_plugins=False)
    p.set_defaults(func=cmd_nodes)


def plugin_kwargs(args: argparse.Namespace) -> dict:
    """``plugins=`` and ``auto_plugins=`` for flowtex.graph.compiled's loaders."""
    return {"plugins": tuple(args.plugins), "auto_plugins": not args.no_plugins}


def report_plugins(graph_path: str | Path, args: argparse.Namespace) -> None:
    """One stderr line naming the plugin files (Python code) that ran to load ``graph_path``; nothing if none."""
    from ..graph.compiled import graph_registry

    files = graph_registry(graph_path, tuple(args.plugins), not args.no_plugins).plugin_files
    if files:
        note(f"flowtex: loaded plugin code: {', '.join(str(f) for f in files)} (skip the automatic ones with --no-plugins)")


def load_graph_from_args(args: argparse.Namespace, path: str | Path | None = None, tier: str | None = None,
                         before_compile: Callable[[Any], None] | None = None,
                         outputs: Mapping[str, str | Path | None] | None = None) -> Any:
    """The compiled graph named by ``args.graph`` (or ``path``) with ``--set``, ``--plugins``, ``--no-plugins``,
    compiled by ``tier`` (default ``--compile``, if the verb has it; docs/engine.md); ``before_compile`` runs once
    the graph is checked (flowtex.graph.compiled.load_graph). ``outputs`` (option -> path) are refused, then, when one
    is a file the graph's nodes read (a model set, a plugin's table; from the graph file or ``--set``)."""
    from ..graph.compiled import load_graph

    path = path if path is not None else args.graph
    tier = tier or getattr(args, "compile", None)
    check = before_compile
    if outputs:
        def check(resolved: Any) -> None:
            from ..graph.resolved import files_read
            from ..io.atomic import check_not_input

            read = sorted(files_read(resolved))
            for option, out in outputs.items():
                check_not_input(out, read, option, what="a file the graph reads")
            if before_compile is not None:
                before_compile(resolved)
    graph = load_graph(path, overrides(args.overrides), **plugin_kwargs(args), tier=tier, before_compile=check)
    report_plugins(path, args)
    return graph


def cmd_validate(args: argparse.Namespace) -> int:
    from ..filecheck import GRAPH, check_file, check_map_for_graph, file_kind
    from ..graph.compiled import check_graph

    kind = file_kind(args.graph)
    if kind != GRAPH:
        if args.overrides:
            raise FlowtexError(f"--set: {args.graph} is a {kind}, not a graph; --set applies to graphs only")
        if args.map is not None:
            raise FlowtexError(f"--map: {args.graph} is a {kind}, not a graph; check a map against its graph with "
                               f"'flowtex validate GRAPH --dbc DEVICE.dbc --map {args.map}'")
        say(check_file(args.graph, kind, args.dbc, tuple(args.plugins), not args.no_plugins))
        return 0
    if args.map is not None and args.dbc is None:
        raise FlowtexError(f"--map {args.map}: a device map is checked against its device: give --dbc DEVICE.dbc too")
    rg = check_graph(args.graph, overrides(args.overrides), **plugin_kwargs(args))
    report_plugins(args.graph, args)
    dropped = f"; dropped (unused): {', '.join(rg.dropped)}" if rg.dropped else ""
    say(f"{args.graph}: ok ({len(rg.nodes)} nodes, {len(rg.spec.outputs)} outputs{dropped})")
    if args.map is not None:
        line, warnings = check_map_for_graph(args.map, args.dbc, rg.input_specs, rg.output_specs)
        say(line)
        for w in warnings:
            note(f"flowtex validate: warning: {w}")
    return 0


def cmd_graph(args: argparse.Namespace) -> int:
    from ..graph.describe import describe_graph, graph_dot

    graph = load_graph_from_args(args)
    if args.dot:
        say(graph_dot(graph))
    elif args.show_code:
        say(graph.source)
    else:
        say(describe_graph(graph))
    return 0


def cmd_nodes(args: argparse.Namespace) -> int:
    from ..graph.describe import describe_node_type, describe_registry
    from ..node_api import suggest
    from ..registry import load_registry

    registry = load_registry(tuple(args.plugins))
    if registry.plugin_files:
        note(f"flowtex: loaded plugin code: {', '.join(str(f) for f in registry.plugin_files)}")
    if args.type and registry.get(args.type) is None:
        raise FlowtexError(f"unknown node type {args.type!r}{suggest(args.type, registry.names())}")
    if not args.type:
        registry.load_all()  # every type is described: installed packages are imported
    if args.json:
        import json

        from ..schema.jsonschema import node_facts

        types = {args.type: registry.types[args.type]} if args.type else registry.types
        say(json.dumps(node_facts(types, registry.origins), indent=1, ensure_ascii=False))
    elif args.type:
        say(describe_node_type(registry.types[args.type], registry.origins[args.type]))
    else:
        say(describe_registry(registry))
    return 0
