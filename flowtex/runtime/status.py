"""What a live session prints while it runs: the status line and the watchdog events.

The status line (``\\r``-rewritten every 0.5 s) comes from
:meth:`~flowtex.runtime.stats.TickStats.status_line`; each watchdog event gets a line
of its own naming the graph input and sensor message (:func:`describe_event`).
``--show SIGNAL`` appends chosen graph outputs or inputs to the status line
(:func:`resolve_shown`, :func:`format_values`), read from the graph's port views
when the line is printed. Everything here runs in the slack after a tick's frames were sent.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TextIO

import numpy as np

from ..errors import FlowtexError
from ..graph.program import TickProgram
from ..node_api import suggest
from .canio import CanIO
from .safety import Watchdog
from .stats import TickStats

if TYPE_CHECKING:  # the audio output is passed in; this module needs its type only
    from .audio import AudioOutput


def describe_event(io: CanIO, watchdog: Watchdog, tick: int, reason: str, detail: int) -> str:
    """One line for a watchdog event of ``watchdog.log`` (``reason`` "stale": ``detail`` is the watchdog entry;
    "overrun": how late the tick started, in ns), naming the graph input and sensor message."""
    if reason == "stale":
        name, message = io.watchdog_keys[detail]
        what = f"no {message} frame for input {name!r} in {int(watchdog.timeouts[detail])} ticks"
    else:
        what = f"the tick started {detail / 1e6:.2f} ms late (limit {watchdog.overrun_limit_ns / 1e6:g} ms)"
    return f"watchdog: tick {tick}: {what}; outputs safe until every sensor has sent a fresh frame"


Shown = tuple[str, np.ndarray, str]
"""(label, the port's current-tick view or one element of it, unit) of a ``--show`` signal."""

_NO_UNIT = ("", "1", "dimensionless")


def resolve_shown(graph: TickProgram, names: Sequence[str]) -> list[Shown]:
    """``--show`` arguments -> what the status line shows: ``NAME`` (a graph output, else a graph input; a vector shows
    every component) or ``NAME[i]`` (component ``i`` in C order). :class:`FlowtexError` naming the known ports otherwise."""
    outputs, inputs = graph.outputs, graph.inputs
    shown: list[Shown] = []
    for text in names:
        m = re.fullmatch(r"\s*([A-Za-z_][\w.]*)\s*(?:\[\s*(\d+)\s*\])?\s*", text)
        name = m.group(1) if m else text
        if name in outputs:
            view, spec = graph.output_view(name), outputs[name]
        elif name in inputs:
            view, spec = graph.input_view(name), inputs[name]
        else:
            known = list(outputs) + list(inputs)
            raise FlowtexError(f"--show {text!r}: graph {graph.name!r} has no output or input {name!r}{suggest(name, known)}; "
                               f"outputs: {', '.join(outputs) or 'none'}; inputs: {', '.join(inputs) or 'none'}")
        if m is None:
            raise FlowtexError(f"--show {text!r}: write a graph output or input as NAME or NAME[INDEX], e.g. {name}[0]")
        unit = "" if spec.unit in _NO_UNIT else spec.unit
        if m.group(2) is None:
            shown.append((name, view, unit))
            continue
        i = int(m.group(2))
        if not 0 <= i < view.shape[0]:
            raise FlowtexError(f"--show {text!r}: {name!r} has {view.shape[0]} component(s) (shape {list(spec.shape)}); "
                               f"the index must be 0..{view.shape[0] - 1}")
        shown.append((f"{name}[{i}]", view[i:i + 1], unit))
    return shown


def format_values(shown: Sequence[Shown]) -> str:
    """``"vibration 0.25 A | force [0.0123 -0.0045 0] N"``: each value with 4 significant digits (nan/inf as such)."""
    parts = []
    for label, view, unit in shown:
        vals = " ".join(f"{float(v):.4g}" for v in view)
        text = f"{label} {vals}" if view.shape[0] == 1 else f"{label} [{vals}]"
        parts.append(f"{text} {unit}" if unit else text)
    return " | ".join(parts)


CLAMP_WARN_FRACTION = 0.01
"""A session warns about an output clamped or peak-limited on more than this fraction of its ticks."""


GUARD_WORDS = {"clamped": "clamped", "peak_limited": "peak-limited", "nonfinite": "nonfinite"}
"""One word per guard event, the same in the status line, the end summary, ``--stats`` (its keys) and the warnings."""


def guard_counts(io: CanIO, audio: AudioOutput | None = None) -> dict[str, dict[str, int]]:
    """The session's guard events: :meth:`CanIO.guard_counts` per CAN output, with the audio channels' NaN/inf ticks
    (:meth:`AudioOutput.nonfinite_counts`) added to ``nonfinite`` after them. What the status line, the end summary and
    ``--stats`` report."""
    counts = io.guard_counts()
    if audio is not None:
        counts["nonfinite"].update(audio.nonfinite_counts())
    return counts


def guard_text(io: CanIO, audio: AudioOutput | None = None) -> str:
    """`` | clamped NAME N, ... | peak-limited NAME N | nonfinite NAME N`` for the kinds of guard event that occurred
    so far (one group per kind, the words of :data:`GUARD_WORDS`; :func:`guard_counts`), else ``""``."""
    counts = guard_counts(io, audio)
    groups = []
    for key, word in GUARD_WORDS.items():
        parts = [f"{name} {n}" for name, n in counts[key].items() if n]
        if parts:
            groups.append(f" | {word} {', '.join(parts)}")
    return "".join(groups)


def clamp_warnings(io: CanIO, ticks: int) -> list[str]:
    """One line per output clamped or peak-limited on more than 1 % of ``ticks`` (its busiest component), named by
    what happened: ``clamped``, ``peak-limited`` or both (:data:`GUARD_WORDS`)."""
    if ticks <= 0:
        return []
    counts = io.guard_counts()
    lines = []
    for name, n in io.limited_ticks().items():
        if n > CLAMP_WARN_FRACTION * ticks:
            b = io.map.outputs[name]
            clamped, peaked = counts["clamped"][name] > 0, counts["peak_limited"][name] > 0
            word = " or ".join(GUARD_WORDS[k] for k, on in (("clamped", clamped), ("peak_limited", peaked)) if on)
            limit = f"clamp [{b.lo.min():g}, {b.hi.max():g}]"
            if peaked:
                limit = f"{limit} and its peak allowance" if clamped else f"the peak allowance of {limit}"
            lines.append(f"output {name!r} was {word} on {n} of {ticks} ticks ({100.0 * n / ticks:.1f} %, over the "
                         f"{100 * CLAMP_WARN_FRACTION:g} % warning level): the graph commands more than {limit} "
                         f"in {io.map.path.name} allows; check the graph's gains or the clamp")
    return lines


class StatusDisplay:
    """The status line and watchdog event lines of one session on ``out`` (a text stream, e.g. stderr).

    :meth:`tick` after every executed tick: prints new watchdog events at once and the
    status line every ``every`` ticks, followed by the ``shown`` values (:func:`resolve_shown`);
    :meth:`finish` prints what is left and the end summary.

    On a terminal the status line is rewritten in place (``\\r``). Anywhere else (a log file, a pipe to ``tee``,
    CI) every line ends with a newline and the status line comes every :data:`LOG_EVERY` terminal refreshes, so a
    session's log is lines a reader can grep rather than one line of carriage returns.
    """

    LOG_EVERY = 10
    """Status lines to a non-terminal: one per this many terminal refreshes (5 s at the default 0.5 s)."""

    EVENT_LINES = 3
    """Watchdog events printed one by one per status period (``every`` ticks). A machine too loaded to keep time trips
    the overrun watchdog again and again (hundreds of lines in a few seconds buried the status line); the period's other
    events are counted into one line when the period ends (:meth:`_held_back`). The status line, the end summary and
    ``--stats`` count every event."""

    def __init__(self, out: TextIO | None, io: CanIO, watchdog: Watchdog, stats: TickStats, every: int, shown: Sequence[Shown] = ()) -> None:
        self.out = out
        self.shown = list(shown)
        self.io = io
        self.watchdog = watchdog
        self.stats = stats
        self.tty = bool(getattr(out, "isatty", lambda: False)())
        self.every = max(1, int(every)) * (1 if self.tty else self.LOG_EVERY)
        self._cr = "\r" if self.tty else ""
        self._shown = 0
        self._line_len = 0
        self.extra: Callable[[], str] | None = None
        """Returns more counters for the status line (the audio output's underruns)."""
        self.audio: AudioOutput | None = None
        """The session's audio output, whose NaN/inf ticks the guard groups show (:func:`guard_counts`)."""
        self._lines_left = self.EVENT_LINES
        self._held: list[int] = []
        """Ticks of this period's events past :data:`EVENT_LINES`, printed as one line when the period ends."""

    def tick(self, k: int) -> None:
        """Called after tick ``k - 1`` ran (``k`` ticks executed)."""
        if len(self.watchdog.log) != self._shown:
            self._events()
        if k % self.every == 0:
            self._held_back()
            self.stats.watchdog_events = self.watchdog.events
            self.stats.timeouts = self.watchdog.stale_events
            line = self.line()
            self._line_len = len(line)
            self._write(self._cr + line + ("" if self.tty else "\n"))

    def line(self) -> str:
        """The status line: timing and counters, the outputs the guard limited so far, then the shown values."""
        line = self.stats.status_line() + guard_text(self.io, self.audio)
        if self.extra is not None:
            line = f"{line} | {self.extra()}"
        return f"{line} | {format_values(self.shown)}" if self.shown else line

    def _events(self) -> None:
        """Print the watchdog events not shown yet on their own lines, over the status line: at most
        :data:`EVENT_LINES` a period, the others held back for :meth:`_held_back`."""
        wd = self.watchdog
        for tick, reason, detail in wd.log[self._shown:]:
            if self._lines_left > 0:
                self._lines_left -= 1
                self._over_status(describe_event(self.io, wd, tick, reason, detail))
            else:
                self._held.append(tick)
        self._shown = len(wd.log)

    def _held_back(self) -> None:
        """One line for the events of the period ending now that were not printed one by one; a new period begins."""
        if self._held:
            first, last, n = self._held[0], self._held[-1], len(self._held)
            self._over_status(f"watchdog: {n} more event{'s' if n > 1 else ''} in ticks {first}-{last} (outputs safe at "
                              f"each; at most {self.EVENT_LINES} shown one by one each {self.every} ticks; the status line "
                              "and the summary count them all)")
        self._held, self._lines_left = [], self.EVENT_LINES

    def _over_status(self, line: str) -> None:
        """``line`` on a line of its own, over the status line on a terminal."""
        self._write(self._cr + (line.ljust(self._line_len) if self.tty else line) + "\n")

    def finish(self, rt_granted: bool) -> None:
        """The remaining events, a last status line and the end-of-run summary."""
        self._events()
        self._held_back()
        self._write(self._cr + self.line() + "\n" + self.stats.format_summary(rt_granted) + "\n")

    def _write(self, text: str) -> None:
        """Write and flush ``text``; a stream that refuses (the terminal gone, a closed pipe: EIO, EPIPE) is dropped
        for the rest of the session. The display only informs: it must not end a session, which its safety, its
        signals (SIGHUP when the terminal closes) and --stats already cover."""
        if self.out is None:
            return
        try:
            self.out.write(text)
            self.out.flush()
        except (OSError, ValueError):  # ValueError: a closed file object
            self.out = None
