"""DeadlineClock: skip/miss logic with a fake time source (exact), plus a short real run (counts only)."""

from __future__ import annotations

import time

import pytest

from flowtex.runtime.clock import DeadlineClock

MS = 1_000_000
US = 1_000


class FakeTime:
    """Fake monotonic clock: every now() call costs ``step`` ns; sleep(s) advances s (+ oversleep)."""

    def __init__(self, t0: int = 10 * MS, step: int = US, oversleep: int = 0, sleep_fraction: float = 1.0) -> None:
        self.t = t0
        self.step = step
        self.oversleep = oversleep
        self.sleep_fraction = sleep_fraction
        self.sleeps: list[float] = []
        self.now_calls = 0

    def now(self) -> int:
        v = self.t
        self.t += self.step
        self.now_calls += 1
        return v

    def sleep(self, s: float) -> None:
        assert s > 0, "never sleeps for a non-positive time"
        self.sleeps.append(s)
        self.t += int(round(s * 1e9 * self.sleep_fraction)) + self.oversleep

    def work(self, ns: int) -> None:
        self.t += ns


def make(rate: float = 1000.0, spin_s: float = 200e-6, **kw) -> tuple[DeadlineClock, FakeTime]:
    ft = FakeTime(**kw)
    c = DeadlineClock(rate, spin_s=spin_s, sleep=ft.sleep, now=ft.now)
    return c, ft


def test_steady_ticks_hit_absolute_deadlines():
    c, ft = make()
    c.start()
    t0 = 10 * MS  # the first now() call returns t0
    for k in range(1, 21):
        ft.work(300 * US)
        nsleep = len(ft.sleeps)
        late = c.wait()
        assert c.tick == k
        assert c.deadline_ns == t0 + k * MS  # absolute: no drift
        assert c.missed == 0 and c.skipped == 0
        # exactly one sleep, ending spin_s before the deadline (sleep then spin, never pure spin)
        assert len(ft.sleeps) == nsleep + 1
        # returned lateness is what the fake clock said at return; spin steps are 1 us
        assert 0 <= late < US
        assert ft.t - ft.step == c.deadline_ns + late


def test_sleep_argument_leaves_spin_margin():
    c, ft = make(step=0 + 1)  # 1 ns per now() call
    c.start()  # now() -> t0, t becomes t0+1
    ft.work(300 * US - 1)  # wait's first now() returns exactly t0 + 300 us
    c.wait()
    # remaining = 700 us, spin 200 us -> sleep 500 us
    assert ft.sleeps[0] == pytest.approx(500e-6, abs=1e-12)


def test_spin_duration_bounded_by_spin_s():
    c, ft = make(spin_s=200e-6, step=US)
    c.start()
    ft.work(100 * US)
    before = ft.now_calls
    c.wait()
    # one now() at entry, one after the sleep, then the spin: <= 200 us / 1 us + 1 calls
    spin_calls = ft.now_calls - before - 2
    assert 0 <= spin_calls <= 201


def test_spin_is_capped_at_half_a_period():
    c, ft = make(rate=1000.0, spin_s=5e-3, step=1)
    assert c.spin_ns == 500_000
    c.start()
    ft.work(100 * US - 1)
    c.wait()
    assert ft.sleeps and ft.sleeps[0] == pytest.approx(400e-6, abs=1e-12)


def test_overrun_skips_without_burst():
    c, ft = make()
    c.start()
    t0 = 10 * MS
    ft.work(300 * US)
    c.wait()  # tick 1 at t0 + 1 ms
    assert c.tick == 1
    # the work of tick 1 lasts 2.5 ms: deadlines of ticks 2 and 3 pass (t0+2ms, t0+3ms)
    ft.work(2_500 * US)
    late = c.wait()
    assert c.skipped == 2
    assert c.missed == 2
    assert c.tick == 4
    assert c.deadline_ns == t0 + 4 * MS
    assert 0 <= late < US
    # no catch-up afterwards: the next normal tick is tick 5 at t0 + 5 ms
    ft.work(100 * US)
    c.wait()
    assert (c.tick, c.skipped, c.missed, c.deadline_ns) == (5, 0, 2, t0 + 5 * MS)


def test_arriving_exactly_at_deadline_is_not_a_miss():
    c, ft = make(step=1)
    c.start()  # t0 returned, t = t0 + 1
    t0 = 10 * MS
    ft.work(MS - 1)  # wait()'s first now() returns exactly t0 + 1 ms
    late = c.wait()
    assert (c.tick, c.skipped, late) == (1, 0, 0)
    assert ft.sleeps == []  # nothing to sleep
    assert c.deadline_ns == t0 + MS


def test_one_ns_past_deadline_is_one_miss():
    c, ft = make(step=1)
    c.start()
    t0 = 10 * MS
    ft.work(MS)  # first now() inside wait returns t0 + 1 ms + 1 ns
    c.wait()
    assert (c.tick, c.skipped, c.missed) == (2, 1, 1)
    assert c.deadline_ns == t0 + 2 * MS


def test_landing_exactly_on_a_later_deadline():
    c, ft = make(step=1)
    c.start()
    t0 = 10 * MS
    ft.work(3 * MS - 1)  # first now() returns exactly t0 + 3 ms: deadlines 1 and 2 passed, 3 is now
    late = c.wait()
    assert (c.tick, c.skipped, c.missed, late) == (3, 2, 2, 0)
    assert c.deadline_ns == t0 + 3 * MS


def test_oversleep_makes_a_late_tick_then_a_miss():
    # the OS wakes us 1.5 ms late: the tick is late (not missed) ...
    c, ft = make(oversleep=1_500 * US, step=1)
    c.start()
    t0 = 10 * MS
    ft.work(100 * US)
    late = c.wait()
    assert c.tick == 1 and c.missed == 0
    # wake-up = t0 + 100us (+1 for each now) + sleep to deadline - 200 us + 1.5 ms
    assert late == pytest.approx(1_300 * US, abs=10)
    assert late > MS
    # ... and the next wait finds deadline 2 (t0 + 2 ms) already passed: one miss
    ft.oversleep = 0
    c.wait()
    assert (c.tick, c.skipped, c.missed) == (3, 1, 1)
    assert c.deadline_ns == t0 + 3 * MS


def test_early_wakeups_sleep_again():
    c, ft = make(sleep_fraction=0.5, step=1)
    c.start()
    ft.work(100 * US)
    late = c.wait()
    assert c.tick == 1 and c.missed == 0
    assert len(ft.sleeps) > 1  # slept again after each early return
    assert 0 <= late <= 1
    assert all(s > 0 for s in ft.sleeps)


def test_non_integer_period_rounds_to_ns():
    c, ft = make(rate=3000.0)
    assert c.period_ns == 333_333
    c.start()
    for _ in range(3):
        c.wait()
    assert c.deadline_ns == 10 * MS + 3 * 333_333


def test_restart_resets_counters():
    c, ft = make()
    c.start()
    ft.work(5 * MS)
    c.wait()
    assert c.missed > 0
    c.start()
    assert (c.tick, c.missed, c.skipped) == (0, 0, 0)


def test_prepare_runs_once_per_wait_at_its_lead_before_the_deadline():
    ft = FakeTime()
    calls: list[int] = []
    c = DeadlineClock(1000.0, spin_s=200e-6, sleep=ft.sleep, now=ft.now, prepare=lambda: calls.append(ft.t), prepare_lead_s=50e-6)
    c.start()
    for k in range(1, 11):
        ft.work(300 * US)
        late = c.wait()
        assert len(calls) == k
        # called in the spin, once the clock read >= deadline - 50 us (1 us steps), before the deadline
        assert c.deadline_ns - 50 * US < calls[-1] <= c.deadline_ns - 49 * US
        assert 0 <= late < 3 * US


def test_prepare_is_skipped_when_the_sleep_overshoots_its_moment():
    ft = FakeTime(oversleep=180 * US)  # wakes 20 us before the deadline, after the 50 us preparing moment
    calls: list[int] = []
    c = DeadlineClock(1000.0, spin_s=200e-6, sleep=ft.sleep, now=ft.now, prepare=lambda: calls.append(ft.t), prepare_lead_s=50e-6)
    c.start()
    for _ in range(5):
        ft.work(300 * US)
        assert 0 <= c.wait() < 3 * US
    assert calls == []


def test_prepare_lead_is_capped_at_the_spin_window():
    c = DeadlineClock(1000.0, spin_s=100e-6, prepare=lambda: None, prepare_lead_s=1.0)
    assert c.prepare_lead_ns == c.spin_ns == 100 * US


def test_errors():
    with pytest.raises(ValueError, match="rate_hz"):
        DeadlineClock(0.0)
    with pytest.raises(ValueError, match="rate_hz"):
        DeadlineClock(float("nan"))
    with pytest.raises(ValueError, match="spin_s"):
        DeadlineClock(1000.0, spin_s=-1e-6)
    with pytest.raises(ValueError, match="prepare_lead_s"):
        DeadlineClock(1000.0, prepare_lead_s=float("nan"))
    with pytest.raises(RuntimeError, match="start"):
        DeadlineClock(1000.0).wait()


def test_short_real_run_is_consistent():
    """Real clock, 1 kHz, 60 waits: only consistency of counts, no timing assertions."""
    c = DeadlineClock(1000.0)
    c.start()
    t0 = c.deadline_ns
    lates = []
    for _ in range(60):
        lates.append(c.wait())
        assert time.perf_counter_ns() >= c.deadline_ns
    assert c.tick == 60 + c.missed
    assert c.deadline_ns == t0 + c.tick * c.period_ns
    assert all(late >= 0 for late in lates)


# -- real-time setup (flowtex.runtime.realtime) -------------------------------------

REFUSED_SCRIPT = """
import os, sys
from flowtex.runtime.realtime import enter_realtime
os.setgid(65534); os.setuid(65534)   # drop root: SCHED_FIFO must now be refused
s = enter_realtime(priority=10)
print(s.granted, os.sched_getscheduler(0) == os.SCHED_OTHER, repr(s.message))
"""


def test_enter_realtime_refused_warns_and_continues():
    import os
    import subprocess
    import sys

    if os.geteuid() == 0:
        proc = subprocess.run([sys.executable, "-c", REFUSED_SCRIPT], capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr
        granted, other, message = proc.stdout.strip().split(" ", 2)
        assert (granted, other) == ("False", "True")
        assert "SCHED_FIFO refused" in message and "continuing" in message
    else:
        from flowtex.runtime.realtime import enter_realtime, leave_realtime

        s = enter_realtime(priority=10)
        leave_realtime(s)
        assert s.granted or "SCHED_FIFO refused" in s.message


def test_enter_realtime_bad_arguments_never_raise():
    import os

    from flowtex.runtime.realtime import enter_realtime, leave_realtime

    before = (os.sched_getscheduler(0), os.sched_getaffinity(0))
    s = enter_realtime(priority=1000, cpu=10_000)
    try:
        assert s.granted is False and s.cpu is None
        assert "outside SCHED_FIFO range" in s.message
        assert "CPU 10000 is not among the allowed CPUs" in s.message
        assert "\n" not in s.message
    finally:
        leave_realtime(s)
    assert (os.sched_getscheduler(0), os.sched_getaffinity(0)) == before


def test_enter_and_leave_realtime_restore_policy_and_affinity():
    import os

    from flowtex.runtime.realtime import enter_realtime, leave_realtime

    before = (os.sched_getscheduler(0), os.sched_getaffinity(0))
    s = enter_realtime(priority=5)
    try:
        if s.granted:
            assert os.sched_getscheduler(0) == os.SCHED_FIFO
            assert os.sched_getparam(0).sched_priority == 5
        if s.cpu is not None:
            assert os.sched_getaffinity(0) == {s.cpu}
    finally:
        leave_realtime(s)
    assert (os.sched_getscheduler(0), os.sched_getaffinity(0)) == before


def test_freeze_gc_disables_and_restores():
    import gc

    from flowtex.runtime.realtime import freeze_gc

    suite_froze = gc.get_freeze_count() > 0  # tests/conftest.py freezes what collection left
    gc.unfreeze()
    try:
        assert gc.isenabled()
        with freeze_gc():
            assert not gc.isenabled()
            assert gc.get_freeze_count() > 0
        assert gc.isenabled() and gc.get_freeze_count() == 0  # nothing was frozen before: nothing stays frozen
        gc.disable()
        try:
            with freeze_gc():
                pass
            assert not gc.isenabled()  # restores the previous state, not "enabled"
        finally:
            gc.enable()
        gc.freeze()
        before = gc.get_freeze_count()
        with freeze_gc():
            pass
        assert gc.get_freeze_count() >= before > 0  # a caller's frozen objects stay frozen
    finally:
        gc.freeze() if suite_froze else gc.unfreeze()


def test_catch_up_runs_passed_deadlines_back_to_back_then_returns_to_schedule():
    ft = FakeTime()
    c = DeadlineClock(1000.0, sleep=ft.sleep, now=ft.now, catch_up_s=0.005)
    c.start()
    t0 = 10 * MS
    ft.work(3_200 * US)  # a 3.2 ms stall in tick 0: deadlines 1, 2 and 3 have passed, within the 5 ms allowance
    lates = []
    for _ in range(3):
        lates.append(c.wait())
        assert c.skipped == 0
        ft.work(100 * US)
    assert c.tick == 3 and c.missed == 0  # every tick ran, none skipped
    assert lates[0] >= 2_200 * US and lates[0] > lates[1] > lates[2] > 0  # late, less so each tick, back to back
    assert not ft.sleeps  # no sleep while behind
    c.wait()  # on time again: tick 4 sleeps until its deadline
    assert c.deadline_ns == t0 + 4 * MS and ft.sleeps and c.missed == 0


def test_catch_up_allowance_exceeded_skips_as_before():
    ft = FakeTime()
    c = DeadlineClock(1000.0, sleep=ft.sleep, now=ft.now, catch_up_s=0.002)
    c.start()
    ft.work(3_500 * US)  # 2.5 ms past tick 1's deadline: more than the 2 ms allowance
    c.wait()
    assert (c.skipped, c.tick, c.deadline_ns) == (3, 4, 10 * MS + 4 * MS)
