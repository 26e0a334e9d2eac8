"""Option builders shared by every verb: one spelling and one meaning per flag (docs/cli.md lists them all).

- ``--plugins DIR`` / ``--no-plugins``: extra plugin folders; skip the graph's own (its ``plugins/`` and ``plugins:`` key).
- ``--set NODE.PARAM=VALUE``: override a node parameter (``--set rate=HZ``: the graph's rate).
- ``--seed N``: noise seed.
- ``--from-rate HZ``: the rate of a recording that states none (old spelling ``--rate`` in the fit verbs, with a notice).
- the live options (``--bus``, ``--dbc``, ``--map``, ``--record``, ``--stats``, ...), shared by ``live`` and ``scene live``.

Porting a new flag to several verbs is one line in the builder here.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from typing import Any

from ..errors import FlowtexError
from ..limits import MAX_RATE_HZ, MAX_SEED


def add_plugin_options(p: argparse.ArgumentParser, no_plugins: bool = True) -> None:
    """``--plugins DIR`` (repeatable) and (``no_plugins``) ``--no-plugins``."""
    p.add_argument("--plugins", action="append", default=[], metavar="DIR",
                   help="extra plugin folder (repeatable; plugin files are Python code that runs: docs/plugins.md)")
    if not no_plugins:
        p.set_defaults(no_plugins=False)
        return
    p.add_argument("--no-plugins", action="store_true",
                   help="do not load the graph's own plugin folders (its folder's plugins/ and its plugins: key); "
                        "only --plugins DIR and $FLOWTEX_PLUGINS")


def add_set_option(p: argparse.ArgumentParser) -> None:
    """``--set NODE.PARAM=VALUE`` (repeatable), stored in ``args.overrides``."""
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="NODE.PARAM=VALUE",
                   help="override a node parameter (repeatable), e.g. --set lookup.models=Models_Cork.xml; "
                        "--set rate=HZ sets the graph's rate")


def add_graph_options(p: argparse.ArgumentParser, no_plugins: bool = True) -> None:
    """The options of every verb that loads a graph: plugins and ``--set``."""
    add_plugin_options(p, no_plugins)
    add_set_option(p)


TIER_HELP = {
    "fused": "fused: one compiled tick per graph structure (fastest ticks; seconds to compile a new structure)",
    "dispatch": "dispatch: cached per-node kernels (a structural edit compiles nothing new)",
    "auto": "auto: fused if cached, else dispatch with the fused tick compiled in the background",
}


def add_compile_option(p: argparse.ArgumentParser, default: str, choices: tuple[str, ...] = ("fused", "dispatch", "auto")) -> None:
    """``--compile fused|dispatch|auto``: which compile tier builds the graph (docs/engine.md)."""
    p.add_argument("--compile", choices=choices, default=default,
                   help="; ".join(TIER_HELP[c] for c in choices) + f" (default: {default}; docs/engine.md)")


def positive_seconds(high: float = math.inf) -> Any:
    """argparse type: a duration in (0, ``high``] seconds."""
    return lambda text: number_in_range(text, 0.0, high, low_open=True, unit="s")


def add_seed_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seed", type=int_at_least(0, MAX_SEED), default=None, help="noise seed (0..2^63-1; default: the graph's)")




def positive_hz(text: str) -> float:
    """argparse type: a rate in (0, :data:`MAX_RATE_HZ`] Hz."""
    return number_in_range(text, 0.0, MAX_RATE_HZ, low_open=True, unit="Hz")


def number_in_range(text: str, low: float, high: float, *, low_open: bool = False, high_open: bool = False,
                    unit: str = "") -> float:
    """A finite float in [low, high] (open at either end with ``low_open`` / ``high_open``); argparse turns the error into a usage line."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    below = value <= low if low_open else value < low
    above = value >= high if high_open else value > high
    if not math.isfinite(value) or below or above:
        lo = "(" if low_open else "["
        hi = "inf)" if high == math.inf else f"{high:g}" + (")" if high_open else "]")
        raise argparse.ArgumentTypeError(f"{text} is out of range: valid {lo}{low:g}, {hi}{' ' + unit if unit else ''}")
    return value


def int_at_least(low: int, high: int | None = None) -> Any:
    """argparse type: an integer in [low, high]."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < low or (high is not None and value > high):
            top = "inf" if high is None else ("2^63-1" if high == 2**63 - 1 else str(high))
            raise argparse.ArgumentTypeError(f"{text} is out of range: valid {low}..{top}")
        return value

    return parse


def cpu_index(text: str) -> int:
    """argparse type: a CPU this process may run on (``os.sched_getaffinity``; where unknown, below ``os.cpu_count()``)."""
    import os

    value = int_at_least(0)(text)
    allowed = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else list(range(os.cpu_count() or 1))
    if value not in allowed:
        raise argparse.ArgumentTypeError(f"{text}: no such CPU for this process (it may use CPU {', '.join(map(str, allowed))})")
    return value


def one_motion_source(args: argparse.Namespace) -> None:
    """``--speed`` and ``--position`` both say how fast the tool moves: refuse both rather than silently use one; and
    ``--normal`` (the surface normal for ``--position``) without ``--position``, which nothing would read."""
    if getattr(args, "speed", None) is not None and getattr(args, "position", None) is not None:
        raise FlowtexError(f"--speed {args.speed} and --position {args.position}: give one (the speed signal, or the position "
                           "the speed is computed from), not both")
    if getattr(args, "normal", None) is not None and getattr(args, "position", None) is None:
        raise FlowtexError(f"--normal {args.normal}: the surface normal the speed is computed from with --position; give "
                           "--position P with it, or drop --normal")


_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")


def scheduler_address(text: str) -> str:
    """argparse type: a Dask scheduler address ``[SCHEME://]HOST:PORT`` (port 1..65535), e.g. ``tcp://10.0.0.5:8786``."""
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    host, colon, port = rest.rpartition(":")
    if scheme not in _SCHEMES or not colon or not host or any(c.isspace() for c in text) or not port.isdigit() \
            or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"{text!r} is not a scheduler address; write tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786)")
    return text


class Renamed(argparse.Action):
    """An old spelling of a flag: stores into the new one's ``dest`` and prints a one-line notice on stderr."""

    def __init__(self, option_strings: Sequence[str], dest: str, new: str = "", meaning: str = "", **kwargs: Any) -> None:
        self.new = new
        self.meaning = meaning
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any,
                 option_string: str | None = None) -> None:
        print(f"notice: {option_string} is now spelled {self.new}{' (' + self.meaning + ')' if self.meaning else ''}; "
              f"the old spelling still works", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_from_rate(p: argparse.ArgumentParser, old_rate: bool = False) -> None:
    """``--from-rate HZ`` (stored in ``args.from_rate``); ``old_rate`` also accepts the old ``--rate`` with a notice."""
    p.add_argument("--from-rate", type=positive_hz, metavar="HZ", help="sample rate (Hz) of a recording that states none")
    if old_rate:
        p.add_argument("--rate", dest="from_rate", type=positive_hz, action=Renamed, new="--from-rate",
                       meaning="the recording's rate", help=argparse.SUPPRESS)


def add_live_options(p: argparse.ArgumentParser, device_required: bool = True) -> None:
    """The options of a live session (``live`` and ``scene live``)."""
    p.add_argument("--bus", help="INTERFACE[:CHANNEL], e.g. virtual, socketcan:can0, slcan:/dev/ttyACM0, pcan, kvaser, "
                                 "socketcand:can0@127.0.0.1:29536")
    p.add_argument("--bitrate", type=int_at_least(1), help="bus bitrate in bit/s (interfaces that need one)")
    p.add_argument("--dbc", required=device_required, help="DBC file describing the device's messages")
    p.add_argument("--map", required=device_required, help="map YAML binding DBC signals to graph inputs/outputs (docs/live.md)")
    p.add_argument("--record", help="log every frame read and written to SESSION.blf or SESSION.log")
    p.add_argument("--record-audio", metavar="OUT.wav", help="write the samples handed to the sound card (the map's audio "
                                                             "section) as a float32 WAV")
    p.add_argument("--duration", type=positive_seconds(),
                   help="seconds to run (default: until Ctrl-C / SIGTERM)")
    p.add_argument("--rt", action="store_true", help="ask for SCHED_FIFO real-time scheduling and pin the loop to a CPU")
    p.add_argument("--rt-priority", type=int_at_least(1, 99), default=80, help="SCHED_FIFO priority with --rt (1..99, default 80)")
    p.add_argument("--cpu", type=cpu_index, help="CPU to pin the loop to with --rt (one this process may use)")
    p.add_argument("--stats", help="write the end-of-run statistics as JSON to this file")
    p.add_argument("--simulate", metavar="RECORDING", help="run a simulated device in this process playing RECORDING (.npz/.csv/.h5)")
    p.add_argument("--quiet", action="store_true", help="no status line")
    p.add_argument("--show", action="append", default=[], metavar="SIGNAL",
                   help="add a graph output or input (NAME, or NAME[i] for one component) to the status line (repeatable)")
    add_seed_option(p)
    add_graph_options(p)


def overrides(items: Sequence[str]) -> dict:
    """``--set`` items as {"node.param": value}."""
    from ..graph.spec import parse_override

    return dict(parse_override(text) for text in items)
