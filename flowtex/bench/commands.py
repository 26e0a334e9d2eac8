"""``flowtex bench``: speed against error of knob settings (docs/bench.md). Registered from flowtex/cli.py."""

from __future__ import annotations

import argparse
import contextlib
import csv
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("bench", help="sweep knobs: ns/tick against output error, Pareto front",
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
    p.add_argument("--repeats", type=int, default=5, help="timed runs per configuration (median; default 5)")
    p.add_argument("--seed", type=int, help="noise seed (default: the graph's)")
    p.add_argument("-o", "--output", help="write the table as CSV")
    p.add_argument("--plot", help="draw the Pareto plot to this PNG (needs matplotlib: pip install 'flowtex[plot]')")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="run the configurations on a local Dask cluster of N worker processes")
    where.add_argument("--scheduler", help="run the configurations on an existing Dask cluster (scheduler address, e.g. tcp://host:8786)")
    p.add_argument("--plugins", action="append", default=[], metavar="DIR")
    p.add_argument("--compile", choices=("dispatch", "fused"), default="dispatch",
                   help="dispatch (default): shape knobs (every, plan) compile nothing new once the node types are cached; "
                        "fused: compile each configuration's own tick (seconds each; fastest ticks). docs/engine.md")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    from ..errors import DataError, FlowtexError
    from ..graph.spec import parse_override
    from ..io.recordings import load_recording
    from .sweep import default_metric, format_table, parse_knob, sweep, table

    if not args.knob:
        raise FlowtexError("flowtex bench: give at least one --knob NODE.PARAM=V1,V2,...")
    knobs = dict(parse_knob(k) for k in args.knob)
    reference = dict(parse_override(r) for r in args.reference)
    if args.plot:
        _need_matplotlib()
    rec = load_recording(args.input)
    with _dask_client(args) as client:
        configs, outputs = sweep(args.graph, dict(rec.arrays), knobs, reference, args.outputs, args.metric, max(1, args.repeats),
                                 args.seed, tuple(args.plugins), client=client, tier=args.compile)
    if not configs:
        raise DataError("no configuration to run")
    from .sweep import build

    units = build(args.graph, configs[0].values, tuple(args.plugins), args.compile).outputs
    metrics = {o: args.metric or default_metric(units[o].unit) for o in outputs}
    rows = table(configs, outputs, metrics)
    print(format_table(rows))
    print(f"* = Pareto front over (ns/tick, {outputs[0]} {metrics[outputs[0]]})")
    if args.output:
        with open(args.output, "w", newline="") as fh:
            csv.writer(fh).writerows(rows)
    if args.plot:
        pareto_plot(configs, outputs[0], metrics[outputs[0]], Path(args.plot))
    return 0


@contextlib.contextmanager
def _dask_client(args: argparse.Namespace) -> Iterator[Any]:
    """A Dask client for --workers / --scheduler, else None (configurations run in this process)."""
    if not (args.workers or args.scheduler):
        yield None
        return
    from dask.distributed import Client, LocalCluster

    if args.scheduler:
        with Client(args.scheduler) as client:
            yield client
        return
    with LocalCluster(n_workers=max(1, args.workers), threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        yield client


def _need_matplotlib() -> None:
    from ..errors import FlowtexError

    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise FlowtexError("plots need matplotlib: pip install 'flowtex[plot]'") from None


def pareto_plot(configs: list, output: str, metric: str, path: Path) -> None:
    """ns/tick against error, Pareto front joined and labelled."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    x = [c.ns_per_tick for c in configs]
    y = [c.errors[output] for c in configs]
    ax.scatter(x, y, color="0.6", label="configuration")
    front = sorted((c for c in configs if c.pareto), key=lambda c: c.ns_per_tick)
    ax.plot([c.ns_per_tick for c in front], [c.errors[output] for c in front], "o-", color="C3", label="Pareto front")
    for c in front:
        ax.annotate(", ".join(f"{k}={v}" for k, v in c.values.items()), (c.ns_per_tick, c.errors[output]), fontsize=7,
                    xytext=(4, 4), textcoords="offset points")
    ax.set_xlabel(f"ns/tick ({configs[0].timed_on})")
    ax.set_ylabel(f"{output} error ({ {'lsd': 'LSD, dB', 'gfc': '1 - GFC'}.get(metric, metric.upper())})")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"Pareto plot -> {path}", file=sys.stderr)
