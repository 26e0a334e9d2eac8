"""Real-time setup for the live loop: SCHED_FIFO + CPU affinity (best effort), GC freeze.

:func:`enter_realtime` asks Linux for the SCHED_FIFO policy at a given priority and pins
the calling thread to one CPU. Both need privileges (root, ``CAP_SYS_NICE`` or an
``rtprio`` limit in ``/etc/security/limits.conf``); when refused it never raises: it
returns a :class:`RealtimeStatus` with ``granted=False`` and a one-line ``message`` the
caller prints as a warning, and the loop continues under the normal scheduler. On Linux
``sched_setscheduler(0, ...)`` and ``sched_setaffinity(0, ...)`` apply to the calling
thread, so call it from the thread that runs the loop. :func:`leave_realtime` restores
what :func:`enter_realtime` changed.

:func:`freeze_gc` is a context manager for the loop: it runs a full collection, moves
every surviving object into the permanent generation (``gc.freeze()``, so later
collections never scan them) and disables the collector. Measured here, GC pauses of
10-300 ms otherwise hit the loop. On exit the collector is re-enabled (if it was) and the
frozen objects are returned to the oldest generation, unless the caller had frozen objects
itself: Python cannot unfreeze part of the permanent generation, so then everything frozen
stays frozen, the caller's objects as the caller wanted and the session's survivors with
them (still freed by reference counting; only cycles among them wait for an unfreeze).
"""

from __future__ import annotations

import contextlib
import gc
import os
from collections.abc import Iterator
from dataclasses import dataclass, field


@dataclass
class RealtimeStatus:
    """Outcome of :func:`enter_realtime`.

    ``granted`` is True when SCHED_FIFO was set (this is the ``rt`` flag of the stats
    JSON); ``cpu`` is the CPU the thread was pinned to, or None when pinning was not
    asked for or refused; ``message`` is one line for the user (empty when all was
    granted).
    """

    granted: bool
    priority: int
    cpu: int | None
    message: str = ""
    _old_policy: int | None = field(default=None, repr=False)
    _old_priority: int = field(default=0, repr=False)
    _old_affinity: set[int] | None = field(default=None, repr=False)


def _default_cpu(allowed: set[int]) -> int:
    """Highest-numbered allowed CPU: CPU 0 usually takes the most interrupts."""
    return max(allowed)


def enter_realtime(priority: int = 50, cpu: int | None = None) -> RealtimeStatus:
    """Ask for SCHED_FIFO at ``priority`` (1-99) and pin the thread to ``cpu``; never raises.

    ``cpu=None`` pins to the highest-numbered CPU this process may use. Failures (no
    permission, unsupported platform, CPU not allowed) are reported in the returned
    status's ``message``; the scheduling policy and the affinity are tried
    independently, so a refused policy can still leave the thread pinned.
    """
    problems: list[str] = []
    status = RealtimeStatus(granted=False, priority=int(priority), cpu=None)
    if not hasattr(os, "sched_setscheduler") or not hasattr(os, "SCHED_FIFO"):
        status.message = "real-time scheduling is not available on this platform; running with normal scheduling"
        return status
    try:
        lo = os.sched_get_priority_min(os.SCHED_FIFO)
        hi = os.sched_get_priority_max(os.SCHED_FIFO)
        if not lo <= priority <= hi:
            problems.append(f"priority {priority} outside SCHED_FIFO range {lo}..{hi}")
        else:
            status._old_policy = os.sched_getscheduler(0)
            status._old_priority = os.sched_getparam(0).sched_priority
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
            status.granted = True
    except (PermissionError, OSError) as e:
        status._old_policy = None
        problems.append(f"SCHED_FIFO refused ({e.strerror or e}); grant CAP_SYS_NICE or an rtprio limit, or run as root")
    try:
        allowed = os.sched_getaffinity(0)
        target = _default_cpu(allowed) if cpu is None else int(cpu)
        if target not in allowed:
            problems.append(f"CPU {target} is not among the allowed CPUs {sorted(allowed)}")
        else:
            os.sched_setaffinity(0, {target})
            status._old_affinity = set(allowed)
            status.cpu = target
    except (PermissionError, OSError) as e:
        problems.append(f"CPU affinity refused ({e.strerror or e})")
    if problems:
        status.message = "real-time setup incomplete: " + "; ".join(problems) + "; continuing"
    return status


def leave_realtime(status: RealtimeStatus) -> None:
    """Undo what :func:`enter_realtime` changed (policy and affinity); never raises.

    ``status`` keeps its ``granted``/``cpu`` fields (they describe the run); calling this
    twice is harmless.
    """
    if status._old_policy is not None and status.granted:
        with contextlib.suppress(OSError):
            os.sched_setscheduler(0, status._old_policy, os.sched_param(status._old_priority))
        status._old_policy = None
    if status._old_affinity is not None:
        with contextlib.suppress(OSError):
            os.sched_setaffinity(0, status._old_affinity)
        status._old_affinity = None


@contextlib.contextmanager
def freeze_gc() -> Iterator[None]:
    """Collect, freeze and disable the garbage collector for the ``with`` body; restore after.

    A caller's frozen objects stay frozen (module docstring): unfreezing them would hand the whole of a long-lived
    process's heap back to every later full collection, which then walks it (a test run's workers, a server that
    froze its start-up state)."""
    was_enabled = gc.isenabled()
    caller_froze = gc.get_freeze_count() > 0
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        if not caller_froze:
            gc.unfreeze()
        if was_enabled:
            gc.enable()
