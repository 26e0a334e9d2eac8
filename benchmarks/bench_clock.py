"""Clock benchmark: a plain time.sleep loop vs DeadlineClock (sleep then spin), each with and without --rt.

Runs each variant for N seconds at 1 kHz in this one process, side by side, with a
small busy "compute" per tick, and prints lateness p50/p99/p99.9/max (µs), ticks later
than 1 ms, and missed (skipped) deadlines. The baseline sleeps with ``time.sleep`` until
each absolute deadline (no spin, no skipping). The "rt" variants call
``enter_realtime()`` (SCHED_FIFO + CPU pinning; a warning is printed when refused) and
freeze the garbage collector for the loop, as ``flowtex live --rt`` does.

    python benchmarks/bench_clock.py [seconds=10] [--work-us 100] [--rate 1000]
"""

from __future__ import annotations

import argparse
import time

from flowtex.runtime.clock import DeadlineClock
from flowtex.runtime.realtime import enter_realtime, freeze_gc, leave_realtime
from flowtex.runtime.stats import TickStats


def busy(ns: int) -> None:
    end = time.perf_counter_ns() + ns
    while time.perf_counter_ns() < end:
        pass


def run_sleep_loop(seconds: float, rate: float, work_ns: int) -> TickStats:
    """Baseline: sleep with time.sleep until each absolute deadline, no spin."""
    period = int(round(1e9 / rate))
    n = int(seconds * rate)
    stats = TickStats(n)
    now = time.perf_counter_ns
    deadline = now()
    for _ in range(n):
        busy(work_ns)
        deadline += period
        rem = deadline - now()
        if rem > 0:
            time.sleep(rem * 1e-9)
        t = now()
        stats.record(t - deadline, work_ns)
    return stats


def run_deadline_clock(seconds: float, rate: float, work_ns: int) -> TickStats:
    clock = DeadlineClock(rate)
    n = int(seconds * rate)
    stats = TickStats(n)
    clock.start()
    while clock.tick < n:
        busy(work_ns)
        late = clock.wait()
        stats.record_skipped(clock.skipped, late, clock.period_ns)
        stats.record(late, work_ns)
    return stats


def with_rt(fn, *args):
    status = enter_realtime()
    if status.message:
        print(f"  warning: {status.message}")
    try:
        with freeze_gc():
            stats = fn(*args)
    finally:
        leave_realtime(status)
    return stats, status.granted


def row(name: str, s: TickStats, rt: bool) -> str:
    d = s.summary(rt)["lateness_us"]
    return (
        f"{name:<24s} {s.ticks:>7d} {d['p50']:>9.1f} {d['p99']:>9.1f} {d['p999']:>9.1f} {d['max']:>10.1f} "
        f"{s.late_over_1ms:>8d} {s.missed:>7d}  {'yes' if rt else 'no'}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("seconds", nargs="?", type=float, default=10.0, help="seconds per variant (default 10)")
    ap.add_argument("--rate", type=float, default=1000.0, help="tick rate in Hz (default 1000)")
    ap.add_argument("--work-us", type=float, default=100.0, help="busy work per tick in µs (default 100)")
    a = ap.parse_args()
    work_ns = int(a.work_us * 1000)
    print(f"{a.seconds:g} s per variant at {a.rate:g} Hz, {a.work_us:g} µs busy work per tick")
    rows = []
    s = run_sleep_loop(a.seconds, a.rate, work_ns)
    rows.append(row("time.sleep loop", s, False))
    s = run_deadline_clock(a.seconds, a.rate, work_ns)
    rows.append(row("DeadlineClock", s, False))
    s, granted = with_rt(run_sleep_loop, a.seconds, a.rate, work_ns)
    rows.append(row("time.sleep loop --rt", s, granted))
    s, granted = with_rt(run_deadline_clock, a.seconds, a.rate, work_ns)
    rows.append(row("DeadlineClock --rt", s, granted))
    print(f"{'lateness (µs)':<24s} {'ticks':>7s} {'p50':>9s} {'p99':>9s} {'p99.9':>9s} {'max':>10s} {'>1ms':>8s} {'missed':>7s}  rt")
    for r in rows:
        print(r)


if __name__ == "__main__":
    main()
