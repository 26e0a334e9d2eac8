"""``flowtex fit KIND``: friction, taps, pattern and compliance here; texture in fit_texture.py.

Vocabulary (docs/cli.md): ``--force`` is the normal force (N) in every kind; ``--force3`` a 3-axis force;
``--from-rate`` the rate of a recording that states none (the old ``--rate`` still works, with a notice).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from ..errors import DataError, FlowtexError
from . import fit_texture
from .options import Renamed, add_from_rate, int_at_least, number_in_range, one_motion_source, positive_seconds
from .output import note, say


def register(sub: Any) -> None:
    p = sub.add_parser("fit", help="fit models (texture, friction, taps, pattern, compliance) to recordings",
                       description="Turn recordings into models that flowtex's nodes render.")
    kinds = p.add_subparsers(dest="fit_kind", required=True, metavar="KIND", parser_class=type(p))
    for add in (_pattern, _compliance, fit_texture.register_fit, _friction, _taps):
        add(kinds)


def nonneg(unit: str) -> Any:
    return lambda text: number_in_range(text, 0.0, math.inf, unit=unit)


def highpass_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--highpass", type=nonneg("Hz"), default=10.0, metavar="HZ",
                   help="zero-phase high-pass of the acceleration (0: none; below half the recording's rate)")


def _friction(kinds: Any) -> None:
    from ..fit.friction import DEFAULT_MIN_FORCE_N, NOISE_MODELS

    p = kinds.add_parser("friction", help="kinetic friction coefficient mu from normal and tangential forces",
                         description="Robust line through the origin of tangential vs normal force (samples in contact only), "
                                     "with the share of the tangential force the normal force explains (r2).")
    p.add_argument("recording", type=Path, help="recording (.npz, .csv, .h5)")
    p.add_argument("--force", dest="normal_force", metavar="N", help="normal force signal (N)")
    p.add_argument("--normal-force", dest="normal_force", action=Renamed, new="--force", meaning="the normal force in N",
                   help=argparse.SUPPRESS)
    p.add_argument("--friction-force", metavar="T", help="tangential (friction) force signal (N): 1-D magnitude or (n, 3)")
    p.add_argument("--force3", metavar="F3", help="3-axis force signal (N), split into normal and tangential by --normal")
    p.add_argument("--normal", metavar="V", help="surface normal: a (n, 3) signal or a vector x,y,z")
    add_from_rate(p, old_rate=True)
    p.add_argument("--min-force", type=nonneg("N"), default=DEFAULT_MIN_FORCE_N, help="in contact from this normal force (N, >= 0)")
    p.add_argument("--offset", choices=("yes", "no"), default="no",
                   help="no (default): HaTT's line through the origin, T = mu N; yes: T = mu N + b (cannot be stored with --into)")
    p.add_argument("--noise", choices=NOISE_MODELS, default="force",
                   help="force (default): the residual scale is a power law in the normal force, as real friction noise "
                        "grows with force; constant: one scale for every sample")
    p.add_argument("-o", "--output", required=True, type=Path, help="output JSON (mu, mu_ci, ...)")
    p.add_argument("--into", metavar="SURFACE", help="also store mu in this model set (native JSON or HaTT XML), keeping its mode")
    p.set_defaults(func=cmd_fit_friction)


def cmd_fit_friction(args: argparse.Namespace) -> int:
    from ..fit.friction import fit_friction_recording, friction_table, store_mu
    from ..io.atomic import check_output, write_json_atomic
    from ..io.modelset import load_model_set

    force3 = args.force3
    if force3 is None and args.normal_force is not None and args.normal is not None and args.friction_force is None:
        note("notice: --force with --normal is the old spelling of --force3 (a 3-axis force); read as --force3")
        force3, args.normal_force = args.normal_force, None
    with_offset = args.offset == "yes"
    if with_offset and args.into:
        raise DataError(f"--into {args.into}: a model set stores mu only, so the offset of --offset yes would be dropped and "
                        "the rendered friction would be wrong; fit without --offset (HaTT's line through the origin) to store mu")
    check_output(args.output, inputs=[args.recording, args.into], option="-o", suffixes=(".json",))
    if args.into is not None:
        load_model_set(args.into)  # refuse a missing or broken model set before any work
        check_output(args.into, inputs=[args.recording], option="--into", create_folders=False)
    fit, doc = fit_friction_recording(args.recording, args.from_rate, args.normal_force, args.friction_force, force3,
                                      args.normal, args.min_force, with_offset, args.noise)
    for line in friction_table(fit):
        say(line)
    if args.into:
        store_mu(args.into, fit.mu)
        say(f"mu = {fit.mu:.4f} stored in {args.into}")
    write_json_atomic(args.output, doc)
    say(f"-> {args.output}")
    return 0


def _taps(kinds: Any) -> None:
    from ..dsp.contact import CONTACT_OFF_N
    from ..fit.taps import DEFAULT_QUIET_S, MAX_TAP_S

    p = kinds.add_parser("taps", help="tap library (100 ms transients by incoming speed) from a recording of taps",
                         description="Detect contact onsets, cut 100 ms after each, label by incoming speed (Culbertson & Kuchenbecker 2017).")
    p.add_argument("recording", type=Path)
    p.add_argument("--accel", required=True, metavar="A", help="acceleration (m/s^2): 1-D or 3 axes (DFT321)")
    p.add_argument("--force", required=True, metavar="F", help="normal force (N)")
    p.add_argument("--position", metavar="P", help="tool position (mm, 3 axes): incoming speed from it")
    p.add_argument("--normal", metavar="N", help="surface normal signal for --position (default +z)")
    p.add_argument("--speed", metavar="S", help="approach speed signal (mm/s), instead of --position")
    add_from_rate(p, old_rate=True)
    p.add_argument("--length", type=positive_seconds(MAX_TAP_S), default=0.1,
                   help=f"seconds cut after each onset (0 < S <= {MAX_TAP_S:g}, at least one sample; Culbertson & Kuchenbecker 2017: 0.1)")
    highpass_option(p)
    p.add_argument("--quiet", type=lambda t: number_in_range(t, 0.0, MAX_TAP_S, unit="s"), default=DEFAULT_QUIET_S, metavar="S",
                   help=f"seconds without contact (force < {CONTACT_OFF_N:g} N) before an onset counts as a tap (0..{MAX_TAP_S:g})")
    p.add_argument("--name", help="library name (default: the file's stem)")
    p.add_argument("-o", "--output", required=True, type=Path, help="tap library JSON (docs/tap-library.md)")
    p.set_defaults(func=cmd_fit_taps)


def cmd_fit_taps(args: argparse.Namespace) -> int:
    from ..fit.taps import fit_tap_recording, tap_table, write_taps
    from ..io.atomic import check_output

    one_motion_source(args)
    check_output(args.output, inputs=[args.recording], option="-o", suffixes=(".json",))
    lib, taps, notes, rate = fit_tap_recording(args.recording, args.accel, args.force, args.from_rate, args.position, args.normal,
                                               args.speed, args.length, args.highpass, args.name, args.quiet)
    for line in tap_table(taps, notes, lib, rate):
        say(line)
    write_taps(args.output, lib, args.recording)
    say(f"-> {args.output}")
    return 0


def _pattern(kinds: Any) -> None:
    p = kinds.add_parser("pattern", help="patterned texture: features + Prony/IIR ring-downs (Guruswamy thesis ch. 4)",
                         description="Fit a patterned texture to REC: one IIR filter per surface feature, at its position along the path.")
    p.add_argument("recording", metavar="REC", help="recording (.npz/.csv/.h5)")
    p.add_argument("--accel", required=True, metavar="A", help="signal name of the acceleration (m/s^2, 1 to 3 axes)")
    p.add_argument("--position", required=True, metavar="P", help="signal name of the tool position (mm, 3 components)")
    p.add_argument("--speed", metavar="S", help="signal name of the speed (mm/s); only reported (features are placed by position)")
    p.add_argument("-o", "--output", required=True, metavar="PATTERN.json", help="pattern file to write (docs/pattern-format.md)")
    add_from_rate(p, old_rate=True)
    p.add_argument("--max-order", type=int_at_least(2, 30), default=8, help="highest filter order N = M tried (2..30, default 8)")
    p.set_defaults(func=cmd_fit_pattern)


def cmd_fit_pattern(args: argparse.Namespace) -> int:
    from ..fit.pattern import fit_pattern_recording, pattern_summary
    from ..io.atomic import check_output
    from ..io.patternfile import write_pattern

    check_output(args.output, inputs=[args.recording], option="-o", suffixes=(".json",))
    pat = fit_pattern_recording(args.recording, args.accel, args.position, args.from_rate, args.speed, args.max_order)
    write_pattern(args.output, pat)
    say(f"{args.output}: {pattern_summary(pat)}")
    return 0


def _compliance(kinds: Any) -> None:
    from ..dsp.contact import CONTACT_ON_N

    p = kinds.add_parser("compliance", help="WHaT compliance k_c from stroking (force vs RMS vibration, Guruswamy thesis sec. 5.2)",
                         description="Estimate the compliance coefficient k_c (0 soft .. 1 stiff) of the stroked surface in REC. "
                                     "An estimate that is not valid (smooth surface, poor fit) is still written, with a reason.")
    p.add_argument("recording", metavar="REC", help="recording (.npz/.csv/.h5)")
    p.add_argument("--force", required=True, metavar="F", help="signal name of the normal force (N)")
    p.add_argument("--accel", required=True, metavar="A", help="signal name of the acceleration (m/s^2, 1 or 3 axes)")
    p.add_argument("--contact", metavar="C", help="signal name of a 0/1 contact state (default: force above --force-threshold)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.json", help="result file (JSON)")
    add_from_rate(p, old_rate=True)
    p.add_argument("--kg", type=lambda t: number_in_range(t, 0.0, math.inf, low_open=True, unit="N per m/s^2"), default=1.0,
                   help="k_g normalisation in N per m/s^2 (> 0; Guruswamy thesis eq. 6; default 1)")
    p.add_argument("--force-range", type=nonneg("N"), nargs=2, metavar=("LO", "HI"),
                   help="force range of the 24 bins in N (default: the range of the contact samples' low-passed force)")
    p.add_argument("--force-threshold", type=nonneg("N"), default=CONTACT_ON_N,
                   help=f"contact when the low-passed force exceeds this (N, default {CONTACT_ON_N:g})")
    p.add_argument("--smooth-floor", type=nonneg("m/s^2"), default=0.1, help="RMS vibration floor of a smooth surface (m/s^2, default 0.1)")
    p.add_argument("--r2-min", type=lambda t: number_in_range(t, 0.0, 1.0), default=0.8,
                   help="least weighted R^2 of a valid line fit (0..1, default 0.8)")
    p.set_defaults(func=cmd_fit_compliance)


def cmd_fit_compliance(args: argparse.Namespace) -> int:
    from ..fit.compliance import compliance_recording, compliance_summary
    from ..io.atomic import check_output, write_json_atomic

    if args.force_range and not args.force_range[0] < args.force_range[1]:
        raise FlowtexError(f"--force-range {args.force_range[0]:g} {args.force_range[1]:g}: LO must be below HI (N)")
    check_output(args.output, inputs=[args.recording], option="-o", suffixes=(".json",))
    result = compliance_recording(args.recording, args.force, args.accel, args.from_rate, args.contact,
                                  tuple(args.force_range) if args.force_range else None, k_g=args.kg,
                                  force_threshold=args.force_threshold, smooth_floor=args.smooth_floor, r2_min=args.r2_min)
    write_json_atomic(args.output, result)
    say(f"{args.output}: {compliance_summary(result)}")
    return 0
