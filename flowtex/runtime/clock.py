"""Deadline clock for the live loop: sleep until just before each deadline, then spin.

Why this shape. A plain ``time.sleep(period)`` loop drifts (each sleep adds its own
overshoot) and, measured here, misses 1 ms deadlines hundreds of times per 30 s under
load. A pure spin holds time well but burns a whole core and is preempted by the
kernel scheduler anyway. The compromise used here: deadlines are absolute
(``t0 + k * period``, no drift), the thread sleeps until ``spin_s`` before the next
deadline and then spins on the clock for the last stretch (``spin_s`` is capped at
half a period, so the loop never degenerates into a pure spin). Under SCHED_FIFO
(see :mod:`flowtex.runtime.realtime`) this gave p99 lateness of 2-6 us.

Overrun rule (no catch-up bursts). ``wait()`` is called once per tick, after the
tick's work. If, when it is called, the deadline of the next tick has already passed
(the work plus I/O took longer than a period), the clock does **not** return
immediately to run the passed ticks back to back: it skips to the first deadline at
or after the present moment, adds the number of skipped deadlines to ``missed`` and
advances ``tick`` by ``1 + skipped``. A deadline that is exactly "now" counts as not
passed (lateness 0). Lateness returned by ``wait()`` is therefore the lateness of the
moment it returned relative to the deadline it waited for (sleep overshoot, spin
granularity, preemption); it can exceed a period only if the thread was descheduled
during the sleep/spin itself, and that tick is then late, not missed.

Catching up (``catch_up_s``, default 0: off). A loop that feeds a sound card must not
lose ticks to a short stall: the sound card keeps playing at its own rate, and a
tick not run is a gap in the audio. With ``catch_up_s > 0``, a next deadline that
passed less than ``catch_up_s`` ago is not skipped: ``wait()`` returns at once (the
tick is late, not missed), and the following ticks run back to back until the loop
is on time again. A stall longer than that is skipped as above. The live loop uses
the audio map's ``margin_ms`` here: the stall its margin absorbs.

Usage::

    clock = DeadlineClock(1000.0)
    clock.start()                  # tick 0's deadline is now
    while running:
        ...one tick of work...
        lateness_ns = clock.wait() # now at tick clock.tick
        if clock.skipped: ...      # deadlines skipped by this wait (also summed in clock.missed)

Preparing. ``prepare`` (optional) is called once per wait, ``prepare_lead_s`` before
the deadline, in the spin. The live loop passes the work that belongs just before a
tick: receiving the frames that have already arrived, and one effect-free warming
pass through the tick's code (after a sleep the first run of that code was 2-4x
slower than in a tight loop: caches and branch predictors belong to whatever ran
while this thread slept, and warming during the spin, close to the deadline, brings
it most of the way back). If the sleep overshot past that moment, ``prepare`` is
skipped for that tick rather than made to delay it.

``now`` and ``sleep`` are injectable so tests can drive the clock with a fake time
source; ``now`` must return integer nanoseconds, ``sleep`` takes seconds.
"""

from __future__ import annotations

import time
from collections.abc import Callable


class DeadlineClock:
    """Absolute-deadline clock at ``rate_hz`` (sleep then spin; skips, never bursts).

    Attributes (read them, do not write them):

    - ``period_ns``: the period in integer nanoseconds (``round(1e9 / rate_hz)``).
    - ``tick``: index of the current tick (0 after :meth:`start`).
    - ``deadline_ns``: absolute deadline of the current tick, in ``now()`` units (ns).
    - ``missed``: total deadlines skipped after overruns since :meth:`start`.
    - ``skipped``: deadlines skipped by the most recent :meth:`wait` (0 normally).
    """

    def __init__(
        self,
        rate_hz: float,
        spin_s: float = 200e-6,
        sleep: Callable[[float], None] = time.sleep,
        now: Callable[[], int] = time.perf_counter_ns,
        prepare: Callable[[], object] | None = None,
        prepare_lead_s: float = 50e-6,
        catch_up_s: float = 0.0,
    ) -> None:
        if not (rate_hz > 0.0) or rate_hz == float("inf"):
            raise ValueError(f"DeadlineClock: rate_hz must be a positive finite number of Hz, got {rate_hz!r}")
        if not (spin_s >= 0.0) or spin_s == float("inf"):
            raise ValueError(f"DeadlineClock: spin_s must be a finite number of seconds >= 0, got {spin_s!r}")
        period_ns = int(round(1e9 / rate_hz))
        if period_ns < 1:
            raise ValueError(f"DeadlineClock: rate_hz={rate_hz!r} gives a period below 1 ns")
        self.rate_hz = float(rate_hz)
        self.period_ns = period_ns
        # spin at most half a period, so every period has a sleep (never a pure spin)
        self.spin_ns = min(int(round(spin_s * 1e9)), period_ns // 2)
        if not (prepare_lead_s >= 0.0) or prepare_lead_s == float("inf"):
            raise ValueError(f"DeadlineClock: prepare_lead_s must be a finite number of seconds >= 0, got {prepare_lead_s!r}")
        if not (catch_up_s >= 0.0) or catch_up_s == float("inf"):
            raise ValueError(f"DeadlineClock: catch_up_s must be a finite number of seconds >= 0, got {catch_up_s!r}")
        self.catch_up_ns = int(round(catch_up_s * 1e9))
        self._sleep = sleep
        self._now = now
        self._prepare = prepare
        self.prepare_lead_ns = min(int(round(prepare_lead_s * 1e9)), self.spin_ns)
        self.tick = 0
        self.deadline_ns = 0
        self.missed = 0
        self.skipped = 0
        self._started = False

    def start(self) -> None:
        """Begin at tick 0 with its deadline set to the present moment; reset counters."""
        self.deadline_ns = int(self._now())
        self.tick = 0
        self.missed = 0
        self.skipped = 0
        self._started = True

    def wait(self) -> int:
        """Block until the next tick's deadline; return lateness in ns of the return moment.

        Sleeps (possibly in several pieces, should a sleep return early) until
        ``spin_ns`` before the deadline, then spins on ``now()`` until the deadline is
        reached, calling ``prepare`` once ``prepare_lead_ns`` before it. If the next deadline
        has already passed when called, skips to the first deadline at or after now
        (see the module docstring) and counts the skipped ones in ``missed`` and
        ``skipped``.
        """
        if not self._started:
            raise RuntimeError("DeadlineClock.wait() called before start()")
        period = self.period_ns
        target = self.deadline_ns + period
        now = self._now()
        skipped = 0
        if now > target and now - target <= self.catch_up_ns:
            pass  # behind by less than the catch-up allowance: run this tick now (late, not missed)
        elif now > target:
            # Overrun: the deadlines target, target+period, ... up to the last one
            # strictly before now have passed. Skip them all but land on the
            # first deadline >= now.
            skipped = (now - target + period - 1) // period
            target += skipped * period
        self.skipped = skipped
        self.missed += skipped
        self.tick += 1 + skipped
        self.deadline_ns = target
        spin = self.spin_ns
        sleep = self._sleep
        remaining = target - now
        while remaining > spin:
            sleep((remaining - spin) * 1e-9)
            now = self._now()
            remaining = target - now
        prepare = self._prepare
        if prepare is not None:
            prepare_at = target - self.prepare_lead_ns
            if now < prepare_at:
                while now < prepare_at:
                    now = self._now()
                prepare()
                now = self._now()
        while now < target:
            now = self._now()
        return now - target

    def shift(self, ns: int) -> None:
        """Move the current deadline, and so every later one, by ``ns`` (positive: later); for a clock that
        follows another one, e.g. the sound card's (:meth:`flowtex.runtime.audio.AudioOutput.pace`)."""
        self.deadline_ns += int(ns)

    def time_left_ns(self) -> int:
        """Nanoseconds from now until the next tick's deadline (negative once it has passed)."""
        return self.deadline_ns + self.period_ns - self._now()
