"""The ``flowtex`` command: one parser, one error and exit-code convention (docs/cli.md).

Every verb lives in one module of this package with ``register(subparsers)`` adding its parser and handlers named
``cmd_<verb>``; handlers call library functions with Python values and return an exit code.

Exit codes: 0 ok; 1 user error (a one-line message naming the file, option or signal and the fix, also for a bad
command line); 2 internal error (a bug: ``flowtex: internal error: ...``; ``FLOWTEX_DEBUG=1`` shows the traceback);
3 ``live`` ended without one sensor frame; 130 interrupted (Ctrl-C); 143 terminated (SIGTERM), 129 hung up (SIGHUP) before the verb finished.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import signal
import sys
from collections.abc import Iterator, Sequence
from typing import Any

from .. import config
from ..errors import FlowtexError
from ..interrupts import interrupt_was_lost, interrupts_kept, signals_handled, signals_named
from .output import clean

EXIT_OK = 0
EXIT_USER_ERROR = 1
EXIT_INTERNAL_ERROR = 2
EXIT_NO_SENSOR_FRAMES = 3
EXIT_INTERRUPTED = 130
STOP_SIGNALS = signals_named("SIGTERM", "SIGHUP")
"""Signals that raise :class:`Terminated` while a verb runs (SIGHUP does not exist on Windows); the verb then exits
128 + the signal's number: 143 for SIGTERM, 129 for SIGHUP (``live`` stops cleanly with 0 once its loop runs)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (``signum``), raised where Ctrl-C would raise KeyboardInterrupt: the same clean-up runs (no
    ``.part`` file left). Without it SIGHUP would end the process at once and leave the temporary files behind."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__()
        self.signum = int(signum)

COMMANDS: dict[str, tuple[str, str]] = {
    "validate": ("flowtex.cli.graph", "check any flowtex file (graph, scene, device map, model set, pattern, tap library, "
                                      "friction, compliance); one line per problem"),
    "graph": ("flowtex.cli.graph", "show execution order, buffers and dropped nodes"),
    "nodes": ("flowtex.cli.graph", "list node types with ports, parameters and docs"),
    "run": ("flowtex.cli.run", "run a graph offline over a recording (or replay a CAN session)"),
    "live": ("flowtex.cli.live", "run a graph live against a CAN device at the graph's rate"),
    "simulate-device": ("flowtex.cli.live", "run the simulated CAN device as its own process"),
    "fit": ("flowtex.cli.fit", "fit models (texture, friction, taps, pattern, compliance) to recordings"),
    "compare": ("flowtex.cli.compare", "render a surface along a recording's speed and force and compare (power, LSD, ...)"),
    "models": ("flowtex.cli.models", "operate on texture model sets and tap libraries (resample)"),
    "resample": ("flowtex.cli.resample", "resample every signal of a recording to another rate (zero delay)"),
    "scene": ("flowtex.cli.scene", "plan a multi-surface scene into a graph that renders only what matters"),
    "bench": ("flowtex.cli.bench", "sweep knobs: ns/tick against output error, Pareto front"),
    "plot": ("flowtex.cli.plot", "plot a run's outputs: time series, vibration spectrograms, force-speed trace"),
    "schema": ("flowtex.cli.schema", "print the JSON Schema of a file kind for editors (graph, scene, map)"),
    "plugin": ("flowtex.cli.plugin", "write a plugin package for a new node type, or check a plugin's node types"),
    "watch": ("flowtex.cli.watch", "rerun a graph over a recording whenever the graph, its model files or its plugins change"),
}
"""The lazy command table (as pip's ``commands_dict``): command -> (module adding it, one-line summary).

A module's ``register(subparsers)`` adds its commands; only the module of the command being run is imported, so
``flowtex --help`` and ``--version`` import none (tests/cli/test_cli_lazy.py checks the summaries equal the
parsers' help)."""

COMMAND_MODULES = tuple(dict.fromkeys(module for module, _ in COMMANDS.values()))
"""Modules that add subcommands, in table order."""


class Parser(argparse.ArgumentParser):
    """argparse with flowtex's convention for a bad command line: one line on stderr, exit code 1."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(clean(f"{self.prog}: {message} (see {self.prog} --help)"), file=sys.stderr)
        sys.exit(EXIT_USER_ERROR)


def build_parser(command: str | None = "") -> argparse.ArgumentParser:
    """The ``flowtex`` parser.

    ``command`` ``""`` (the default): every command's full parser (docs and tests walk it). Otherwise only the module of
    ``command`` is imported (``None``: none); the other commands are listed with their summaries and parse nothing.
    """
    from ..version import __version__

    parser = Parser(prog="flowtex", description="Dataflow graphs for haptic signal processing (every flag: docs/cli.md).",
                    epilog="Exit codes: 0 ok, 1 user error (one line), 2 internal error, 3 live without sensor frames, "
                           "130 interrupted (Ctrl-C), 143 terminated (SIGTERM), 129 hung up (SIGHUP).")
    parser.add_argument("--version", action="version", version=f"flowtex {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    chosen = COMMANDS[command][0] if command else None
    registered: set[str] = set()
    for name, (module_name, summary) in COMMANDS.items():
        if command == "" or module_name == chosen:
            if module_name not in registered:
                registered.add(module_name)
                importlib.import_module(module_name).register(sub)
        else:
            sub.add_parser(name, help=summary)
    return parser


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """While the ``with`` body runs, SIGTERM and SIGHUP raise :class:`Terminated` (main thread only; the old handlers
    come back).

    Every writer already removes its temporary file on KeyboardInterrupt (:func:`flowtex.io.atomic.atomic_output`),
    so these signals leave nothing behind either. ``live`` installs its own handlers for its loop (a clean stop).
    """
    def handler(signum: int, frame: Any) -> None:
        raise Terminated(signum)

    with signals_handled(STOP_SIGNALS, handler):
        yield


def _signal_of(exc: BaseException) -> int | None:
    """The signal an interrupt exception stands for (SIGTERM or SIGHUP for :class:`Terminated`, SIGINT for Ctrl-C),
    else None."""
    if isinstance(exc, Terminated):
        return exc.signum
    return signal.SIGINT if isinstance(exc, KeyboardInterrupt) else None


def _stopped(exc: KeyboardInterrupt) -> int:
    """The exit code and last line for a verb stopped by a signal (the terminal may be gone: SIGHUP)."""
    with contextlib.suppress(OSError):
        print("terminated" if isinstance(exc, Terminated) else "interrupted", file=sys.stderr)
    return 128 + exc.signum if isinstance(exc, Terminated) else EXIT_INTERRUPTED


def main(argv: Sequence[str] | None = None) -> int:
    try:
        with sigterm_interrupts(), interrupts_kept(_signal_of):
            return _main(argv)
    except KeyboardInterrupt as exc:  # between the verb's own handlers (after it returned, or while the parser loads)
        return _stopped(exc)


def _command_of(argv: Sequence[str]) -> str | None:
    """The command named on the command line (its first word that is not an option), or None."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def _main(argv: Sequence[str] | None) -> int:
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser(_command_of(words))
        args = parser.parse_args(words)
    except SystemExit as exc:  # --help, --version (0) or a bad command line (1, one line already printed)
        return int(exc.code or 0)
    try:
        return int(args.func(args) or 0)
    except FlowtexError as exc:
        for line in str(exc).splitlines() or [type(exc).__name__]:
            print(clean(line), file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt as exc:
        return _stopped(exc)
    except BrokenPipeError:
        return EXIT_OK
    except Exception as exc:
        if interrupt_was_lost():  # an interrupt dropped inside a C callback broke what it interrupted (.interrupts)
            print("interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        if config.debug():
            raise
        print(clean(f"flowtex: internal error: {type(exc).__name__}: {exc} (set FLOWTEX_DEBUG=1 for a traceback; please report it)"),
              file=sys.stderr)
        return EXIT_INTERNAL_ERROR
