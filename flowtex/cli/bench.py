"""``flowtex bench``: speed against error of knob settings (docs/bench.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ..errors import DataError, FlowtexError
from .options import add_compile_option, add_graph_options, add_seed_option, int_at_least, overrides, scheduler_address
from .output import say


def register(sub: Any) -> None:
    p = sub.add_parser("bench", help="sweep knobs: ns/tick against output error, Pareto front",
                       description="Run every combination of knob values on the same input and seed; report ns/tick "
                                   "(median of side-by-side runs) and each output's error against the reference.")
    p.add_argument("graph", help="graph YAML file, or a scene file (then plan=planned,all and plan.COMPONENT=auto,keep,drop are knobs)")
    p.add_argument("--input", "-i", required=True, help="recording (.npz, .csv, .h5) holding the graph's inputs")
    p.add_argument("--knob", action="append", default=[], metavar="NODE.PARAM=V1,V2,...",
                   help="values to sweep (repeatable); NODE.every=1,2,4 sets a node's rate divider")
    p.add_argument("--reference", action="append", default=[], metavar="NODE.PARAM=V",
                   help="reference setting (default: the first value of each knob)")
    p.add_argument("--outputs", nargs="+", help="outputs to compare (default: all)")
    p.add_argument("--metric", choices=("lsd", "rms", "gfc"), help="error metric (default: lsd for m/s^2 outputs, rms otherwise)")
    p.add_argument("--repeats", type=int_at_least(1, 1000), default=5, help="timed runs per configuration (1..1000, median; default 5)")
    add_seed_option(p)
    p.add_argument("-o", "--output", help="write the table as CSV")
    p.add_argument("--plot", help="draw the Pareto plot to this PNG (needs matplotlib: pip install 'flowtex[plot]')")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int_at_least(1), help="run the configurations on a local Dask cluster of N worker processes")
    where.add_argument("--scheduler", type=scheduler_address, help="run the configurations on an existing Dask cluster (scheduler address, e.g. tcp://host:8786)")
    add_compile_option(p, "dispatch", ("dispatch", "fused"))
    add_graph_options(p, no_plugins=False)
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    from ..bench.report import dask_client, need_matplotlib, pareto_plot, write_csv
    from ..bench.sweep import build, check_configuration_count, default_metric, format_table, parse_knob, sweep, table
    from ..graph.spec import parse_override
    from ..io.atomic import check_output
    from ..io.recordings import load_recording

    if not args.knob:
        raise FlowtexError("flowtex bench: give at least one --knob NODE.PARAM=V1,V2,...")
    knobs = dict(parse_knob(k) for k in args.knob)
    sets = overrides(args.overrides)
    for key, value in sets.items():  # a --set is a knob with one value, in every configuration
        if key in knobs:
            raise FlowtexError(f"--set {key}: that parameter is also a --knob; give it once")
        knobs[key] = [value]
    check_configuration_count({k: len(v) for k, v in knobs.items()})
    reference = dict(parse_override(r, "--reference") for r in args.reference)
    inputs = [args.graph, args.input]
    check_output(args.output, inputs=inputs, option="-o", suffixes=(".csv",))
    check_output(args.plot, inputs=inputs, option="--plot", others={"-o": args.output})
    if args.output or args.plot:  # a knob may name another file to read in each configuration
        _check_not_read(args, knobs, reference, set(sets))
    if args.plot:
        need_matplotlib()
    rec = load_recording(args.input)
    if rec.samples < 2:
        raise DataError(f"{args.input}: the recording has {rec.samples} sample(s); bench needs at least 2")
    with dask_client(args.workers, args.scheduler) as client:
        configs, outputs = sweep(args.graph, rec, knobs, reference, args.outputs, args.metric, args.repeats,
                                 args.seed, tuple(args.plugins), client=client, tier=args.compile)
    if not configs:
        raise DataError("no configuration to run")
    units = build(args.graph, configs[0].values, tuple(args.plugins), args.compile).outputs
    metrics = {o: args.metric or default_metric(units[o].unit) for o in outputs}
    rows = table(configs, outputs, metrics)
    say(format_table(rows))
    say(f"* = Pareto front over (ns/tick, {outputs[0]} {metrics[outputs[0]]})")
    if args.output:
        write_csv(args.output, rows)
    if args.plot:
        pareto_plot(configs, outputs[0], metrics[outputs[0]], Path(args.plot))
    return 0


def _check_not_read(args: argparse.Namespace, knobs: dict[str, list[Any]], reference: dict[str, Any], sets: set[str]) -> None:
    """Refuse ``-o``/``--plot`` naming a file any configuration's graph reads (the reference's too), naming the
    ``--knob``, ``--set`` or ``--reference`` setting that makes it read that file."""
    from ..bench.reads import files_read_by_configs
    from ..bench.sweep import combinations, reference_values
    from ..io.atomic import check_not_input

    reads = files_read_by_configs(args.graph, [*combinations(knobs), reference_values(knobs, reference)], tuple(args.plugins))
    for option, out in (("-o", args.output), ("--plot", args.plot)):
        for path, setting in reads.items():
            via = ""
            if setting is not None:
                key, value = setting
                given = "--set" if key in sets else "--knob" if value in knobs.get(key, ()) else "--reference"
                via = f" with {given} {key}={value}"
            check_not_input(out, [path], option, what=f"a file the graph reads{via}")
