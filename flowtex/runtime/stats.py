"""Per-tick statistics of a live run: lateness (of every deadline, skipped ones included), compute time, stalls, frames.

:class:`TickStats` preallocates two int64 rings (lateness per deadline and compute
time per executed tick, ns) at construction; :meth:`TickStats.record` writes one slot
of each and updates a few int counters, so the 1 kHz loop allocates nothing but the
usual small-int boxing (ints are not tracked by the garbage collector).

Who updates what:

- :meth:`record` (once per executed tick) maintains ``ticks``, ``deadlines``,
  ``late_over_1ms`` (lateness strictly greater than 1,000,000 ns) and the whole-run maxima.
- :meth:`record_skipped` (once per wait that skipped deadlines, before the
  :meth:`record` of the tick that ran after them) maintains ``missed``, ``overruns``
  (stalls), ``longest_stall_ns`` and counts the skipped deadlines in ``deadlines``,
  the lateness ring, ``late_over_1ms`` and the lateness maximum.
  The loop must **not** increment these counters itself.
- The loop increments the plain attributes ``frames_in``, ``frames_out``,
  ``timeouts`` (sensor inputs that went stale) and ``watchdog_events`` (e.g. copied
  from ``Watchdog.events``).

Definitions. *Lateness* is how late the tick of a deadline started: for an executed
tick, the value :meth:`flowtex.runtime.clock.DeadlineClock.wait` returns. A skipped
deadline had no tick and no command sent for it; it counts with the lateness it
would have had, from its deadline to the moment the loop resumed (the start of the
next executed tick), so a stall of ``s`` skipped deadlines before a tick starting
``L`` ns late adds the lateness values ``s*P + L, ..., 2*P + L, P + L`` (``P`` the
period). That stall's length is ``s*P + L``: from the first deadline without a tick
to the moment the loop resumed; ``longest_stall_ns`` is the longest. *Compute* is the
tick's own work: signal decode + graph tick + signal encode, excluding bus
send/receive; skipped deadlines have no compute sample.

Capacity. When a run lasts longer than ``capacity_ticks`` deadlines, the rings wrap:
the counts (``ticks``, ``late_over_1ms``, ...) and the ``max`` values stay exact for
the whole run, while p50/p99/p99.9 are computed over the latest ``capacity_ticks``
deadlines (lateness) or executed ticks (compute); the summary reports those windows
as ``lateness_window`` and ``window_ticks``. With no ticks recorded the percentiles
are ``None`` (JSON ``null``).

Percentiles use numpy's default (linear interpolation between order statistics) and
are reported in microseconds as floats.
"""

from __future__ import annotations

import os

import numpy as np

from ..io.atomic import write_json_atomic

LATE_LIMIT_NS = 1_000_000
"""Lateness above this (1 ms, strictly greater) counts in ``late_over_1ms``."""

_PERCENTILES = (("p50", 50.0), ("p99", 99.0), ("p999", 99.9))


class TickStats:
    """Preallocated per-tick lateness/compute rings plus run counters (see module docstring)."""

    def __init__(self, capacity_ticks: int) -> None:
        capacity_ticks = int(capacity_ticks)
        if capacity_ticks < 1:
            raise ValueError(f"TickStats: capacity_ticks must be >= 1, got {capacity_ticks}")
        self.capacity = capacity_ticks
        self.lateness_ns = np.zeros(capacity_ticks, dtype=np.int64)
        self.compute_ns = np.zeros(capacity_ticks, dtype=np.int64)
        self.ticks = 0
        self.deadlines = 0
        """Executed ticks plus skipped deadlines: the samples written to the lateness ring."""
        self.late_over_1ms = 0
        self.lateness_max_ns = 0
        self.compute_max_ns = 0
        self.missed = 0
        self.overruns = 0
        self.longest_stall_ns = 0
        self.frames_in = 0
        self.frames_out = 0
        self.timeouts = 0
        self.watchdog_events = 0
        self._status_from = 0
        self._status_from_deadline = 0
        self.guard: dict[str, dict[str, int]] | None = None
        """Output guard events per output (``clamped``, ``peak_limited``, ``nonfinite``; see
        :meth:`~flowtex.runtime.canio.CanIO.guard_counts`), set by the loop at the end; in :meth:`summary` when set."""

    def record(self, lateness_ns: int, compute_ns: int) -> None:
        """Store one executed tick's lateness and compute time (both ns)."""
        self.compute_ns[self.ticks % self.capacity] = compute_ns
        self.ticks += 1
        self.lateness_ns[self.deadlines % self.capacity] = lateness_ns
        self.deadlines += 1
        if lateness_ns > LATE_LIMIT_NS:
            self.late_over_1ms += 1
        if lateness_ns > self.lateness_max_ns:
            self.lateness_max_ns = lateness_ns
        if compute_ns > self.compute_max_ns:
            self.compute_max_ns = compute_ns

    def record_skipped(self, skipped: int, resumed_lateness_ns: int, period_ns: int) -> None:
        """Count ``skipped`` deadlines that passed without a tick before the loop resumed ``resumed_lateness_ns``
        after the deadline it resumed at (``period_ns`` apart; see the module docstring).

        Call it when :meth:`~flowtex.runtime.clock.DeadlineClock.wait` reports skipped
        deadlines, with the lateness that wait returned, before recording the tick that runs then.
        """
        skipped, late, period = int(skipped), int(resumed_lateness_ns), int(period_ns)
        if skipped <= 0:
            return
        if period <= 0:
            raise ValueError(f"TickStats.record_skipped: period_ns must be > 0, got {period_ns}")
        stall = skipped * period + late
        self.missed += skipped
        self.overruns += 1
        self.longest_stall_ns = max(self.longest_stall_ns, stall)
        self.lateness_max_ns = max(self.lateness_max_ns, stall)
        # lateness j*P + L of the deadline j periods before the resumed one is > 1 ms for j > (1 ms - L) / P
        on_time = min(skipped, (LATE_LIMIT_NS - late) // period) if late <= LATE_LIMIT_NS else 0
        self.late_over_1ms += skipped - on_time
        n = min(skipped, self.capacity)  # the ring keeps the latest n (those closest to the resumed deadline)
        slots = (self.deadlines + skipped - n + np.arange(n)) % self.capacity
        self.lateness_ns[slots] = np.arange(n, 0, -1, dtype=np.int64) * period + late
        self.deadlines += skipped

    # -- views -----------------------------------------------------------------
    def _recent(self, ring: np.ndarray, start: int, count: int) -> np.ndarray:
        """Samples ``start .. count-1`` of ``ring`` holding ``count`` samples so far (clipped to the ring), oldest first."""
        start = max(start, count - self.capacity)
        if start >= count:
            return ring[:0]
        a = start % self.capacity
        b = count % self.capacity
        if a < b:
            return ring[a:b]
        return np.concatenate((ring[a:], ring[:b]))

    def _dist_us(self, ring: np.ndarray, count: int, max_ns: int) -> dict:
        """Percentiles, mean (over the ring's latest ``count`` samples, up to capacity) and ``max_ns``, in us."""
        w = ring[: min(count, self.capacity)]
        out: dict = {}
        if w.size == 0:
            for key, _ in _PERCENTILES:
                out[key] = None
            out["max"] = None
            out["mean"] = None
            return out
        qs = np.percentile(w, [q for _, q in _PERCENTILES])
        for (key, _), v in zip(_PERCENTILES, qs, strict=True):
            out[key] = float(v) / 1e3
        out["max"] = float(max_ns) / 1e3
        out["mean"] = float(np.mean(w)) / 1e3
        return out

    # -- reports ---------------------------------------------------------------
    def summary(self, rt: bool) -> dict:
        """End-of-run summary; the dict written by :meth:`write_json`.

        Keys: ``ticks`` (executed), ``missed`` (deadlines skipped), ``deadlines`` (both),
        ``late_over_1ms`` (deadlines, executed or skipped, whose tick started more than 1 ms
        late), ``lateness_us`` (over every deadline) and ``compute_us`` (over executed
        ticks), each ``p50``, ``p99``, ``p999``, ``max``, ``mean`` (µs floats, ``max`` over
        the whole run, the rest over the latest ``lateness_window`` / ``window_ticks``),
        ``longest_stall_us`` (0 without a skipped deadline), ``overruns`` (stalls: waits that
        skipped deadlines), ``frames_in``, ``frames_out``, ``watchdog_events``, ``timeouts``,
        ``rt`` (SCHED_FIFO granted), ``capacity_ticks``; when :attr:`guard` is set, ``clamped``,
        ``peak_limited`` and ``nonfinite``, each ``{output: events}``.
        """
        return {
            "ticks": int(self.ticks),
            "missed": int(self.missed),
            "deadlines": int(self.deadlines),
            "late_over_1ms": int(self.late_over_1ms),
            "lateness_us": self._dist_us(self.lateness_ns, self.deadlines, self.lateness_max_ns),
            "compute_us": self._dist_us(self.compute_ns, self.ticks, self.compute_max_ns),
            "longest_stall_us": float(self.longest_stall_ns) / 1e3,
            "frames_in": int(self.frames_in),
            "frames_out": int(self.frames_out),
            "watchdog_events": int(self.watchdog_events),
            "rt": bool(rt),
            "overruns": int(self.overruns),
            "timeouts": int(self.timeouts),
            "window_ticks": int(min(self.ticks, self.capacity)),
            "lateness_window": int(min(self.deadlines, self.capacity)),
            "capacity_ticks": int(self.capacity),
            **(self.guard or {}),
        }

    def status_line(self) -> str:
        """One line for a live display (print with ``'\\r'``, e.g. every 0.5 s).

        Shows totals plus the max and mean lateness/compute of the deadlines and ticks recorded
        since the previous call (a short window, so the call stays cheap inside the loop).
        """
        lat = self._recent(self.lateness_ns, self._status_from_deadline, self.deadlines)
        comp = self._recent(self.compute_ns, self._status_from, self.ticks)
        self._status_from, self._status_from_deadline = self.ticks, self.deadlines
        if lat.size:
            recent = (
                f"late mean {lat.mean() / 1e3:7.1f} max {lat.max() / 1e3:8.1f} us | "
                + (f"compute mean {comp.mean() / 1e3:6.1f} max {comp.max() / 1e3:7.1f} us" if comp.size else "compute        -           -   ")
            )
        else:
            recent = "late        -           -    | compute        -           -   "
        return (
            f"tick {self.ticks:>9d} | {recent} | missed {self.missed} | >1ms {self.late_over_1ms} | "
            f"in {self.frames_in} out {self.frames_out} | timeouts {self.timeouts} | watchdog {self.watchdog_events}"
        )

    def format_summary(self, rt: bool) -> str:
        """Multi-line human-readable end-of-run summary (same numbers as :meth:`summary`)."""
        s = self.summary(rt)

        def dist(d: dict) -> str:
            if d["max"] is None:
                return "no ticks"
            return f"p50 {d['p50']:.1f}  p99 {d['p99']:.1f}  p99.9 {d['p999']:.1f}  max {d['max']:.1f} us"

        return "\n".join(
            [
                f"ticks {s['ticks']}  missed {s['missed']}"
                + (f" in {s['overruns']} stall(s), longest {s['longest_stall_us'] / 1e3:.2f} ms" if s["missed"] else "")
                + f"  late>1ms {s['late_over_1ms']} (skipped deadlines included)  rt {'SCHED_FIFO' if s['rt'] else 'no'}",
                f"lateness  {dist(s['lateness_us'])}" + (" (every deadline, skipped ones included)" if s["missed"] else ""),
                f"compute   {dist(s['compute_us'])}",
                f"frames in {s['frames_in']}  out {s['frames_out']}  timeouts {s['timeouts']}  watchdog events {s['watchdog_events']}",
            ]
            + [f"guard     {key.replace('_', '-')} " + ", ".join(f"{k} {v}" for k, v in self.guard[key].items())
               for key in ("clamped", "peak_limited", "nonfinite") if self.guard and any(self.guard.get(key, {}).values())]
        )

    def write_json(self, path: str | os.PathLike, rt: bool, extra: dict | None = None) -> None:
        """Write :meth:`summary` (plus the entries of ``extra``, e.g. ``"audio"``) as JSON (UTF-8, indented) to ``path``
        (atomically: :func:`~flowtex.io.atomic.write_json_atomic`)."""
        write_json_atomic(path, {**self.summary(rt), **(extra or {})})
