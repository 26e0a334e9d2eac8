"""OutputGuard and Watchdog: every rule, its edges (exact limits, NaN/inf, peak durations) and recovery."""

from __future__ import annotations

import logging
import math
import tracemalloc

import numpy as np
import pytest

from flowtex.runtime.safety import OutputGuard, Watchdog

NAN = math.nan
INF = math.inf


def run(guard: OutputGuard, values, force_safe: bool = False) -> tuple[list[float], int]:
    v = np.asarray(values, dtype=np.float64)
    out = np.full(v.shape[0], -12345.0)
    n = guard.apply(v, out, force_safe)
    return out.tolist(), n


# -- OutputGuard -------------------------------------------------------------------


def test_pass_through_and_clamp_with_exact_bounds():
    g = OutputGuard(lo=[-1.0, 0.0], hi=[1.0, 2.0], safe=[0.0, 0.0])
    assert run(g, [1.0, 0.0]) == ([1.0, 0.0], 0)  # bounds are inclusive
    assert run(g, [-1.0, 2.0]) == ([-1.0, 2.0], 0)
    assert run(g, [1.5, -0.25]) == ([1.0, 0.0], 2)
    assert run(g, [np.nextafter(1.0, 2.0), np.nextafter(2.0, 0.0)]) == ([1.0, np.nextafter(2.0, 0.0)], 1)
    assert g.clamp_counts.tolist() == [2, 1]


@pytest.mark.parametrize("bad", [NAN, INF, -INF])
def test_nonfinite_becomes_safe(bad):
    g = OutputGuard(lo=-2.0, hi=2.0, safe=[0.5, -0.5, 0.0])
    assert run(g, [bad, 1.0, bad]) == ([0.5, 1.0, 0.0], 2)
    assert g.nonfinite_counts.tolist() == [1, 0, 1]
    assert g.clamp_counts.tolist() == [0, 0, 0]


def test_force_safe_overrides_everything():
    g = OutputGuard(lo=-2.0, hi=2.0, safe=[0.25, -1.0])
    assert run(g, [1.0, NAN], force_safe=True) == ([0.25, -1.0], 0)
    out = np.zeros(2)
    g.safe_values(out)
    assert out.tolist() == [0.25, -1.0]


def test_peak_allowed_for_exactly_max_ticks_then_clamped():
    g = OutputGuard(lo=-1.0, hi=1.0, safe=0.0, peak_hi=3.0, peak_max_ticks=3)
    outs = [run(g, [2.5])[0][0] for _ in range(5)]
    assert outs == [2.5, 2.5, 2.5, 1.0, 1.0]
    # stays clamped while the command stays out of range (how the allowance refills: test_peak_budget.py)
    assert run(g, [2.9]) == ([1.0], 1)


def test_peak_beyond_peak_limit_clamps_to_peak_limit_during_allowance():
    g = OutputGuard(lo=-1.0, hi=1.0, safe=0.0, peak_hi=3.0, peak_max_ticks=2)
    assert run(g, [10.0]) == ([3.0], 1)
    assert run(g, [3.0]) == ([3.0], 0)  # exactly the peak limit, within allowance
    assert run(g, [3.0]) == ([1.0], 1)  # third consecutive tick: steady clamp


def test_negative_peaks_mirror_by_default_and_count_in_same_run():
    g = OutputGuard(lo=-1.0, hi=1.0, safe=0.0, peak_hi=3.0, peak_max_ticks=2)
    assert g.peak_lo.tolist() == [-3.0]
    # a ringing tap: +, -, + all outside [lo, hi] -> one consecutive run
    assert run(g, [2.0]) == ([2.0], 0)
    assert run(g, [-2.0]) == ([-2.0], 0)
    assert run(g, [2.0]) == ([1.0], 1)
    assert run(g, [-5.0]) == ([-1.0], 1)


def test_peak_lo_can_disable_lower_peaks():
    g = OutputGuard(lo=0.0, hi=1.0, safe=0.0, peak_hi=2.0, peak_max_ticks=5, peak_lo=0.0)
    assert run(g, [-0.5]) == ([0.0], 1)
    assert run(g, [1.5]) == ([1.5], 0)


def test_peak_max_zero_means_no_peaks():
    g = OutputGuard(lo=-1.0, hi=1.0, safe=0.0, peak_hi=3.0, peak_max_ticks=0)
    assert run(g, [2.0]) == ([1.0], 1)


def test_per_channel_peak_settings():
    g = OutputGuard(lo=[-1.0, -1.0], hi=[1.0, 1.0], safe=[0.0, 0.0], peak_hi=[2.0, 4.0], peak_max_ticks=np.array([1, 3]))
    seq = [run(g, [1.5, 3.5])[0] for _ in range(4)]
    assert seq == [[1.5, 3.5], [1.0, 3.5], [1.0, 3.5], [1.0, 1.0]]


def test_guard_validation_errors():
    with pytest.raises(ValueError, match="safe"):
        OutputGuard(lo=0.0, hi=1.0, safe=2.0)
    with pytest.raises(ValueError, match="lo must be <= hi"):
        OutputGuard(lo=1.0, hi=0.0, safe=0.5)
    with pytest.raises(ValueError, match="peak_hi"):
        OutputGuard(lo=0.0, hi=1.0, safe=0.0, peak_hi=0.5, peak_max_ticks=2)
    with pytest.raises(ValueError, match="peak_max_ticks"):
        OutputGuard(lo=0.0, hi=1.0, safe=0.0, peak_hi=2.0, peak_max_ticks=-1)
    with pytest.raises(ValueError, match="lo has 2 entries, expected 3"):
        OutputGuard(lo=[0.0, 0.0], hi=[1.0, 1.0, 1.0], safe=0.0)
    with pytest.raises(ValueError, match="finite"):
        OutputGuard(lo=0.0, hi=NAN, safe=0.0)


def test_guard_apply_does_not_allocate():
    g = OutputGuard(lo=-1.0, hi=1.0, safe=[0.0] * 4, peak_hi=2.0, peak_max_ticks=3)
    v = np.array([0.5, 1.5, NAN, -3.0])
    out = np.zeros(4)
    g.apply(v, out, False)  # compile
    tracemalloc.start()
    try:
        base, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        for _ in range(5000):
            g.apply(v, out, False)
        cur, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert cur - base < 512 and peak - base < 4096


# -- Watchdog ----------------------------------------------------------------------


def test_starts_tripped_until_every_input_reports():
    w = Watchdog(np.array([2, 5]), overrun_limit_ns=500_000)
    assert w.check(0, 0) is True
    w.fresh(0, 1)
    assert w.check(1, 0) is True  # input 1 never reported
    w.fresh(1, 2)
    # input 0's frame (tick 1) predates the latest trip tick (1, when input 1 was still
    # missing): the documented rule wants a frame from every input after it
    assert w.check(2, 0) is True
    w.fresh(0, 3)
    assert w.check(3, 0) is False
    assert w.events == 0  # startup is not an event
    assert w.log == []


def test_stale_exactly_at_timeout_is_still_fresh():
    w = Watchdog(np.array([3]), overrun_limit_ns=10**9)
    w.fresh(0, 10)
    assert w.check(10, 0) is False
    assert w.check(13, 0) is False  # age 3 == timeout
    assert w.check(14, 0) is True  # age 4 > timeout
    assert w.events == 1
    assert w.log == [(14, "stale", 0)]
    assert w.reason == "stale"
    assert (w.stale_events, w.overrun_events) == (1, 0)


def test_stale_recovery_needs_fresh_data_after_trip():
    w = Watchdog(np.array([3, 100]), overrun_limit_ns=10**9, emit_log=False)
    w.fresh(0, 0)
    w.fresh(1, 0)
    assert w.check(0, 0) is False
    assert w.check(4, 0) is True  # input 0 stale at tick 4
    assert w.check(5, 0) is True  # still stale
    w.fresh(0, 6)
    # input 0 fresh again, but input 1 has not sent anything since the trip (tick 5)
    assert w.check(6, 0) is True
    w.fresh(1, 7)
    assert w.check(7, 0) is False
    assert w.events == 1


def test_overrun_trips_strictly_above_limit_and_recovers_on_fresh_inputs():
    w = Watchdog(np.array([10, 10]), overrun_limit_ns=2_000_000, emit_log=False)
    for i in range(2):
        w.fresh(i, 0)
    assert w.check(0, 2_000_000) is False  # exactly at the limit: no trip
    for i in range(2):
        w.fresh(i, 1)
    assert w.check(1, 2_000_001) is True
    assert w.events == 1 and w.log[-1] == (1, "overrun", 2_000_001)
    # inputs refreshed at the trip tick itself do not count; need a later frame from each
    assert w.check(2, 0) is True
    w.fresh(0, 3)
    assert w.check(3, 0) is True
    w.fresh(1, 3)
    assert w.check(3, 0) is False


def test_retrip_while_tripped_is_one_event_and_extends():
    w = Watchdog(np.array([5]), overrun_limit_ns=100, emit_log=False)
    w.fresh(0, 0)
    assert w.check(0, 0) is False
    assert w.check(1, 500) is True
    w.fresh(0, 2)
    assert w.check(2, 500) is True  # a second overrun while tripped: trip tick moves to 2
    assert w.check(3, 0) is True  # the frame at tick 2 is not after the latest trip tick
    w.fresh(0, 4)
    assert w.check(4, 0) is False
    assert w.events == 1
    assert w.check(5, 101) is True
    assert w.events == 2
    assert [e[0] for e in w.log] == [1, 5]


def test_zero_timeout_requires_update_every_tick():
    w = Watchdog(np.array([0]), overrun_limit_ns=10**9, emit_log=False)
    w.fresh(0, 7)
    assert w.check(7, 0) is False
    assert w.check(8, 0) is True


def test_events_are_logged(caplog):
    w = Watchdog(np.array([1]), overrun_limit_ns=10**9)
    w.fresh(0, 0)
    w.check(0, 0)
    with caplog.at_level(logging.WARNING, logger="flowtex.runtime.safety"):
        w.check(3, 0)
    assert any("sensor input 0 stale" in r.getMessage() for r in caplog.records)


def test_log_capacity_caps_log_not_count():
    w = Watchdog(np.array([1]), overrun_limit_ns=0, log_capacity=2, emit_log=False)
    tick = 0
    for _ in range(5):
        w.fresh(0, tick)
        w.check(tick, 0)
        tick += 1
        w.check(tick, 1)  # overrun trip
        tick += 1
    assert w.events == 5 and w.overrun_events == 5 and w.stale_events == 0
    assert len(w.log) == 2


def test_watchdog_validation():
    with pytest.raises(ValueError, match="timeouts_ticks"):
        Watchdog(np.array([-1]), 0)
    with pytest.raises(ValueError, match="timeouts_ticks"):
        Watchdog(np.array([1.5]), 0)
    with pytest.raises(ValueError, match="overrun_limit_ns"):
        Watchdog(np.array([1]), -5)
