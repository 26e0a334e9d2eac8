"""``flowtex scene plan|run|live``: plan a multi-surface scene into a graph, and run it offline or live (docs/scenes.md)."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from ..errors import FlowtexError
from .graph import load_graph_from_args
from .options import add_compile_option, add_graph_options, add_live_options, add_plugin_options, add_seed_option
from .output import note, say
from .run import RECORDING_SUFFIXES, run_summary


def register(sub: Any) -> None:
    """Add ``scene`` with its ``plan``, ``run`` and ``live`` subcommands."""
    scene = sub.add_parser("scene", help="plan a multi-surface scene into a graph that renders only what matters",
                           description="Scenes: surfaces + a representative trajectory -> a graph with only the salient components "
                                       "(docs/scenes.md).")
    actions = scene.add_subparsers(dest="scene_command", required=True, metavar="ACTION", parser_class=type(scene))

    p = actions.add_parser("plan", help="write the planned graph; explain what is kept and why")
    p.add_argument("scene", help="scene YAML file")
    p.add_argument("-o", "--output", required=True, help="graph YAML file to write")
    p.add_argument("--json", help="also write the decisions as JSON {surface: {component: {keep, salience, threshold, reason}}}")
    p.add_argument("--explain", action="store_true", help="print salience, threshold and decision per surface and component")
    add_plugin_options(p, no_plugins=False)  # a scene has no plugin folders of its own: only --plugins and $FLOWTEX_PLUGINS
    p.set_defaults(func=cmd_scene_plan)

    p = actions.add_parser("run", help="plan and run offline over a recording in one step")
    p.add_argument("scene", help="scene YAML file")
    p.add_argument("--input", "-i", required=True, help="recording with position, normal_force, normal (and the surface index input)")
    p.add_argument("--output", "-o", help="output file: .npz, .csv, .h5")
    p.add_argument("--surface", help="render this surface alone (the recording then needs no surface input)")
    add_seed_option(p)
    p.add_argument("--explain", action="store_true", help="print the plan first")
    add_compile_option(p, "auto")
    add_graph_options(p)
    p.set_defaults(func=cmd_scene_run)

    p = actions.add_parser("live", help="plan and run live against the scene's device in one step")
    p.add_argument("scene", help="scene YAML file")
    p.add_argument("--surface", help="render this surface alone")
    add_live_options(p, device_required=False)
    p.set_defaults(func=cmd_scene_live)


def cmd_scene_plan(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output, write_text_atomic
    from ..scene.build import plan_to_graph
    from ..scene.plan import explain, plan_json, silent_surfaces

    check_output(args.output, inputs=[args.scene], option="-o", suffixes=(".yaml", ".yml"))
    check_output(args.json, inputs=[args.scene], option="--json", suffixes=(".json",), others={"-o": args.output})
    plan = plan_to_graph(args.scene, args.output, tuple(args.plugins))
    if args.json:
        write_text_atomic(Path(args.json), json.dumps(plan_json(plan), indent=2) + "\n")
    if args.explain:
        say(explain(plan))
    kept = sum(d.keep for data in plan.values() for d in data.decisions.values())
    total = sum(len(data.decisions) for data in plan.values())
    say(f"{args.scene}: {len(plan)} surfaces, {kept} of {total} components kept -> {args.output}")
    for line in silent_surfaces(plan):
        note(f"warning: {line}")
    return 0


def cmd_scene_run(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output
    from ..runtime.offline import load_recording_for, run_recording
    from ..scene.build import plan_to_graph
    from ..scene.plan import explain

    check_output(args.output, inputs=[args.scene, args.input], option="-o", suffixes=RECORDING_SUFFIXES)
    with tempfile.TemporaryDirectory(prefix="flowtex-scene-") as tmp:
        graph_path = Path(tmp) / "scene.yaml"
        plan = plan_to_graph(args.scene, graph_path, tuple(args.plugins), fixed=args.surface, relative=False)
        if args.explain:
            say(explain(plan))
        read: dict[str, Any] = {}

        def read_recording(resolved: Any) -> None:  # once the planned graph is checked, before its compile
            read["recording"] = load_recording_for(resolved, args.input)

        graph = load_graph_from_args(args, graph_path, before_compile=read_recording, outputs={"-o": args.output})
        recording = read["recording"]
        outputs = run_recording(graph, args.input, args.output, seed=args.seed, progress=sys.stderr.isatty(), recording=recording)
    say(run_summary(graph, outputs, args.output))
    return 0


def cmd_scene_live(args: argparse.Namespace) -> int:
    from ..scene.build import plan_to_graph
    from ..scene.file import load_scene
    from .live import check_live_outputs, live_outputs, run_live_session

    scene = load_scene(args.scene)
    dbc = args.dbc or (str(scene.dbc) if scene.dbc else None)
    map_ = args.map or (str(scene.map) if scene.map else None)
    if not (dbc and map_):
        raise FlowtexError(f"{args.scene}: live use needs a device: add device: {{dbc: FILE, map: FILE}} to the scene or give --dbc and --map")
    check_live_outputs(args, args.scene, dbc, map_)
    with tempfile.TemporaryDirectory(prefix="flowtex-scene-") as tmp:
        graph_path = Path(tmp) / "scene.yaml"
        plan_to_graph(args.scene, graph_path, tuple(args.plugins), fixed=args.surface, relative=False)
        graph = load_graph_from_args(args, graph_path, tier="fused", outputs=live_outputs(args))  # live keeps the fused tick
        return run_live_session(graph, args, dbc, map_)
