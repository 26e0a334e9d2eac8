"""``flowtex compare SURFACE REC``: how faithfully a surface renders a recording (flowtex.fit.evaluate, flowtex.fit.compare)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ..limits import MAX_SEEDS
from .options import add_from_rate, int_at_least, one_motion_source
from .output import say


def register(sub: Any) -> None:
    """Add ``flowtex compare``."""
    from ..models.outside import OUTSIDE_CHOICES
    from ..models.rendering import INTERPOLATION_CHOICES

    p = sub.add_parser("compare", help="render a surface along a recording's speed and force and compare (power, LSD, ...)",
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
    add_from_rate(p)
    p.add_argument("--seeds", type=int_at_least(1, MAX_SEEDS), default=4, metavar="N",
                   help=f"renders averaged (different excitation seeds; 1..{MAX_SEEDS})")
    p.add_argument("--outside", choices=OUTSIDE_CHOICES,
                   help="texture_lookup's rule beyond the measured models (default: the set's own, docs/texture.md)")
    p.add_argument("--interpolation", choices=INTERPOLATION_CHOICES,
                   help="texture_lookup's loudness interpolation (default: the set's own, docs/texture.md)")
    p.add_argument("--json", type=Path, metavar="OUT.json", help="write every figure, per window too, as JSON")
    p.add_argument("--report", metavar="DIR", help="write report.md with plots into this folder (needs matplotlib)")
    p.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    from ..fit.compare import CompareOptions, summary_lines
    from ..fit.evaluate import compare_files
    from ..fit.texture_job import TextureJob
    from ..io.atomic import check_output, write_text_atomic
    from .fit_texture import check_report_folder

    one_motion_source(args)
    inputs = [args.surface, args.recording]
    check_output(args.json, inputs=inputs, option="--json")
    from ..fit.compare_report import FIGURES

    check_report_folder(args.report, inputs, {"--json": args.json}, ("report.md", *FIGURES))
    if args.report is not None:
        from ..fit.compare_report import pyplot

        pyplot()                     # fail before the work when matplotlib is missing
    job = TextureJob(accel=args.accel, speed=args.speed, force=args.force, position=args.position, normal=args.normal,
                     rate=args.from_rate)
    rule = {"outside": args.outside, "interpolation": args.interpolation}
    opt = CompareOptions(seeds=args.seeds, lookup={k: v for k, v in rule.items() if v})
    cmp = compare_files(Path(args.surface), Path(args.recording), job, opt)
    for line in summary_lines(cmp):
        say(line)
    if args.json is not None:
        doc = {"surface": str(args.surface), "recording": str(args.recording)} | cmp.to_json()
        write_text_atomic(args.json, json.dumps(doc, indent=1) + "\n")
        say(f"-> {args.json}")
    if args.report is not None:
        from ..fit.compare_report import write_compare_report

        say(f"-> {write_compare_report(cmp, Path(args.report), f'{Path(args.surface).name} along {Path(args.recording).name}')}")
    return 0
