"""``flowtex scene plan|run|live``: argparse wiring (registered from flowtex/cli.py)."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    """Add ``scene`` with its ``plan``, ``run`` and ``live`` subcommands."""
    scene = subparsers.add_parser("scene", help="plan a multi-surface scene into a graph that renders only what matters",
                                  description="Scenes: surfaces + a representative trajectory -> a graph with only the salient components "
                                              "(docs/scenes.md).")
    sub = scene.add_subparsers(dest="scene_command", required=True)

    p = sub.add_parser("plan", help="write the planned graph; explain what is kept and why")
    p.add_argument("scene", help="scene YAML file")
    p.add_argument("-o", "--output", required=True, help="graph YAML file to write")
    p.add_argument("--json", help="also write the decisions as JSON {surface: {component: {keep, salience, threshold, reason}}}")
    p.add_argument("--explain", action="store_true", help="print salience, threshold and decision per surface and component")
    p.add_argument("--plugins", action="append", default=[], metavar="DIR", help="extra plugin folder (repeatable)")
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser("run", help="plan and run offline over a recording in one step")
    p.add_argument("scene", help="scene YAML file")
    p.add_argument("--input", "-i", required=True, help="recording with position, normal_force, normal (and the surface index input)")
    p.add_argument("--output", "-o", help="output file: .npz, .csv, .h5")
    p.add_argument("--surface", help="render this surface alone (the recording then needs no surface input)")
    p.add_argument("--seed", type=int, default=None, help="noise seed (default: the graph's)")
    p.add_argument("--explain", action="store_true", help="print the plan first")
    p.add_argument("--plugins", action="append", default=[], metavar="DIR", help="extra plugin folder (repeatable)")
    p.add_argument("--compile", choices=("fused", "dispatch", "auto"), default="auto",
                   help="compile tier (default auto: fused if cached, else dispatch; docs/engine.md)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("live", help="plan and run live against the scene's device in one step")
    p.add_argument("scene", help="scene YAML file")
    p.add_argument("--surface", help="render this surface alone")
    p.add_argument("--bus", help="INTERFACE[:CHANNEL] as for 'flowtex live'")
    p.add_argument("--bitrate", type=int, help="bus bitrate in bit/s")
    p.add_argument("--dbc", help="DBC file (default: the scene's device.dbc)")
    p.add_argument("--map", help="signal map file (default: the scene's device.map)")
    p.add_argument("--record", help="log every frame to SESSION.blf or SESSION.log")
    p.add_argument("--duration", type=float, help="seconds to run (default: until Ctrl-C)")
    p.add_argument("--rt", action="store_true", help="SCHED_FIFO real-time scheduling (as 'flowtex live')")
    p.add_argument("--rt-priority", type=int, default=80)
    p.add_argument("--cpu", type=int)
    p.add_argument("--stats", help="write end-of-run statistics as JSON")
    p.add_argument("--simulate", metavar="RECORDING", help="simulated device playing RECORDING in this process")
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.add_argument("--show", action="append", default=[], metavar="SIGNAL",
                   help="append a graph output or input (NAME or NAME[i]) to the status line (repeatable)")
    p.add_argument("--seed", type=int)
    p.add_argument("--plugins", action="append", default=[], metavar="DIR")
    p.set_defaults(func=cmd_live)


def cmd_plan(args: argparse.Namespace) -> int:
    from .build import plan_to_graph, write_text_atomic
    from .plan import explain, plan_json

    plan = plan_to_graph(args.scene, args.output, tuple(args.plugins))
    if args.json:
        write_text_atomic(Path(args.json), json.dumps(plan_json(plan), indent=2) + "\n")
    if args.explain:
        print(explain(plan))
    kept = sum(d.keep for data in plan.values() for d in data.decisions.values())
    total = sum(len(data.decisions) for data in plan.values())
    print(f"{args.scene}: {len(plan)} surfaces, {kept} of {total} components kept -> {args.output}")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from ..graph.compiled import load_graph
    from ..runtime.offline import run_recording
    from .build import plan_to_graph
    from .plan import explain

    with tempfile.TemporaryDirectory(prefix="flowtex-scene-") as tmp:
        graph_path = Path(tmp) / "scene.yaml"
        plan = plan_to_graph(args.scene, graph_path, tuple(args.plugins), fixed=args.surface, relative=False)
        if args.explain:
            print(explain(plan))
        graph = load_graph(graph_path, plugins=tuple(args.plugins), tier=args.compile)
        outputs = run_recording(graph, args.input, args.output, seed=args.seed, progress=sys.stderr.isatty())
    n = next(iter(outputs.values())).shape[0] if outputs else 0
    target = f" -> {args.output}" if args.output else ""
    print(f"{graph.name}: {n} ticks at {graph.rate:g} Hz, outputs {', '.join(outputs)}{target} ({graph.tier} tier)")
    return 0


def cmd_live(args: argparse.Namespace) -> int:
    from ..errors import FlowtexError
    from ..runtime.commands import cmd_live as run_live_command
    from .build import plan_to_graph
    from .file import load_scene

    scene = load_scene(args.scene)
    dbc = args.dbc or (str(scene.dbc) if scene.dbc else None)
    map_ = args.map or (str(scene.map) if scene.map else None)
    if not (dbc and map_):
        raise FlowtexError(f"{args.scene}: live use needs a device: add device: {{dbc: FILE, map: FILE}} to the scene or give --dbc and --map")
    with tempfile.TemporaryDirectory(prefix="flowtex-scene-") as tmp:
        graph_path = Path(tmp) / "scene.yaml"
        plan_to_graph(args.scene, graph_path, tuple(args.plugins), fixed=args.surface, relative=False)
        live_args = argparse.Namespace(**{**vars(args), "graph": str(graph_path), "dbc": dbc, "map": map_, "set": []})
        return run_live_command(live_args)
