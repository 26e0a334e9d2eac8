"""``flowtex resample IN --rate HZ -o OUT``: every signal of a recording at another rate (flowtex.io.recording_resample)."""

from __future__ import annotations

import argparse
from typing import Any

from ..io.formats import AUDIO, suffixes
from .options import add_from_rate, number_in_range, positive_hz
from .output import say
from .run import RECORDING_SUFFIXES

AUDIO_SUFFIXES = suffixes(AUDIO)


def register(sub: Any) -> None:
    from ..dsp.resample import DEFAULT_ATTEN_DB

    p = sub.add_parser("resample", help="resample every signal of a recording to another rate (zero delay)",
                       description="Resample every signal of recording IN (.npz/.csv/.h5) to --rate Hz with a "
                                   "Kaiser-window polyphase filter; zero delay, length n*rate/from_rate rounded.")
    p.add_argument("input", metavar="IN", help="recording to read (.npz/.csv/.h5)")
    p.add_argument("--rate", type=positive_hz, required=True, metavar="HZ",
                   help="target rate in Hz (the rate it produces; at most 64x up or down)")
    add_from_rate(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT", help="recording to write (.npz/.csv/.h5)")
    p.add_argument("--atten-db", type=lambda t: number_in_range(t, 20.0, 200.0, unit="dB"), default=DEFAULT_ATTEN_DB,
                   help=f"attenuation of aliases and images in dB (20..200, default {DEFAULT_ATTEN_DB:g})")
    p.set_defaults(func=cmd_resample)


def cmd_resample(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output
    from ..io.recording_resample import resample_recording

    check_output(args.output, inputs=[args.input], option="-o", suffixes=(*RECORDING_SUFFIXES, *AUDIO_SUFFIXES))
    say(resample_recording(args.input, args.output, args.rate, args.from_rate, args.atten_db))
    return 0
