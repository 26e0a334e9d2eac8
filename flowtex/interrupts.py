"""Ctrl-C (and SIGTERM) are never lost inside a C callback.

numba's compiler receives LLVM's finished object code through a ctypes callback. A KeyboardInterrupt raised while
Python code of such a callback runs cannot leave the callback: ctypes prints it as "Exception ignored" and drops it.
The compile then goes on as if nothing happened (a session started with Ctrl-C runs to its end), or fails later
with numba's "no compiled object yet" (an internal error instead of "interrupted"). :func:`interrupts_kept` notes
every interrupt dropped that way and raises the signal again a moment later, outside the callback, so that it
interrupts the program at its next ordinary point; :func:`interrupt_was_lost` lets the command line report an error
that a dropped interrupt caused as the interrupt it was.

The command line keeps interrupts for its whole run (SIGTERM included). Any other caller (a notebook, a script
calling :func:`flowtex.runtime.live.run_live`) gets the same for Ctrl-C during every numba compile of the process:
:func:`guard_compiles`, installed when flowtex first configures numba's cache, keeps interrupts from the start to the
end of each outermost compile (numba's ``numba:compile`` events), unless a caller already keeps them.
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

    hook.flowtex_keeps_interrupts = True  # type: ignore[attr-defined]  (guard_compiles: one keeper at a time)
    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous


def sigint_of(exc: BaseException) -> int | None:
    """SIGINT for a KeyboardInterrupt, else None: what a library caller's Ctrl-C stands for."""
    return signal.SIGINT if isinstance(exc, KeyboardInterrupt) else None


def keeping_interrupts() -> bool:
    """True while :func:`interrupts_kept` is active (its hook is ``sys.unraisablehook``)."""
    return bool(getattr(sys.unraisablehook, "flowtex_keeps_interrupts", False))


_GUARDED: list[bool] = []


def guard_compiles() -> None:
    """Keep Ctrl-C during every outermost numba compile of this process (module docstring); once per process."""
    if _GUARDED:
        return
    _GUARDED.append(True)
    from numba.core import event

    class CompileInterrupts(event.Listener):
        """Enters :func:`interrupts_kept` at the start of an outermost compile and leaves it at its end (numba's
        compiles hold one process-wide lock, so their events nest)."""

        def __init__(self) -> None:
            self.depth = 0
            self.kept: contextlib.AbstractContextManager[None] | None = None

        def on_start(self, ev: event.Event) -> None:
            self.depth += 1
            if self.depth == 1 and not keeping_interrupts():
                self.kept = interrupts_kept(sigint_of)
                self.kept.__enter__()

        def on_end(self, ev: event.Event) -> None:
            self.depth -= 1
            if self.depth == 0 and self.kept is not None:
                kept, self.kept = self.kept, None
                kept.__exit__(None, None, None)

    event.register("numba:compile", CompileInterrupts())
