"""Ctrl-C (and SIGTERM) are never lost inside a C callback.

numba's compiler receives LLVM's finished object code through a ctypes callback. A KeyboardInterrupt raised while
Python code of such a callback runs cannot leave the callback: ctypes prints it as "Exception ignored" and drops it.
The compile then goes on as if nothing happened (a session started with Ctrl-C runs to its end), or fails later
with numba's "no compiled object yet" (an internal error instead of "interrupted"). :func:`interrupts_kept` notes
every interrupt dropped that way and raises the signal again a moment later, outside the callback, so that it
interrupts the program at its next ordinary point; :func:`interrupt_was_lost` lets the command line report an error
that a dropped interrupt caused as the interrupt it was.

The command line keeps interrupts for its whole run (SIGTERM included), and exits on the first Ctrl-C. Any other
caller (a notebook, a script calling :func:`flowtex.runtime.live.run_live`) goes on in the same process after a
Ctrl-C, so a compile cut short would leave numba's half-built code behind: every later compile that links it fails
with "no compiled object yet" until the process restarts. For them a Ctrl-C during a compile waits for the compile's
end and is raised there (:func:`interrupts_deferred`; a second Ctrl-C stops at once). :func:`guard_compiles`,
installed when flowtex first configures numba's cache, does both for each outermost numba compile (numba's
``numba:compile`` events), unless a caller already keeps interrupts; flowtex's own C-callable wrappers, which numba
compiles without those events, defer in :func:`flowtex.graph.kcache.sealed_compile`.
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


def signals_named(*names: str) -> tuple[int, ...]:
    """The signals of ``names`` this platform has (SIGHUP does not exist on Windows)."""
    return tuple(getattr(signal, name) for name in names if hasattr(signal, name))


@contextlib.contextmanager
def signals_handled(signums: tuple[int, ...], handler: Callable[[int, Any], None], install: bool = True) -> Iterator[None]:
    """While the ``with`` body runs, ``handler`` handles ``signums``; the old handlers come back at its end.

    Nothing is installed outside the main thread (Python accepts handlers only there) or when ``install`` is false."""
    if not install or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, handler) for s in signums}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


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


DEFER_NOTE = ("flowtex: Ctrl-C: stopping when this compile ends (cut short, it would leave numba unable to compile in this "
              "process until it restarts); press Ctrl-C again to stop at once\n")
"""What the first Ctrl-C during a deferred compile prints on stderr."""

_deferring: list[bool] = []


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """A Ctrl-C while the ``with`` body runs is raised when the body ends, not inside it (module docstring).

    The first Ctrl-C prints :data:`DEFER_NOTE`; a second one calls the handler from before the block at once. The
    handler from before the block is back at its end, and a deferred Ctrl-C is passed to it then (Python's default
    raises KeyboardInterrupt). Nothing changes where it cannot work or is not needed: outside the main thread
    (signals go to the main thread, so the body is not interrupted anyway), under a handler that is not a Python
    function (SIGINT ignored or default), inside another deferred block, and while the command line keeps
    interrupts (it exits on Ctrl-C, leaving nothing half-built behind)."""
    if (_deferring or keeping_interrupts() or threading.current_thread() is not threading.main_thread()
            or not callable(previous := signal.getsignal(signal.SIGINT))):
        yield
        return
    pending: list[bool] = []

    def defer(signum: int, frame: Any) -> None:
        if pending:  # the second: now
            pending.clear()
            signal.signal(signal.SIGINT, previous)
            previous(signum, frame)
            return
        pending.append(True)
        with contextlib.suppress(OSError):
            os.write(2, DEFER_NOTE.encode())  # not print(): this may run while the main thread is writing to stderr

    _deferring.append(True)
    signal.signal(signal.SIGINT, defer)
    try:
        yield
    finally:
        if signal.getsignal(signal.SIGINT) is defer:
            signal.signal(signal.SIGINT, previous)
        _deferring.clear()
    if pending:
        previous(signal.SIGINT, sys._getframe())


_GUARDED: list[bool] = []


def guard_compiles() -> None:
    """Keep Ctrl-C during every outermost numba compile of this process (module docstring); once per process."""
    if _GUARDED:
        return
    _GUARDED.append(True)
    from numba.core import event

    class CompileInterrupts(event.Listener):
        """Enters :func:`interrupts_kept` and :func:`interrupts_deferred` at the start of an outermost compile and
        leaves them at its end (numba's compiles hold one process-wide lock, so their events nest). A Ctrl-C deferred
        to the end is raised from ``on_end``: after numba registered the compiled function, before it wrote the
        function to its disk cache (so the next process compiles it again)."""

        def __init__(self) -> None:
            self.depth = 0
            self.kept: contextlib.ExitStack | None = None

        def on_start(self, ev: event.Event) -> None:
            self.depth += 1
            if self.depth == 1 and not keeping_interrupts():
                self.kept = contextlib.ExitStack()
                self.kept.enter_context(interrupts_deferred())  # first: it stands aside while interrupts are kept
                self.kept.enter_context(interrupts_kept(sigint_of))

        def on_end(self, ev: event.Event) -> None:
            self.depth -= 1
            if self.depth == 0 and self.kept is not None:
                kept, self.kept = self.kept, None
                kept.close()

    event.register("numba:compile", CompileInterrupts())
