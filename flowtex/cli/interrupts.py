"""Ctrl-C (and SIGTERM) are never lost inside a C callback.

numba's compiler receives LLVM's finished object code through a ctypes callback. A KeyboardInterrupt raised while
Python code of such a callback runs cannot leave the callback: ctypes prints it as "Exception ignored" and drops it.
The compile then goes on as if nothing happened (a session started with Ctrl-C runs to its end), or fails later
with numba's "no compiled object yet" (an internal error instead of "interrupted"). :func:`interrupts_kept` notes
every interrupt dropped that way and raises the signal again a moment later, outside the callback, so that it
interrupts the command at its next ordinary point; :func:`interrupt_was_lost` lets the command line report an error
that a dropped interrupt caused as the interrupt it was.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

RESEND_AFTER_S = 0.05
"""Seconds between an interrupt dropped in a callback and the same signal raised again (long enough for the callback
to return; a second drop, as unlikely as the first, raises it once more)."""

_lost = threading.Event()


def interrupt_was_lost() -> bool:
    """True once an interrupt was dropped inside a C callback while :func:`interrupts_kept` was active."""
    return _lost.is_set()


def _raise_again(signum: int) -> None:
    if os.name == "nt":
        signal.raise_signal(signum)
    else:
        os.kill(os.getpid(), signum)  # process-directed: it also wakes a blocking call in the main thread


@contextlib.contextmanager
def interrupts_kept(signal_of: Callable[[BaseException], int | None]) -> Iterator[None]:
    """While the ``with`` body runs, an exception dropped by a C callback for which ``signal_of`` names a signal is
    noted and that signal is raised again after :data:`RESEND_AFTER_S`; other dropped exceptions are reported as
    before. The previous ``sys.unraisablehook`` comes back at the end."""
    previous = sys.unraisablehook
    _lost.clear()

    def hook(unraisable: Any) -> None:
        signum = signal_of(unraisable.exc_value) if unraisable.exc_value is not None else None
        if signum is None:
            previous(unraisable)
            return
        _lost.set()
        timer = threading.Timer(RESEND_AFTER_S, _raise_again, (signum,))
        timer.daemon = True
        timer.start()

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous
