"""Tell the user when a graph is being compiled: the first run of a graph is otherwise silent for many seconds.

:func:`compile_notice` wraps the compilation. If it is still running after
``delay`` seconds (a disk-cache hit finishes well before), one line goes to
stderr saying what is compiled and that the result is cached; when stderr is
a terminal a spinner with the elapsed seconds follows on the same line and is
replaced by the total time at the end. Nothing is printed for a cache hit.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TextIO

NOTICE_DELAY_S = 1.0
"""Seconds a compilation may take before it is announced (loading cached code takes well under this)."""
SPINNER = "|/-\\"


@contextmanager
def compile_notice(what: str, cached_in: str, delay: float = NOTICE_DELAY_S, stream: TextIO | None = None) -> Iterator[None]:
    """Announce a compilation that takes longer than ``delay`` seconds on ``stream`` (default stderr)."""
    out = stream if stream is not None else sys.stderr
    tty = bool(getattr(out, "isatty", lambda: False)())
    done = threading.Event()
    announced = threading.Event()
    start = time.monotonic()

    def watch() -> None:
        if done.wait(delay):
            return
        line = f"flowtex: compiling {what} with numba (first run only: cached in {cached_in})"
        announced.set()
        if not tty:
            print(line, file=out, flush=True)
            return
        k = 0
        while not done.wait(0.2):
            out.write(f"\r{line} {SPINNER[k % len(SPINNER)]} {time.monotonic() - start:.0f} s")
            out.flush()
            k += 1

    thread = threading.Thread(target=watch, name="flowtex-compile-notice", daemon=True)
    thread.start()
    ok = False
    try:
        yield
        ok = True
    finally:
        done.set()
        thread.join()
        if announced.is_set() and tty:
            end = f"\rflowtex: compiled {what} in {time.monotonic() - start:.1f} s (cached in {cached_in})\x1b[K" if ok else ""
            out.write(end + "\n")  # on an error, end the spinner's line so the message starts on its own
            out.flush()
