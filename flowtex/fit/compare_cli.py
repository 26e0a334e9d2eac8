"""``flowtex compare SURFACE REC``: how faithfully a surface renders a recording (thin wrapper of flowtex.fit.evaluate)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from .compare import CompareOptions, summary_lines
from .inputs import atomic_output
from .texture_cli import TextureJob


def run(args: argparse.Namespace) -> int:
    from .evaluate import compare_files

    if args.report is not None:
        from .compare_report import pyplot

        pyplot()                     # fail before the work when matplotlib is missing
    job = TextureJob(accel=args.accel, speed=args.speed, force=args.force, position=args.position, normal=args.normal,
                     rate=args.from_rate, rate_option="--from-rate")
    opt = CompareOptions(seeds=args.seeds, lookup={"outside": args.outside} if args.outside else {})
    cmp = compare_files(Path(args.surface), Path(args.recording), job, opt)
    for line in summary_lines(cmp):
        print(line)
    if args.json is not None:
        with atomic_output(args.json) as tmp:
            tmp.write_text(json.dumps({"surface": str(args.surface), "recording": str(args.recording)} | cmp.to_json(), indent=1)
                           + "\n", encoding="utf-8")
        print(f"-> {args.json}")
    if args.report is not None:
        from .compare_report import write_compare_report

        path = write_compare_report(cmp, Path(args.report), f"{Path(args.surface).name} along {Path(args.recording).name}")
        print(f"-> {path}")
    return 0


def register(subparsers: Any) -> None:
    """Add ``flowtex compare``."""
    from ..models.outside import OUTSIDE_CHOICES

    p = subparsers.add_parser("compare", help="render a surface along a recording's speed and force and compare (power, LSD, ...)",
                              description="Render SURFACE along REC's own speed and normal force and compare it with REC's "
                                          "acceleration: power ratio, LSD, GFC, spectral centroid and window-RMS correlation, "
                                          "overall and per 1-s window (docs/fitting.md).")
    p.add_argument("surface", metavar="SURFACE", help="model set: native .json or HaTT .xml")
    p.add_argument("recording", metavar="REC", help="recording with acceleration, speed and normal force")
    p.add_argument("--accel", default="accel", metavar="A", help="acceleration signal (m/s^2): 1-D, or 3 axes reduced by DFT321")
    p.add_argument("--speed", metavar="S", help="tangential speed signal (mm/s)")
    p.add_argument("--force", default="normal_force", metavar="F", help="normal force signal (N)")
    p.add_argument("--position", metavar="P", help="tool position (mm, 3 axes): speed from it, as speed_estimator does")
    p.add_argument("--normal", metavar="N", help="surface normal signal (3 axes) for --position (default +z)")
    p.add_argument("--from-rate", type=float, metavar="HZ", help="sample rate of a recording that states none")
    p.add_argument("--seeds", type=int, default=4, metavar="N", help="renders averaged (different excitation seeds)")
    p.add_argument("--outside", choices=OUTSIDE_CHOICES, help="texture_lookup's rule beyond the measured models (default: its own)")
    p.add_argument("--json", type=Path, metavar="OUT.json", help="write every figure, per window too, as JSON")
    p.add_argument("--report", metavar="DIR", help="write report.md with plots here (needs matplotlib)")
    p.set_defaults(func=run)
