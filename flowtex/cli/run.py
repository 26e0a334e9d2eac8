"""``flowtex run``: a graph offline over a recording, or the replay of a CAN session."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import FlowtexError
from ..io.formats import AUDIO, CAN_LOG, RECORDING, kind_of, suffixes
from .graph import load_graph_from_args
from .options import add_compile_option, add_graph_options, add_seed_option
from .output import note, say

REPLAY_SUFFIXES = suffixes(CAN_LOG)
RECORDING_SUFFIXES = suffixes(RECORDING)


def register(sub: Any) -> None:
    p = sub.add_parser("run", help="run a graph offline over a recording (or replay a CAN session)")
    p.add_argument("graph")
    p.add_argument("--input", "-i", required=True, help="recording: .npz, .csv, .h5; or a CAN session .blf/.log")
    p.add_argument("--output", "-o", help="output file: .npz, .csv, .h5, .wav (audio-rate, as --map's audio section plays it) "
                                          "(or .blf/.log/.wav when replaying)")
    add_seed_option(p)
    p.add_argument("--dbc", help="DBC file (replay of a CAN session)")
    p.add_argument("--map", help="signal map file (replay of a CAN session; its audio section for --output OUT.wav)")
    p.add_argument("--expect-audio", metavar="LIVE.wav", help="replay of a CAN session: check the replayed audio against the "
                                                              "session's --record-audio, frame by frame (exit 1 on any "
                                                              "unexplained difference)")
    p.add_argument("--nonfinite", choices=("error", "hold", "zero", "pass"), default="error",
                   help="NaN/inf in the recording: error (default; names signal, count, first index), "
                        "hold (last finite value), zero, or pass (unchanged)")
    p.add_argument("--nonfinite-outputs", choices=("warn", "error"), default="warn",
                   help="NaN/inf in the graph's outputs: warn (default; one line per output: NaN and inf counts, first tick) "
                        "or error (refuse; nothing written)")
    add_compile_option(p, "auto")
    add_graph_options(p)
    p.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    from ..io.atomic import check_output

    replay = kind_of(args.input) == CAN_LOG
    check_output(args.output, inputs=[args.graph, args.input, args.dbc, args.map, args.expect_audio], option="-o",
                 suffixes=(".npz", *suffixes(AUDIO), *REPLAY_SUFFIXES) if replay else (*RECORDING_SUFFIXES, *suffixes(AUDIO)))
    read: dict[str, Any] = {}

    def read_recording(resolved: Any) -> None:  # once the graph is checked, before its compile
        from ..io.recordings import check_writable
        from ..runtime.offline import load_recording_for

        read["recording"] = load_recording_for(resolved, args.input)
        if args.output:  # its outputs' names, before the run: the file's own entries are no signal names
            check_writable(args.output, resolved.spec.outputs)

    def check_replay_files(_resolved: Any) -> None:  # the same, for a replay: the log and the device files it needs
        from ..filecheck import DEVICE_MAP, check_file
        from ..io.canlog import open_session

        if not (args.dbc and args.map):
            raise FlowtexError(f"{args.input}: replaying a CAN session needs --dbc DEVICE.dbc and --map MAP.yaml")
        read["log"] = open_session(args.input)  # its start checked: the replay streams it
        check_file(args.map, DEVICE_MAP, args.dbc)  # the DBC too

    graph = load_graph_from_args(args, before_compile=check_replay_files if replay else read_recording,
                                 outputs={"-o": args.output})
    recording = read.get("recording")
    if replay:
        from ..runtime.replay import replay_session

        report = replay_session(graph, args.input, args.dbc, args.map, args.output, seed=args.seed,
                                expect_audio=args.expect_audio, log=read.get("log"))
        say(str(report))
        return 1 if report.audio_unexplained else 0
    if args.expect_audio:
        raise FlowtexError(f"--expect-audio {args.expect_audio}: only a replay of a CAN session (--input SESSION.blf/.log/.asc) "
                           "can be checked against a live recording")
    if args.output and kind_of(args.output) == AUDIO:
        from ..runtime.offline import render_recording_audio

        shape, rate, clipped = render_recording_audio(graph, args.input, args.output, args.map, seed=args.seed,
                                               progress=sys.stderr.isatty(), nonfinite=args.nonfinite, recording=recording,
                                               nonfinite_out=args.nonfinite_outputs)
        say(f"{graph.name}: {shape[0]} frames x {shape[1]} channel(s) at {rate:g} Hz -> {args.output}")
        for line in clipped:
            note(f"warning: {line}")
        return 0
    from ..runtime.offline import nonfinite_outputs, run_recording

    outputs = run_recording(graph, args.input, args.output, seed=args.seed, progress=sys.stderr.isatty(),
                            nonfinite=args.nonfinite, nonfinite_out=args.nonfinite_outputs, recording=recording)
    for line in nonfinite_outputs(outputs):
        note(f"warning: {line} (--nonfinite-outputs error refuses instead)")
    say(run_summary(graph, outputs, args.output))
    return 0


def run_summary(graph: Any, outputs: dict, output: str | None) -> str:
    """``NAME: N ticks at R Hz, outputs a, b -> OUT (TIER tier)``."""
    n = next(iter(outputs.values())).shape[0] if outputs else 0
    target = f" -> {output}" if output else ""
    return f"{graph.name}: {n} ticks at {graph.rate:g} Hz, outputs {', '.join(outputs)}{target} ({graph.tier} tier)"
