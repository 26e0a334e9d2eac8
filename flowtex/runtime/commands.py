"""``flowtex live`` and ``flowtex simulate-device``: argparse wiring (called from flowtex/cli.py).

Usage::

    subparsers = parser.add_subparsers(dest="command")
    flowtex.runtime.commands.register(subparsers)
    args = parser.parse_args()
    sys.exit(args.func(args))

Each command returns an exit code; user errors (:class:`FlowtexError`) are
printed as ``flowtex <command>: error: ...`` lines, never as tracebacks.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

EXIT_NO_SENSOR_FRAMES = 3
"""Exit code of ``flowtex live`` when the session ended without one sensor frame received (0: clean stop, 1: error)."""


def register(subparsers: Any) -> None:
    """Add the ``live`` and ``simulate-device`` subcommands to an argparse subparsers object."""
    p = subparsers.add_parser("live", help="run a graph live against a CAN device at the graph's rate",
                              description="Run GRAPH live: CAN sensor frames -> graph inputs, graph outputs -> guarded actuator frames.",
                              epilog="Exit codes: 0 clean stop (duration, Ctrl-C, SIGTERM); 1 error (safe values sent); "
                                     "3 no sensor frame arrived during the whole session (outputs stayed safe).")
    p.add_argument("graph", help="graph YAML file")
    p.add_argument("--bus", help="INTERFACE[:CHANNEL], e.g. virtual, socketcan:can0, slcan:/dev/ttyACM0, pcan, kvaser, "
                                 "socketcand:can0@127.0.0.1:29536")
    p.add_argument("--bitrate", type=int, help="bus bitrate in bit/s (interfaces that need one)")
    p.add_argument("--dbc", required=True, help="DBC file describing the device's messages")
    p.add_argument("--map", required=True, help="map YAML binding DBC signals to graph inputs/outputs (docs/live.md)")
    p.add_argument("--record", help="log every frame read and written to SESSION.blf or SESSION.log")
    p.add_argument("--duration", type=float, help="seconds to run (default: until Ctrl-C / SIGTERM)")
    p.add_argument("--rt", action="store_true", help="ask for SCHED_FIFO real-time scheduling and pin the loop to a CPU")
    p.add_argument("--rt-priority", type=int, default=80, help="SCHED_FIFO priority with --rt (default 80)")
    p.add_argument("--cpu", type=int, help="CPU to pin the loop to with --rt")
    p.add_argument("--stats", help="write the end-of-run statistics as JSON to this file")
    p.add_argument("--simulate", metavar="RECORDING", help="run a simulated device in this process playing RECORDING (.npz/.csv/.h5)")
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.add_argument("--show", action="append", default=[], metavar="SIGNAL",
                   help="add a graph output or input (NAME, or NAME[i] for one component) to the status line (repeatable)")
    _common(p)
    p.set_defaults(func=cmd_live)

    s = subparsers.add_parser("simulate-device", help="run the simulated CAN device as its own process",
                              description="Play RECORDING's sensor signals as CAN frames and collect actuator frames, at the given rate.")
    s.add_argument("recording", help="recording (.npz/.csv/.h5) whose arrays are named like the map's graph inputs")
    where = s.add_mutually_exclusive_group(required=True)
    where.add_argument("--bus", help="INTERFACE[:CHANNEL] shared with the runtime (e.g. socketcan:vcan0, socketcand:vcan0@127.0.0.1:29536)")
    where.add_argument("--pty", action="store_true", help="act as an slcan adapter on a new pseudo-terminal; prints the "
                                                          "--bus flowtex_slcan:/dev/pts/N to give the runtime")
    s.add_argument("--bitrate", type=int, help="bus bitrate in bit/s")
    s.add_argument("--dbc", required=True, help="DBC file")
    s.add_argument("--map", required=True, help="map YAML (its inputs say which signals to publish)")
    s.add_argument("--rate", type=float, help="ticks per second (default: the recording's rate, else 1000)")
    s.add_argument("--duration", type=float, help="seconds to run (default: until Ctrl-C / SIGTERM)")
    s.add_argument("--exit-on-close", action="store_true", help="stop when the runtime closes the channel (slcan: after its 'C' command)")
    s.set_defaults(func=cmd_simulate_device)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plugins", action="append", default=[], metavar="DIR", help="folder of plugin nodes (repeatable)")
    p.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=VALUE", help="override a node parameter (repeatable)")
    p.add_argument("--seed", type=int, help="noise seed (default: the graph's)")


def _error(command: str, message: str) -> int:
    for line in str(message).splitlines() or [""]:
        print(f"flowtex {command}: error: {line}", file=sys.stderr)
    return 1


def cmd_live(args: argparse.Namespace) -> int:
    """``flowtex live``: returns 0 after a clean stop (duration, Ctrl-C, SIGTERM), 1 on errors, 3 when no sensor frame arrived."""
    from ..errors import FlowtexError
    from ..graph.compiled import load_graph
    from ..graph.spec import parse_override
    from .live import run_live

    try:
        overrides = dict(parse_override(t) for t in args.set)
        graph = load_graph(args.graph, overrides, tuple(Path(d) for d in args.plugins), tier="fused")  # live: fused ticks
        report = run_live(graph, args.dbc, args.map, args.bus, simulate=args.simulate, duration_s=args.duration,
                          record=args.record, rt=args.rt, rt_priority=args.rt_priority, rt_cpu=args.cpu,
                          stats_path=args.stats, seed=args.seed, status=None if args.quiet else sys.stderr,
                          bitrate=args.bitrate, show=args.show)
    except FlowtexError as exc:
        return _error("live", str(exc))
    except KeyboardInterrupt:
        return _error("live", "interrupted before the loop started")
    if report.error:
        return _error("live", report.error + " (safe values sent)")
    if report.no_sensor_frames:
        _error("live", report.silence)
        return EXIT_NO_SENSOR_FRAMES
    if report.silence:
        print(f"flowtex live: warning: {report.silence}", file=sys.stderr)
    return 0


def cmd_simulate_device(args: argparse.Namespace) -> int:
    """``flowtex simulate-device``: returns 0 after a clean stop, 1 on errors."""
    import can

    from ..errors import FlowtexError
    from .simdevice import run_device

    try:
        run_device(args.bus, args.dbc, args.map, args.recording, rate_hz=args.rate, duration_s=args.duration, bitrate=args.bitrate,
                   pty=args.pty, exit_on_close=args.exit_on_close)
    except FlowtexError as exc:
        return _error("simulate-device", str(exc))
    except OSError as exc:
        return _error("simulate-device", f"CAN bus failure: {exc}")
    except can.CanError as exc:
        return _error("simulate-device", f"CAN bus failure: {' '.join(str(exc).split())}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry (``python -m flowtex.runtime.commands live ...``) until flowtex/cli.py calls :func:`register`."""
    parser = argparse.ArgumentParser(prog="flowtex")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
