"""``flowtex models resample IN --rate HZ -o OUT``: change a texture model set's sample rate (argparse wiring)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    """Add ``flowtex models`` with its ``resample`` action."""
    p = subparsers.add_parser("models", help="operate on texture model sets (resample)",
                              description="Transform texture model sets (HaTT XML or native JSON).")
    actions = p.add_subparsers(dest="models_action", required=True, metavar="ACTION")
    r = actions.add_parser("resample", help="resample every model to another sample rate",
                           description="Resample each model of IN on its own to --rate, keeping its physical PSD below "
                                       "min(old, new) Nyquist and adding nothing above it (docs/fitting.md).")
    r.add_argument("input", metavar="IN", help="model set: HaTT .xml or native flowtex .json")
    r.add_argument("--rate", type=float, required=True, metavar="HZ", help="target sample rate in Hz")
    r.add_argument("-o", "--output", required=True, metavar="OUT", help="native model-set JSON to write")
    r.add_argument("--keep-order", action="store_true",
                   help="keep the models' (p, q) when upsampling by more than 2x (cheaper to render, less exact)")
    r.add_argument("--extra-order", type=int, metavar="N",
                   help="when upsampling, give every model N (even, 0-12) more poles and zeros (default: the fewest of "
                        "0, 2, 4, 6, 8 with which every model keeps its spectrum)")
    r.add_argument("--allow-misses", action="store_true",
                   help="write the set even if some model misses LSD <= 0.5 dB / band power within 2 %% (named in a warning); "
                        "without it such a set is not written and the command fails")
    r.set_defaults(func=cmd_resample)


def cmd_resample(args: Any) -> int:
    from ..io.modelset import load_model_set, save_model_set
    from .resample import check_misses, resample_model_set, tqdm_progress

    ms = load_model_set(args.input)
    progress, close = tqdm_progress(ms.num_models, "resample")
    try:
        out = resample_model_set(ms, args.rate, progress, keep_order=args.keep_order, extra_order=args.extra_order)
    finally:
        close()
    warning = check_misses(out, args.allow_misses, str(args.input))
    target = Path(args.output).expanduser()
    fd, tmp = tempfile.mkstemp(prefix=target.name + ".", suffix=".tmp", dir=target.parent if str(target.parent) else ".")
    os.close(fd)
    try:
        save_model_set(out, tmp)
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    info = out.metadata["resample"]
    (p0, q0), (p, q) = info["from_order"], info["to_order"]
    orders = f"orders {p0}/{q0}" + (f" -> {p}/{q}" if (p, q) != (p0, q0) else "")
    if info["extra_order"]:
        orders += f" ({info['extra_order']} more poles and zeros)"
    print(f"{args.input}: {ms.num_models} models {info['from_hz']:g} Hz -> {info['to_hz']:g} Hz, {orders}, written to {target}; "
          f"worst LSD {info['worst_lsd_db']:.2f} dB, worst band-power error {100 * info['worst_band_power_error']:.2f} % "
          f"(up to 0.9 x the lower Nyquist)"
          + (f", worst power above the old Nyquist {100 * info['worst_power_above_old_nyquist']:.2f} %" if info["to_hz"] > info["from_hz"] else ""))
    if warning:
        print(warning + (" (--keep-order: upsampling by more than 2x needs the higher order; see docs/fitting.md)"
                         if args.keep_order else " (see docs/fitting.md)"))
    return 0
