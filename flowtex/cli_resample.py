"""``flowtex resample IN --rate HZ -o OUT``: bring every signal of a recording to another rate (any rational ratio).

Zero delay (signals stay aligned in time), length n * r2 / r1 rounded, Kaiser
polyphase filter (flowtex.dsp.resample), edges that keep linear trends (a
position ramp stays a ramp, docs/signal-nodes.md). The output states its new rate.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from .errors import DataError, FlowtexError


def register(subparsers: Any) -> None:
    """Add the ``resample`` subcommand."""
    from .dsp.resample import DEFAULT_ATTEN_DB

    p = subparsers.add_parser("resample", help="resample every signal of a recording to another rate (zero delay)",
                              description="Resample every signal of recording IN (.npz/.csv/.h5) to --rate Hz with a "
                                          "Kaiser-window polyphase filter; zero delay, length n*rate/from_rate rounded.")
    p.add_argument("input", metavar="IN", help="recording to read (.npz/.csv/.h5)")
    p.add_argument("--rate", type=float, required=True, metavar="HZ", help="target rate in Hz")
    p.add_argument("--from-rate", type=float, metavar="HZ", help="source rate in Hz, for a recording that states none")
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="recording to write (.npz/.csv/.h5)")
    p.add_argument("--atten-db", type=float, default=DEFAULT_ATTEN_DB,
                   help=f"attenuation of aliases and images in dB (default {DEFAULT_ATTEN_DB:g})")
    p.set_defaults(func=cmd_resample)


def cmd_resample(args: argparse.Namespace) -> int:
    import numpy as np

    from .dsp.resample import rational_ratio, resample_signal
    from .io.recordings import SUFFIXES, load_recording, save_recording

    src = Path(args.input)
    out = Path(args.output)
    if out.suffix.lower() not in SUFFIXES:
        raise DataError(f"{out}: unknown output format {out.suffix!r}; use .npz, .csv or .h5")
    rec = load_recording(src)
    rate_in = rec.rate
    if rate_in is None:
        if args.from_rate is None:
            raise DataError(f"{src}: the recording states no rate; give its rate with --from-rate HZ")
        rate_in = args.from_rate
    elif args.from_rate is not None and args.from_rate != rate_in:
        raise DataError(f"{src}: the recording states {rate_in:g} Hz but --from-rate says {args.from_rate:g} Hz; drop --from-rate")
    try:
        up, down = rational_ratio(rate_in, args.rate)
    except ValueError as exc:
        raise FlowtexError(f"{src}: {exc}") from None
    arrays = {}
    for name, a in rec.arrays.items():
        if not np.all(np.isfinite(a)):
            raise DataError(f"{src}: signal {name!r} has NaN or inf values; clean it before resampling")
        try:
            arrays[name] = resample_signal(a, rate_in, args.rate, atten_db=args.atten_db)
        except ValueError as exc:
            raise FlowtexError(f"{src}: signal {name!r}: {exc}") from None
    tmp = out.with_name(f".{out.stem}.partial{out.suffix}")
    try:
        save_recording(tmp, arrays, rate=args.rate)
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    print(f"{out}: {len(arrays)} signal(s), {rec.samples} samples at {rate_in:g} Hz -> "
          f"{next(iter(arrays.values())).shape[0] if arrays else 0} at {args.rate:g} Hz (x {up}/{down})")
    return 0
