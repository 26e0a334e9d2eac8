"""``flowtex fit texture``: one recording (-o), a Romano-2012 grid (--grid) or many recordings (--out-dir)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from ..errors import DataError
from ..limits import signed
from .options import add_from_rate, int_at_least, number_in_range, one_motion_source, positive_hz, scheduler_address
from .output import note, say


def register_fit(kinds: Any) -> None:
    """Add ``flowtex fit texture``."""
    from ..io.recordings import SUFFIXES

    p = kinds.add_parser("texture", help="texture model set (ARMA models over speed and force) from free exploration",
                         description="Segment free exploration into stationary pieces, fit one ARMA model per piece at one "
                                     "order shared by the material, and assemble a Delaunay model set (docs/fitting.md).")
    p.add_argument("recordings", nargs="*", help=f"recording(s) ({', '.join(SUFFIXES)}), folders or glob patterns")
    p.add_argument("--accel", default="accel", metavar="A", help="acceleration signal (m/s^2): 1-D, or 3 axes reduced by DFT321")
    p.add_argument("--speed", metavar="S", help="tangential speed signal (mm/s)")
    p.add_argument("--force", default="normal_force", metavar="F", help="normal force signal (N)")
    p.add_argument("--position", metavar="P", help="tool position (mm, 3 axes): speed from it, as speed_estimator does")
    p.add_argument("--normal", metavar="N", help="surface normal signal (3 axes) for --position (default +z)")
    add_from_rate(p, old_rate=True)
    p.add_argument("--order", default="auto", help="auto (BIC, shared by all pieces) or P,Q")
    p.add_argument("--max-order", type=int_at_least(1, 40), default=20, help="largest p and q searched by --order auto (1..40)")
    p.add_argument("--highpass", type=lambda t: number_in_range(t, 0.0, math.inf, unit="Hz"), default=10.0, metavar="HZ",
                   help="zero-phase high-pass of the acceleration (0: none; below half the recording's rate)")
    p.add_argument("--pool", type=int_at_least(1, 20), metavar="K",
                   help="fit each model of a free exploration on its piece and the K-1 pieces nearest to it in speed and "
                        "force, which pools the loudness that wanders from second to second (1..20, default 5; 1 fits every "
                        "piece alone; docs/fitting.md)")
    p.add_argument("--render-rate", type=positive_hz, metavar="HZ",
                   help="resample the models to this rate before writing (at most 16x the recording's rate, up or down)")
    p.add_argument("--allow-misses", action="store_true",
                   help="with --render-rate: write the set even if some resampled model misses its spectrum (else refused)")
    p.add_argument("--material", help="surface name (default: the file's stem)")
    p.add_argument("-o", "--output", type=Path, help="output model set (native JSON)")
    p.add_argument("--xml", type=Path, help="also write HaTT XML (with --out-dir: one .xml beside each .json)", nargs="?",
                   const=Path("-"))
    p.add_argument("--report", metavar="DIR", help="write a markdown report with plots into this folder (with --out-dir: "
                                                   "DIR/<name>_report per recording)")
    p.add_argument("--holdout", type=lambda t: number_in_range(t, 0.0, 1.0, low_open=True, high_open=True), metavar="FRACTION",
                   help="hold out FRACTION of the recording (see --holdout-split), fit the rest and compare the fit with "
                        "the held-out part (as flowtex compare does)")
    p.add_argument("--holdout-split", choices=("tail", "blocks"), default="tail",
                   help="with --holdout: hold out the last FRACTION (tail) or interleaved one-second blocks (blocks)")
    p.add_argument("--folds", type=int_at_least(2), metavar="K",
                   help="K-fold cross-validation over interleaved one-second blocks (block k held out by fold k mod K); "
                        "-o gets the fit of the whole recording")
    p.add_argument("--holdout-json", type=Path, metavar="OUT.json",
                   help="with --holdout or --folds: write {split, fraction or folds, results (one per fold), mean}")
    p.add_argument("--grid", metavar="INDEX.csv", help="Romano-2012 grid: CSV of file, speed, force (one stationary recording each)")
    p.add_argument("--out-dir", metavar="OUT", help="fit every recording given into OUT/<name>.json")
    p.add_argument("--workers", type=int_at_least(0), help="Dask workers on this machine for --out-dir (default: one per core)")
    p.add_argument("--scheduler", type=scheduler_address, metavar="tcp://HOST:8786", help="use this running Dask scheduler for --out-dir")
    p.set_defaults(func=cmd_fit_texture)


def _job(args: argparse.Namespace) -> Any:
    from ..fit.texture import TextureOptions
    from ..fit.texture_job import TextureJob, parse_order

    opt = TextureOptions(order=parse_order(args.order), max_order=args.max_order, highpass_hz=args.highpass)
    if args.pool is not None:
        opt.pool_pieces = args.pool
    return TextureJob(accel=args.accel, speed=args.speed, force=args.force, position=args.position, normal=args.normal,
                      rate=args.from_rate, options=opt, render_rate=args.render_rate, material=args.material,
                      allow_misses=args.allow_misses)


def check_report_folder(report: str | None, inputs: list, outputs: dict[str, Any] | None = None,
                        writes: tuple[str, ...] = ("report.md",)) -> None:
    """--report names a folder: refuse an existing file (or an input), the name of another output of the command
    (``outputs``: option -> file), or another output that is one of the files the report writes into it (``writes``:
    ``compare --json r/report.md --report r`` lost the JSON under the report), before any work."""
    from ..io.atomic import check_output

    if report is None:
        return
    path = Path(report).expanduser()
    if path.exists() and not path.is_dir():
        raise DataError(f"--report {report}: is a file; --report names a folder to write the report into")
    for option, file in (outputs or {}).items():
        if file is None:
            continue
        if Path(file).expanduser().resolve() == path.resolve():
            raise DataError(f"--report {report}: {option} writes that file; give the report a folder of its own")
        if any(Path(file).expanduser().resolve() == (path / name).resolve() for name in writes):
            raise DataError(f"{option} {file}: the report writes that file into {report}; give {option} another name "
                            "or the report another folder")
    check_output(path / "report.md", inputs=inputs, option="--report")


def _check_outputs(args: argparse.Namespace, inputs: list) -> None:
    from ..io.atomic import check_output

    check_output(args.output, inputs=inputs, option="-o")
    check_output(args.xml, inputs=inputs, option="--xml", others={"-o": args.output})
    if args.output is not None and Path(args.output).suffix.lower() == ".xml":
        raise DataError(f"-o {args.output}: -o writes flowtex's JSON model set; name it .json and give --xml "
                        f"{args.output} for HaTT's XML")
    if args.xml is not None and Path(args.xml).suffix.lower() == ".json":
        raise DataError(f"--xml {args.xml}: --xml writes HaTT's XML; name it .xml (-o writes the JSON)")
    from ..fit.report import REPORT_FILES

    check_report_folder(args.report, inputs, {"-o": args.output, "--xml": args.xml, "--holdout-json": args.holdout_json},
                        REPORT_FILES)


def cmd_fit_texture(args: argparse.Namespace) -> int:
    from ..fit.report import print_table, write_report
    from ..fit.texture_job import fit_grid_index, fit_recording, write_outputs

    one_motion_source(args)
    if args.out_dir is not None and args.output is not None:
        raise DataError(f"-o {args.output} and --out-dir {args.out_dir}: give one (-o for one recording's surface, --out-dir for "
                        "one surface per recording), not both")
    job = _job(args)
    _check_holdout_options(args)
    if args.xml == Path("-") and args.output is not None:
        args.xml = args.output.with_suffix(".xml")
    if args.grid is not None:
        if args.recordings:
            raise DataError("--grid INDEX.csv names the recordings itself; give no REC arguments with it")
        if args.output is None:
            raise DataError("--grid needs -o SURFACE.json")
        _check_outputs(args, [args.grid])
        fit = fit_grid_index(Path(args.grid), job)
        print_table(fit)
        written = write_outputs(fit, args.output, args.xml, job.render_rate, job.allow_misses)
        if args.report:
            write_report(fit, Path(args.report), written=written)
        say(f"-> {args.output}")
        _note_xml_losses(args.xml, written)
        return 0
    from ..fit.batch import expand_inputs, fit_many

    paths = expand_inputs(args.recordings)
    if args.out_dir is not None:
        from ..io.atomic import check_output

        if args.xml not in (None, Path("-")):
            raise DataError(f"--xml {args.xml}: with --out-dir each surface's XML is OUT/<name>.xml; give --xml without a "
                            "file name")
        check_output(Path(args.out_dir) / "x.json", inputs=paths, option="--out-dir")
        report_dir = None if args.report is None else Path(args.report)
        if report_dir is not None:
            check_report_folder(args.report, paths)
        code = fit_many(paths, job, Path(args.out_dir), args.workers, args.scheduler, args.xml is not None, report_dir)
        if args.xml is not None:
            from ..models.rendering import FITTED_RULE

            _note_xml_rule(Path(args.out_dir) / "*.xml", FITTED_RULE)
        return code
    if len(paths) != 1:
        raise DataError(f"{len(paths)} recordings given; fit several with --out-dir OUT (one surface file each), or give one with -o")
    if args.output is None:
        raise DataError("give -o SURFACE.json (or --out-dir OUT for many recordings)")
    _check_outputs(args, list(paths))
    from ..io.atomic import check_output

    check_output(args.holdout_json, inputs=list(paths), option="--holdout-json", others={"-o": args.output, "--xml": args.xml})
    held = None
    if args.holdout is not None or args.folds is not None:
        fit, held = _fit_holdout(paths[0], job, args)
    else:
        fit = fit_recording(paths[0], job)
        print_table(fit)
    written = write_outputs(fit, args.output, args.xml, job.render_rate, job.allow_misses)
    if held is not None and args.holdout_json is not None:
        from ..io.atomic import write_text_atomic

        write_text_atomic(args.holdout_json, json.dumps(held.doc, indent=1) + "\n")
        say(f"-> {args.holdout_json}")
    if args.report:
        write_report(fit, Path(args.report), held, written)
    say(f"-> {args.output}" + (f", {args.xml}" if args.xml else ""))
    _note_xml_losses(args.xml, written)
    return 0


def _note_xml_losses(xml: Path | None, written: Any) -> None:
    """Warn of what --xml could not keep of the set written: its rendering rule (flowtex.io.hatt.rule_lost_in_xml)
    and, resampled up with --render-rate, the band its models know (flowtex.fit.resampled_band.band_lost_in_xml)."""
    from ..fit.resampled_band import band_lost_in_xml
    from ..io.hatt import rule_lost_in_xml

    if xml is None:
        return
    for lost in (rule_lost_in_xml(written.rule, xml), band_lost_in_xml(written, xml)):
        if lost:
            note(lost)


def _note_xml_rule(xml: Path, rule: Any) -> None:
    """Warn that --xml could not keep the fitted sets' rendering rule (flowtex.io.hatt.rule_lost_in_xml)."""
    from ..io.hatt import rule_lost_in_xml

    lost = rule_lost_in_xml(rule, xml)
    if lost:
        note(lost)


def _check_holdout_options(args: argparse.Namespace) -> None:
    """--holdout, --folds and their companions: one recording, one kind of split, each option where it means something."""
    if args.holdout is not None and args.folds is not None:
        raise DataError("give --holdout FRACTION (one split) or --folds K (K-fold cross-validation), not both")
    held = args.holdout is not None or args.folds is not None
    if held and (args.grid is not None or args.out_dir is not None):
        raise DataError("--holdout/--folds compare one free-exploration recording with its own held-out part; "
                        "give one REC with -o (not --grid or --out-dir)")
    if args.holdout_json is not None and not held:
        raise DataError("--holdout-json writes the held-out comparison: give --holdout FRACTION or --folds K with it")
    if args.holdout_split != "tail" and args.holdout is None:
        raise DataError("--holdout-split chooses how --holdout FRACTION is held out; give --holdout with it "
                        "(--folds always uses interleaved one-second blocks)")


def _fit_holdout(path: Path, job: Any, args: argparse.Namespace) -> tuple[Any, Any]:
    """Fit the held-out split(s), print each comparison and the mean; returns (fit for -o, HeldOut)."""
    from ..fit.compare import summary_lines
    from ..fit.crossval import POOLED_LINE, describe_split, evaluate_splits, fold_splits, holdout_doc, holdout_split
    from ..fit.report import HeldOut, print_table
    from ..fit.texture_job import read_signals

    acc, speed, force, rate = read_signals(path, job)
    material, where, n = job.material or path.stem, str(path), acc.shape[0]
    if args.folds is not None:
        split, key, value = "blocks", "folds", args.folds
        splits = fold_splits(n, rate, args.folds, where)
    else:
        split, key, value = args.holdout_split, "fraction", args.holdout
        splits = [holdout_split(n, rate, args.holdout, split, where)]
    cv = evaluate_splits(acc, speed, force, rate, splits, job.options, material, where)
    if args.folds is not None:
        from ..fit.texture import fit_texture

        fit = fit_texture(acc, speed, force, rate, job.options, material, where)
    else:
        fit = cv.fits[0]
    print_table(fit)
    line = describe_split(split, key, value, n, rate)
    say(line)
    cmps = cv.comparisons
    for k, (c, own) in enumerate(zip(cmps, cv.in_sample, strict=True)):
        if len(cmps) > 1:
            say(f"fold {k}:")
        for text in summary_lines(c):
            say(text)
        say(f"  in-sample (the same surface on its training blocks): power ratio {signed(own.power_ratio_db, 2)} dB, "
            f"LSD {own.lsd_db:.2f} dB; held out minus in-sample: LSD {signed(c.lsd_db - own.lsd_db, 2)} dB")
    doc = holdout_doc(split, key, value, cmps, cv.pooled, cv.in_sample)
    if len(cmps) > 1:
        m = doc["mean"]
        say(f"mean over {len(cmps)} folds: power ratio {signed(m['power_ratio_db'], 2)} dB, LSD {m['lsd_db']:.2f} dB, GFC {m['gfc']:.3f}")
    if cv.pooled is not None:
        say(f"pooled over the folds ({POOLED_LINE}):")
        for text in summary_lines(cv.pooled)[1:]:
            say(text)
    return fit, HeldOut(line, cmps, doc)
