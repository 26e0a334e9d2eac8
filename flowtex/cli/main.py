"""The ``flowtex`` command: one parser, one error and exit-code convention (docs/cli.md).

Every verb lives in one module of this package with ``register(subparsers)`` adding its parser and handlers named
``cmd_<verb>``; handlers call library functions with Python values and return an exit code.

Exit codes: 0 ok; 1 user error (a one-line message naming the file, option or signal and the fix, also for a bad
command line); 2 internal error (a bug: ``flowtex: internal error: ...``; ``FLOWTEX_DEBUG=1`` shows the traceback);
3 ``live`` ended without one sensor frame; 130 interrupted (Ctrl-C); 143 terminated (SIGTERM) before the verb finished.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import threading
from collections.abc import Iterator, Sequence
from typing import Any

from ..errors import FlowtexError
from .output import clean

EXIT_OK = 0
EXIT_USER_ERROR = 1
EXIT_INTERNAL_ERROR = 2
EXIT_NO_SENSOR_FRAMES = 3
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143
"""128 + SIGTERM: a verb stopped by SIGTERM before it finished (``live`` stops cleanly with 0 once its loop runs)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl-C would raise KeyboardInterrupt: the same clean-up runs (no ``.part`` file left)."""

COMMAND_MODULES = (
    "flowtex.cli.graph",
    "flowtex.cli.run",
    "flowtex.cli.live",
    "flowtex.cli.fit",
    "flowtex.cli.compare",
    "flowtex.cli.models",
    "flowtex.cli.resample",
    "flowtex.cli.scene",
    "flowtex.cli.bench",
    "flowtex.cli.plot",
)
"""Modules that add subcommands: each has ``register(subparsers)`` (one command group per module, one line here)."""


class Parser(argparse.ArgumentParser):
    """argparse with flowtex's convention for a bad command line: one line on stderr, exit code 1."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(clean(f"{self.prog}: {message} (see {self.prog} --help)"), file=sys.stderr)
        sys.exit(EXIT_USER_ERROR)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = Parser(prog="flowtex", description="Dataflow graphs for haptic signal processing (every flag: docs/cli.md).",
                    epilog="Exit codes: 0 ok, 1 user error (one line), 2 internal error, 3 live without sensor frames, "
                           "130 interrupted (Ctrl-C), 143 terminated (SIGTERM).")
    parser.add_argument("--version", action="version", version=f"flowtex {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for module_name in COMMAND_MODULES:
        importlib.import_module(module_name).register(sub)
    return parser


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """While the ``with`` body runs, SIGTERM raises :class:`Terminated` (main thread only; the old handler comes back).

    Every writer already removes its temporary file on KeyboardInterrupt (:func:`flowtex.io.atomic.atomic_output`),
    so SIGTERM leaves nothing behind either. ``live`` installs its own handlers for its loop (a clean stop).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise Terminated()

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def main(argv: Sequence[str] | None = None) -> int:
    try:
        with sigterm_interrupts():
            return _main(argv)
    except Terminated:  # between the verb's own handlers (after it returned, or while the parser loads)
        print("terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def _main(argv: Sequence[str] | None) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version (0) or a bad command line (1, one line already printed)
        return int(exc.code or 0)
    try:
        return int(args.func(args) or 0)
    except FlowtexError as exc:
        for line in str(exc).splitlines() or [type(exc).__name__]:
            print(clean(line), file=sys.stderr)
        return EXIT_USER_ERROR
    except Terminated:
        print("terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        return EXIT_OK
    except Exception as exc:
        if os.environ.get("FLOWTEX_DEBUG"):
            raise
        print(clean(f"flowtex: internal error: {type(exc).__name__}: {exc} (set FLOWTEX_DEBUG=1 for a traceback; please report it)"),
              file=sys.stderr)
        return EXIT_INTERNAL_ERROR
