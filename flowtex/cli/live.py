"""``flowtex live`` and ``flowtex simulate-device``: a graph against a CAN device at its rate, and a simulated device."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import FlowtexError
from .graph import load_graph_from_args
from .main import EXIT_NO_SENSOR_FRAMES
from .options import add_live_options, int_at_least, positive_hz, positive_seconds
from .output import note, say


def register(sub: Any) -> None:
    p = sub.add_parser("live", help="run a graph live against a CAN device at the graph's rate",
                       description="Run GRAPH live: CAN sensor frames -> graph inputs, graph outputs -> guarded actuator frames.",
                       epilog="Exit codes: 0 clean stop (duration, Ctrl-C, SIGTERM, SIGHUP); 1 error (the line says whether the safe values "
                              "were sent); 3 no sensor frame arrived during the whole session (outputs stayed safe).")
    p.add_argument("graph", nargs="?", help="graph YAML file")
    p.add_argument("--list-audio", action="store_true", help="list the audio devices PortAudio sees (for a map's audio.device), and exit")
    add_live_options(p, device_required=False)
    p.set_defaults(func=cmd_live)

    s = sub.add_parser("simulate-device", help="run the simulated CAN device as its own process",
                       description="Play RECORDING's sensor signals as CAN frames and collect actuator frames, at the given rate.")
    s.add_argument("recording", help="recording (.npz/.csv/.h5) whose arrays are named like the map's graph inputs")
    where = s.add_mutually_exclusive_group(required=True)
    where.add_argument("--bus", help="INTERFACE[:CHANNEL] shared with the runtime (e.g. socketcan:vcan0, socketcand:vcan0@127.0.0.1:29536)")
    where.add_argument("--pty", action="store_true", help="act as an slcan adapter on a new pseudo-terminal; prints the "
                                                          "--bus flowtex_slcan:/dev/pts/N to give the runtime")
    s.add_argument("--bitrate", type=int_at_least(1), help="bus bitrate in bit/s")
    s.add_argument("--dbc", required=True, help="DBC file")
    s.add_argument("--map", required=True, help="map YAML (its inputs say which signals to publish)")
    s.add_argument("--rate", type=positive_hz, help="ticks per second it produces (default: the recording's rate, else 1000)")
    s.add_argument("--duration", type=positive_seconds(), help="seconds to run (> 0; default: until Ctrl-C / SIGTERM)")
    s.add_argument("--exit-on-close", action="store_true", help="stop when the runtime closes the channel (slcan: after its 'C' command)")
    s.set_defaults(func=cmd_simulate_device)


def cmd_live(args: argparse.Namespace) -> int:
    """0 after a clean stop (duration, Ctrl-C, SIGTERM, SIGHUP), 1 on errors, 3 when no sensor frame arrived."""
    if args.list_audio:
        from ..runtime.audio import list_audio_devices

        say(list_audio_devices())
        return 0
    missing = [f for f, v in (("GRAPH", args.graph), ("--dbc", args.dbc), ("--map", args.map)) if not v]
    if missing:
        raise FlowtexError(f"flowtex live: missing {', '.join(missing)} (usage: flowtex live GRAPH --dbc DEVICE.dbc --map MAP.yaml ...)")
    check_live_outputs(args, args.graph, args.dbc, args.map)
    return run_live_session(load_graph_from_args(args, tier="fused", outputs=live_outputs(args)), args)  # live keeps the fused tick


def check_live_outputs(args: argparse.Namespace, source: str, dbc: str | None, map_: str | None) -> None:
    """``--stats`` and ``--record``: not an input, folder there and writable, before the session (and the compile)."""
    from ..io.atomic import check_output

    inputs = [source, dbc, map_, args.simulate]
    check_output(args.stats, inputs=inputs, option="--stats")
    check_output(args.record, inputs=inputs, option="--record", others={"--stats": args.stats})
    check_output(getattr(args, "record_audio", None), inputs=inputs, others={"--stats": args.stats, "--record": args.record}, option="--record-audio",
                 suffixes=(".wav",))


def live_outputs(args: argparse.Namespace) -> dict[str, str | None]:
    """The files a live session writes, by option (checked against the files its graph reads)."""
    return {"--stats": args.stats, "--record": args.record, "--record-audio": getattr(args, "record_audio", None)}


def run_live_session(graph: Any, args: argparse.Namespace, dbc: str | None = None, map_: str | None = None) -> int:
    """Run ``graph`` live with the live options in ``args`` (``dbc``/``map_`` replace ``args.dbc``/``args.map``)."""
    from ..runtime.live import run_live
    from ..runtime.liveconfig import LiveConfig

    config = LiveConfig(dbc or args.dbc, map_ or args.map, args.bus, simulate=args.simulate, duration_s=args.duration,
                        record=args.record, record_audio=getattr(args, "record_audio", None), stats_path=args.stats,
                        rt=args.rt, rt_priority=args.rt_priority, rt_cpu=args.cpu, seed=args.seed,
                        status=None if args.quiet else sys.stderr, bitrate=args.bitrate, show=tuple(args.show),
                        inputs=tuple(p for p in (getattr(args, "graph", None), getattr(args, "scene", None)) if p))
    report = run_live(graph, config)
    for line in report.warnings:
        note(f"flowtex live: warning: {line}")
    if report.error:
        raise FlowtexError(report.error + (" (safe values sent)" if report.safe_sent else ""))
    if report.no_sensor_frames:
        note(report.silence)
        return EXIT_NO_SENSOR_FRAMES
    if report.silence:
        note(f"warning: {report.silence}")
    return 0


def cmd_simulate_device(args: argparse.Namespace) -> int:
    """0 after a clean stop, 1 on errors."""
    import can

    from ..runtime.simdevice import run_device

    try:
        run_device(args.bus, args.dbc, args.map, args.recording, rate_hz=args.rate, duration_s=args.duration, bitrate=args.bitrate,
                   pty=args.pty, exit_on_close=args.exit_on_close)
    except OSError as exc:
        raise FlowtexError(f"CAN bus failure: {exc}") from None
    except can.CanError as exc:
        raise FlowtexError(f"CAN bus failure: {' '.join(str(exc).split())}") from None
    return 0
