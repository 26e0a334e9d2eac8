"""What a live session prints while it runs: the status line and the watchdog events.

The status line (``\\r``-rewritten every 0.5 s) comes from
:meth:`~flowtex.runtime.stats.TickStats.status_line`; each watchdog event gets a line
of its own naming the graph input and sensor message (:func:`describe_event`).
Everything here runs in the slack after a tick's frames were sent.
"""

from __future__ import annotations

from typing import TextIO

from .canio import CanIO
from .safety import Watchdog
from .stats import TickStats


def describe_event(io: CanIO, watchdog: Watchdog, tick: int, reason: str, detail: int) -> str:
    """One line for a watchdog event of ``watchdog.log`` (``reason`` "stale": ``detail`` is the watchdog entry;
    "overrun": how late the tick started, in ns), naming the graph input and sensor message."""
    if reason == "stale":
        name, message = io.watchdog_keys[detail]
        what = f"no {message} frame for input {name!r} in {int(watchdog.timeouts[detail])} ticks"
    else:
        what = f"the tick started {detail / 1e6:.2f} ms late (limit {watchdog.overrun_limit_ns / 1e6:g} ms)"
    return f"watchdog: tick {tick}: {what}; outputs safe until every sensor has sent a fresh frame"


class StatusDisplay:
    """The status line and watchdog event lines of one session on ``out`` (a text stream, e.g. stderr).

    :meth:`tick` after every executed tick: prints new watchdog events at once and the
    status line every ``every`` ticks; :meth:`finish` prints what is left and the end summary.
    """

    def __init__(self, out: TextIO, io: CanIO, watchdog: Watchdog, stats: TickStats, every: int) -> None:
        self.out = out
        self.io = io
        self.watchdog = watchdog
        self.stats = stats
        self.every = max(1, int(every))
        self._shown = 0
        self._line_len = 0

    def tick(self, k: int) -> None:
        """Called after tick ``k - 1`` ran (``k`` ticks executed)."""
        if len(self.watchdog.log) != self._shown:
            self._events()
        if k % self.every == 0:
            self.stats.watchdog_events = self.watchdog.events
            self.stats.timeouts = self.watchdog.stale_events
            line = self.stats.status_line()
            self._line_len = len(line)
            print("\r" + line, end="", file=self.out, flush=True)

    def _events(self) -> None:
        """Print the watchdog events not shown yet on their own lines, over the status line."""
        wd = self.watchdog
        for tick, reason, detail in wd.log[self._shown:]:
            print("\r" + describe_event(self.io, wd, tick, reason, detail).ljust(self._line_len), file=self.out, flush=True)
        self._shown = len(wd.log)

    def finish(self, rt_granted: bool) -> None:
        """The remaining events, a last status line and the end-of-run summary."""
        self._events()
        print("\r" + self.stats.status_line(), file=self.out)
        print(self.stats.format_summary(rt_granted), file=self.out)
