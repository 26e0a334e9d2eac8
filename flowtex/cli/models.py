"""``flowtex models resample IN --rate HZ -o OUT``: a texture model set at another sample rate (flowtex.fit.resample)."""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import DataError
from .options import int_at_least, positive_hz
from .output import note, say


def register(sub: Any) -> None:
    """Add ``flowtex models`` with its ``resample`` action."""
    from ..fit.resample import MAX_EXTRA_ORDER
    from ..fit.resample_densify import AUTO

    p = sub.add_parser("models", help="operate on texture model sets and tap libraries (resample)",
                       description="Transform texture model sets (HaTT XML or native JSON).")
    actions = p.add_subparsers(dest="models_action", required=True, metavar="ACTION", parser_class=type(p))
    r = actions.add_parser("resample", help="resample every model to another sample rate",
                           description="Resample each model of IN on its own to --rate, keeping its physical PSD below "
                                       "min(old, new) Nyquist and adding nothing above it (docs/fitting.md).")
    r.add_argument("input", metavar="IN", help="model set: HaTT .xml or native flowtex .json")
    r.add_argument("--rate", type=positive_hz, required=True, metavar="HZ",
                   help="target sample rate in Hz (the rate it produces; at most 16x up or down)")
    r.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="model set to write: .json (native, with the resampling record) or .xml (HaTT)")
    r.add_argument("--keep-order", action="store_true",
                   help="keep the models' (p, q) when upsampling by more than 2x (cheaper to render, less exact)")
    r.add_argument("--extra-order", type=int_at_least(0, MAX_EXTRA_ORDER), metavar="N",
                   help=f"give every model exactly N (even, 0..{MAX_EXTRA_ORDER}) more poles and zeros and no elliptic edge "
                        "(default: the first with which every model keeps its spectrum of: the own order, then up to 2x "
                        "up an elliptic lowpass edge at the old Nyquist, then 2, 4 more without and with it, 6, 8 more; beyond 2x "
                        "0..8 more; down 2, 4 more)")
    r.add_argument("--densify", type=_densify_value, default=AUTO, metavar="auto|N",
                   help="add models between the measured ones (the models the set itself renders there: it renders as "
                        "before at its own rate) so that the resampled set follows its original between the models too: "
                        "'auto' (default) adds edge midpoints only where the resampled set departs from the original, "
                        "while its path LSD exceeds 0.4 dB, up to 3 levels; N (0..3) adds every edge midpoint N times "
                        "(each about 4x the models; 0: none) (docs/fitting.md)")
    r.add_argument("--allow-misses", action="store_true",
                   help="write the set even if some model misses LSD <= 0.5 dB / band power within 2 %% (named in a warning); "
                        "without it such a set is not written and the command fails")
    r.set_defaults(func=cmd_models_resample)


def _densify_value(text: str) -> int | str:
    """argparse type of ``--densify``: 'auto' or a number of levels 0..MAX_LEVELS."""
    from ..fit.resample_densify import AUTO
    from ..models.densify import MAX_LEVELS

    if text == AUTO:
        return AUTO
    try:
        return int_at_least(0, MAX_LEVELS)(text)
    except argparse.ArgumentTypeError as exc:
        raise argparse.ArgumentTypeError(f"{exc}; or '{AUTO}'") from None


def cmd_models_resample(args: argparse.Namespace) -> int:
    from ..fit.resample import check_misses, resample_summary, tqdm_progress
    from ..fit.resample_densify import densify_summary, resample_densified
    from ..fit.resampled_band import band_lost_in_xml
    from ..io.atomic import atomic_output, check_output
    from ..io.hatt import rule_lost_in_xml, texture_index, write_hatt_xml
    from ..io.modelset import load_model_set, save_model_set

    target = check_output(args.output, inputs=[args.input], option="-o")
    if _resample_taps(args, target):
        return 0
    if target.suffix.lower() not in (".json", ".xml"):
        raise DataError(f"-o {args.output}: write the resampled set as .json (flowtex's format, with the resampling "
                        "record) or .xml (HaTT's format)")
    original = load_model_set(args.input)
    texture = texture_index(original) if target.suffix.lower() == ".xml" else 0  # a bad one refused before the work
    progress, close = tqdm_progress(original.num_models, "resample")
    try:
        ms, out = resample_densified(original, args.rate, args.densify, progress, keep_order=args.keep_order,
                                     extra_order=args.extra_order)
    finally:
        close()
    added = densify_summary(str(args.input), original, ms)
    if added:
        say(added)
    check_misses(out, args.allow_misses, str(args.input))  # refuses (FlowtexError naming the models) unless --allow-misses
    with atomic_output(target) as tmp:
        if target.suffix.lower() == ".xml":
            write_hatt_xml(out, tmp, texture=texture)
        else:
            save_model_set(out, tmp)
    line, warning = resample_summary(args.input, ms, out, str(target), args.keep_order)
    say(line)
    if warning:
        say(warning)
    if target.suffix.lower() == ".xml":
        for lost in (rule_lost_in_xml(out.rule, target), band_lost_in_xml(out, target)):
            if lost:
                note(lost)
    return 0


def _resample_taps(args: argparse.Namespace, target: Any) -> bool:
    """A tap library (``flowtex fit taps``) as input: resample its transients to ``--rate``, write it; False for a model set."""
    from ..errors import FlowtexError
    from ..io.atomic import atomic_output
    from ..io.taplib import read_tap_library, write_tap_library
    from ..models.taps import resample_tap_library

    try:
        lib = read_tap_library(args.input)
    except FlowtexError:
        return False                     # not a tap library: the model-set reader gives the error, if any
    if target.suffix.lower() != ".json":
        raise DataError(f"-o {args.output}: a tap library is written as .json")
    out = resample_tap_library(lib, args.rate)
    with atomic_output(target) as tmp:
        write_tap_library(tmp, out, notes=f"resampled by flowtex models resample from {lib.sample_rate_hz:g} Hz")
    say(f"{args.input}: tap library ({len(lib.speeds)} taps) {lib.sample_rate_hz:g} Hz -> {args.rate:g} Hz, written to {target}")
    return True
