"""Per-tick statistics of a live run: lateness, compute time, misses, frames, watchdog.

:class:`TickStats` preallocates two int64 rings (lateness and compute time, ns) at
construction; :meth:`TickStats.record` writes one slot of each and updates a few int
counters, so the 1 kHz loop allocates nothing but the usual small-int boxing (ints
are not tracked by the garbage collector).

Who updates what:

- :meth:`record` (once per executed tick) maintains ``ticks``, ``late_over_1ms``
  (lateness strictly greater than 1,000,000 ns) and the whole-run maxima. The loop
  must **not** increment ``late_over_1ms`` itself.
- The loop increments the plain attributes ``missed`` (deadlines skipped, e.g.
  ``stats.missed += clock.skipped``), ``overruns`` (ticks whose wait found a deadline
  already passed), ``frames_in``, ``frames_out``, ``timeouts`` (sensor inputs that
  went stale) and ``watchdog_events`` (e.g. copied from ``Watchdog.events``).

Definitions. *Lateness* is how late the tick started relative to its deadline (the
value :meth:`flowtex.runtime.clock.DeadlineClock.wait` returns). *Compute* is the
tick's own work: signal decode + graph tick + signal encode, excluding bus
send/receive. Ticks skipped after an overrun are not executed, so they are counted in
``missed`` but have no lateness/compute sample.

Capacity. When a run lasts longer than ``capacity_ticks`` ticks, the rings wrap: the
counts (``ticks``, ``late_over_1ms``, ...) and the ``max`` values stay exact for the
whole run, while p50/p99/p99.9 are computed over the latest ``capacity_ticks`` ticks
(the summary reports that window as ``window_ticks``). With no ticks recorded the
percentiles are ``None`` (JSON ``null``).

Percentiles use numpy's default (linear interpolation between order statistics) and
are reported in microseconds as floats.
"""

from __future__ import annotations

import json
import os

import numpy as np

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
        self.late_over_1ms = 0
        self.lateness_max_ns = 0
        self.compute_max_ns = 0
        self.missed = 0
        self.overruns = 0
        self.frames_in = 0
        self.frames_out = 0
        self.timeouts = 0
        self.watchdog_events = 0
        self._status_from = 0

    def record(self, lateness_ns: int, compute_ns: int) -> None:
        """Store one executed tick's lateness and compute time (both ns)."""
        i = self.ticks % self.capacity
        self.lateness_ns[i] = lateness_ns
        self.compute_ns[i] = compute_ns
        self.ticks += 1
        if lateness_ns > LATE_LIMIT_NS:
            self.late_over_1ms += 1
        if lateness_ns > self.lateness_max_ns:
            self.lateness_max_ns = lateness_ns
        if compute_ns > self.compute_max_ns:
            self.compute_max_ns = compute_ns

    # -- views -----------------------------------------------------------------
    def _window(self, ring: np.ndarray) -> np.ndarray:
        """The recorded samples of ``ring`` (up to ``capacity`` latest), in no particular order."""
        return ring[: min(self.ticks, self.capacity)]

    def _recent(self, ring: np.ndarray, start_tick: int) -> np.ndarray:
        """Samples of ticks ``start_tick .. ticks-1`` (clipped to the ring), oldest first."""
        start = max(start_tick, self.ticks - self.capacity)
        if start >= self.ticks:
            return ring[:0]
        a = start % self.capacity
        b = self.ticks % self.capacity
        if a < b:
            return ring[a:b]
        return np.concatenate((ring[a:], ring[:b]))

    def _dist_us(self, ring: np.ndarray, max_ns: int) -> dict:
        w = self._window(ring)
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

        Keys: ``ticks``, ``missed``, ``late_over_1ms``, ``lateness_us`` and
        ``compute_us`` (each ``p50``, ``p99``, ``p999``, ``max``, ``mean``; µs floats,
        ``max`` over the whole run, the rest over the latest ``window_ticks``),
        ``frames_in``, ``frames_out``, ``watchdog_events``, ``rt`` (SCHED_FIFO granted),
        plus ``overruns``, ``timeouts``, ``window_ticks``, ``capacity_ticks``.
        """
        return {
            "ticks": int(self.ticks),
            "missed": int(self.missed),
            "late_over_1ms": int(self.late_over_1ms),
            "lateness_us": self._dist_us(self.lateness_ns, self.lateness_max_ns),
            "compute_us": self._dist_us(self.compute_ns, self.compute_max_ns),
            "frames_in": int(self.frames_in),
            "frames_out": int(self.frames_out),
            "watchdog_events": int(self.watchdog_events),
            "rt": bool(rt),
            "overruns": int(self.overruns),
            "timeouts": int(self.timeouts),
            "window_ticks": int(min(self.ticks, self.capacity)),
            "capacity_ticks": int(self.capacity),
        }

    def status_line(self) -> str:
        """One line for a live display (print with ``'\\r'``, e.g. every 0.5 s).

        Shows totals plus the max and mean lateness/compute of the ticks recorded since
        the previous call (a short window, so the call stays cheap inside the loop).
        """
        lat = self._recent(self.lateness_ns, self._status_from)
        comp = self._recent(self.compute_ns, self._status_from)
        self._status_from = self.ticks
        if lat.size:
            recent = (
                f"late mean {lat.mean() / 1e3:7.1f} max {lat.max() / 1e3:8.1f} us | "
                f"compute mean {comp.mean() / 1e3:6.1f} max {comp.max() / 1e3:7.1f} us"
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
                f"ticks {s['ticks']}  missed {s['missed']}  overruns {s['overruns']}  late>1ms {s['late_over_1ms']}  "
                f"rt {'SCHED_FIFO' if s['rt'] else 'no'}",
                f"lateness  {dist(s['lateness_us'])}",
                f"compute   {dist(s['compute_us'])}",
                f"frames in {s['frames_in']}  out {s['frames_out']}  timeouts {s['timeouts']}  watchdog events {s['watchdog_events']}",
            ]
        )

    def write_json(self, path: str | os.PathLike, rt: bool) -> None:
        """Write :meth:`summary` as JSON (UTF-8, indented) to ``path``."""
        with open(path, "w", encoding="utf-8") as f:
            json.dump(self.summary(rt), f, indent=2, allow_nan=False)
            f.write("\n")
