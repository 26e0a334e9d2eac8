"""``flowtex watch GRAPH --input REC``: rerun on every edit of the graph, its model files or its plugins."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .options import add_compile_option, add_graph_options, int_at_least, number_in_range, overrides
from .output import say


def register(sub: Any) -> None:
    p = sub.add_parser("watch", help="rerun a graph over a recording whenever the graph, its model files or its plugins change")
    p.add_argument("graph")
    p.add_argument("--input", "-i", required=True, help="recording: .npz, .csv, .h5")
    p.add_argument("--output", "-o", help="output file rewritten by every run (.npz, .csv, .h5)")
    p.add_argument("--plot", metavar="PNG", help="PNG of the outputs, refreshed by every run (needs the plot extra)")
    p.add_argument("--interval", type=lambda t: number_in_range(t, 0.05, 60.0, unit="s"), default=0.5, metavar="S",
                   help="seconds between checks of the files' modification times (0.05..60, default 0.5)")
    p.add_argument("--max-runs", type=int_at_least(1, 1_000_000), metavar="N",
                   help="stop after N runs, the first included (default: until Ctrl-C)")
    add_compile_option(p, "auto")
    add_graph_options(p)
    p.set_defaults(func=cmd_watch)


def _say_now(line: str) -> None:
    """One report line, flushed at once (watch's output is read live, often through a pipe)."""
    say(line)
    sys.stdout.flush()


def _png_writer(path: Path) -> Callable[[dict, Any, int], None]:
    """A ``Watcher.plot`` that rewrites the PNG ``path`` (atomically) with the run's outputs."""
    from ..io.atomic import atomic_output
    from ..plotting import plot_signals

    def plot(outputs: dict, graph: Any, run: int) -> None:
        units = {name: spec.unit for name, spec in graph.outputs.items()}
        with atomic_output(path) as tmp:
            plot_signals(outputs, units, graph.rate, Path(tmp), title=f"{graph.name}: run {run}",
                         warn=lambda line: _say_now(f"  --plot {path}: {line}"))

    return plot


def cmd_watch(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output
    from ..runtime.watch import Watcher
    from .run import RECORDING_SUFFIXES

    check_output(args.output, inputs=[args.graph, args.input], option="-o", suffixes=RECORDING_SUFFIXES)
    check_output(args.plot, inputs=[args.graph, args.input], option="--plot", suffixes=(".png",), others={"-o": args.output})
    watcher = Watcher(Path(args.graph), Path(args.input), Path(args.output) if args.output else None,
                      emit=_say_now, overrides=overrides(args.overrides), plugins=tuple(args.plugins),
                      auto_plugins=not args.no_plugins, tier=args.compile, plot=_png_writer(Path(args.plot)) if args.plot else None,
                      plot_path=Path(args.plot) if args.plot else None)
    watcher.loop(args.interval, args.max_runs)
    return 1 if watcher.latest is not None and watcher.latest.error else 0  # --max-runs ended it: did the last run fail?
