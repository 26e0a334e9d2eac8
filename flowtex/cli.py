"""The ``flowtex`` command: validate, run, graph, nodes (and live, simulate-device).

User errors print as one line each (``file:line:col: message``) and exit 1;
they never show a traceback. Set ``FLOWTEX_DEBUG=1`` to see tracebacks of
internal errors.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from .errors import FlowtexError

REPLAY_SUFFIXES = (".blf", ".log", ".asc")

COMMAND_MODULES = (
    "flowtex.runtime.commands",
    "flowtex.fit.commands",
    "flowtex.cli_resample",
    "flowtex.fit.models_command",
    "flowtex.scene.commands",
    "flowtex.bench.commands",
    "flowtex.plotting",
)
"""Modules that add subcommands: each has ``register(subparsers)`` (one job per module, one line here)."""


def _add_graph_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plugins", action="append", default=[], metavar="DIR",
                   help="extra plugin folder (repeatable; ./plugins, the graph file's plugins/ and $FLOWTEX_PLUGINS "
                        "are always searched)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="NODE.PARAM=VALUE",
                   help="override a node parameter (repeatable), e.g. --set lookup.models=Models_Cork.xml")


def _add_compile_option(p: argparse.ArgumentParser, default: str) -> None:
    p.add_argument("--compile", choices=("fused", "dispatch", "auto"), default=default,
                   help="fused: one compiled tick per graph structure (fastest ticks; seconds to compile a new structure); "
                        "dispatch: cached per-node kernels (a structural edit compiles nothing new); "
                        f"auto: fused if cached, else dispatch and fused compiled in the background (default: {default}; "
                        "docs/engine.md)")


def _overrides(items: Sequence[str]) -> dict:
    from .graph.spec import parse_override

    return dict(parse_override(text) for text in items)


def cmd_validate(args: argparse.Namespace) -> int:
    from .graph.compiled import check_graph

    rg = check_graph(args.graph, _overrides(args.overrides), tuple(args.plugins))
    dropped = f"; dropped (unused): {', '.join(rg.dropped)}" if rg.dropped else ""
    print(f"{args.graph}: ok ({len(rg.nodes)} nodes, {len(rg.spec.outputs)} outputs{dropped})")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from .graph.compiled import load_graph

    graph = load_graph(args.graph, _overrides(args.overrides), tuple(args.plugins), tier=args.compile)
    if Path(args.input).suffix.lower() in REPLAY_SUFFIXES:
        if not (args.dbc and args.map):
            raise FlowtexError(f"{args.input}: replaying a CAN session needs --dbc DEVICE.dbc and --map MAP.yaml")
        from .runtime.replay import replay_session

        report = replay_session(graph, args.input, args.dbc, args.map, args.output, seed=args.seed)
        print(report)
        return 0
    from .runtime.offline import run_recording

    outputs = run_recording(graph, args.input, args.output, seed=args.seed, progress=sys.stderr.isatty(),
                            nonfinite=args.nonfinite)
    n = next(iter(outputs.values())).shape[0] if outputs else 0
    target = f" -> {args.output}" if args.output else ""
    print(f"{graph.name}: {n} ticks at {graph.rate:g} Hz, outputs {', '.join(outputs)}{target} ({graph.tier} tier)")
    return 0


def cmd_graph(args: argparse.Namespace) -> int:
    from .graph.compiled import load_graph
    from .graph.describe import describe_graph, graph_dot

    graph = load_graph(args.graph, _overrides(args.overrides), tuple(args.plugins), tier=args.compile)
    if args.dot:
        print(graph_dot(graph))
    elif args.show_code:
        print(graph.source)
    else:
        print(describe_graph(graph))
    return 0


def cmd_nodes(args: argparse.Namespace) -> int:
    from .graph.describe import describe_node_type, describe_registry
    from .node_api import suggest
    from .registry import load_registry

    registry = load_registry(tuple(args.plugins))
    if args.type:
        cls = registry.get(args.type)
        if cls is None:
            raise FlowtexError(f"unknown node type {args.type!r}{suggest(args.type, registry.names())}")
        print(describe_node_type(cls, registry.origins[args.type]))
    else:
        print(describe_registry(registry))
    return 0


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = argparse.ArgumentParser(prog="flowtex", description="Dataflow graphs for haptic signal processing.")
    parser.add_argument("--version", action="version", version=f"flowtex {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("validate", help="check a graph file; one line per problem")
    p.add_argument("graph")
    _add_graph_options(p)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("run", help="run a graph offline over a recording (or replay a CAN session)")
    p.add_argument("graph")
    p.add_argument("--input", "-i", required=True, help="recording: .npz, .csv, .h5; or a CAN session .blf/.log")
    p.add_argument("--output", "-o", help="output file: .npz, .csv, .h5 (or .blf/.log when replaying)")
    p.add_argument("--seed", type=int, default=None, help="noise seed (default: the graph's seed)")
    p.add_argument("--dbc", help="DBC file (replay of a CAN session)")
    p.add_argument("--map", help="signal map file (replay of a CAN session)")
    p.add_argument("--nonfinite", choices=("error", "hold", "zero", "pass"), default="error",
                   help="NaN/inf in the recording: error (default; names signal, count, first index), "
                        "hold (last finite value), zero, or pass (unchanged)")
    _add_compile_option(p, "auto")
    _add_graph_options(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("graph", help="show execution order, buffers and dropped nodes")
    p.add_argument("graph")
    group = p.add_mutually_exclusive_group()
    group.add_argument("--dot", action="store_true", help="print Graphviz source")
    group.add_argument("--show-code", action="store_true",
                       help="print what runs: the fused tier's generated tick source, or the dispatch tier's node order and driver")
    _add_compile_option(p, "fused")
    _add_graph_options(p)
    p.set_defaults(func=cmd_graph)

    p = sub.add_parser("nodes", help="list node types with ports, parameters and docs")
    p.add_argument("type", nargs="?", help="show only this node type")
    p.add_argument("--plugins", action="append", default=[], metavar="DIR")
    p.set_defaults(func=cmd_nodes)

    for module_name in COMMAND_MODULES:
        importlib.import_module(module_name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except FlowtexError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    except Exception as exc:
        if os.environ.get("FLOWTEX_DEBUG"):
            raise
        print(f"flowtex: internal error: {type(exc).__name__}: {exc} (set FLOWTEX_DEBUG=1 for a traceback; please report it)",
              file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
