"""``flowtex plot OUT.npz``: a quick look at a run's outputs (flowtex.plotting)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from .output import note


def register(sub: Any) -> None:
    p = sub.add_parser("plot", help="plot a run's outputs: time series, vibration spectrograms, force-speed trace")
    p.add_argument("file", help="output file of a run (.npz, .csv, .h5)")
    p.add_argument("--signals", nargs="+", help="signals to show (default: all)")
    p.add_argument("-o", "--output", help="PNG to write (default: FILE with .png)")
    p.set_defaults(func=cmd_plot)


def cmd_plot(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output
    from ..plotting import plot_recording

    out = Path(args.output) if args.output else Path(args.file).with_suffix(".png")
    check_output(out, inputs=[args.file], option="-o", suffixes=(".png",))
    n = plot_recording(args.file, args.signals, out, warn=lambda line: note(f"warning: {args.file}: {line}"))
    note(f"{args.file}: {n} signals -> {out}")
    return 0
