"""TickStats: counts, percentiles against analytic order statistics, ring wrap, JSON, no per-tick growth."""

from __future__ import annotations

import json
import math
import tracemalloc

import numpy as np
import pytest

from flowtex.runtime.stats import TickStats

REQUIRED = {"ticks", "missed", "late_over_1ms", "lateness_us", "compute_us", "frames_in", "frames_out", "watchdog_events", "rt"}


def test_percentiles_of_a_known_ramp():
    # lateness 0, 1, ..., 999 us; compute 2x that. Linear-interpolated percentile of a
    # ramp 0..N-1 at q is q/100 * (N-1).
    s = TickStats(2000)
    for k in range(1000):
        s.record(k * 1000, 2 * k * 1000)
    out = s.summary(rt=False)
    lat = out["lateness_us"]
    assert lat["p50"] == pytest.approx(0.50 * 999)
    assert lat["p99"] == pytest.approx(0.99 * 999)
    assert lat["p999"] == pytest.approx(0.999 * 999)
    assert lat["max"] == pytest.approx(999.0)
    assert lat["mean"] == pytest.approx(499.5)
    comp = out["compute_us"]
    assert comp["p99"] == pytest.approx(2 * 0.99 * 999)
    assert comp["max"] == pytest.approx(1998.0)
    assert out["ticks"] == 1000
    assert out["window_ticks"] == 1000
    assert all(isinstance(v, float) for v in lat.values())


def test_late_over_1ms_is_strict():
    s = TickStats(10)
    s.record(1_000_000, 0)  # exactly 1 ms: not over
    s.record(1_000_001, 0)
    s.record(999_999, 0)
    s.record(5_000_000, 0)
    assert s.late_over_1ms == 2
    assert s.summary(True)["late_over_1ms"] == 2


def test_ring_wrap_keeps_counts_and_whole_run_max():
    s = TickStats(100)
    s.record(50_000_000, 7_000_000)  # a huge early outlier, later overwritten in the ring
    for _ in range(149):
        s.record(2_000_000, 1_000)  # 2 ms late each: all over 1 ms
    for k in range(100):
        s.record(k * 1000, 3_000)  # the last 100 ticks: a 0..99 us ramp
    out = s.summary(False)
    assert out["ticks"] == 250
    assert out["late_over_1ms"] == 150
    assert out["window_ticks"] == 100
    assert out["capacity_ticks"] == 100
    # percentiles over the latest 100 ticks only
    assert out["lateness_us"]["p50"] == pytest.approx(49.5)
    assert out["lateness_us"]["p99"] == pytest.approx(0.99 * 99)
    assert out["compute_us"]["p50"] == pytest.approx(3.0)
    # max over the whole run
    assert out["lateness_us"]["max"] == pytest.approx(50_000.0)
    assert out["compute_us"]["max"] == pytest.approx(7_000.0)


def test_counters_and_json(tmp_path):
    s = TickStats(16)
    for k in range(5):
        s.record(1000 * k, 500)
    s.missed += 3
    s.frames_in += 7
    s.frames_out += 5
    s.watchdog_events += 1
    s.timeouts += 2
    s.overruns += 1
    p = tmp_path / "stats.json"
    s.write_json(p, rt=True)
    data = json.loads(p.read_text(encoding="utf-8"))
    assert REQUIRED <= set(data)
    assert (data["ticks"], data["missed"], data["frames_in"], data["frames_out"]) == (5, 3, 7, 5)
    assert (data["watchdog_events"], data["timeouts"], data["overruns"], data["rt"]) == (1, 2, 1, True)
    for key in ("lateness_us", "compute_us"):
        assert {"p50", "p99", "p999", "max"} <= set(data[key])
    assert data["lateness_us"]["p50"] == pytest.approx(2.0)


def test_empty_run_gives_null_percentiles(tmp_path):
    s = TickStats(4)
    out = s.summary(False)
    assert out["ticks"] == 0
    assert out["lateness_us"]["p99"] is None and out["compute_us"]["max"] is None
    p = tmp_path / "s.json"
    s.write_json(p, rt=False)  # must be strict JSON (no NaN)
    assert json.loads(p.read_text())["lateness_us"]["p50"] is None
    assert "no ticks" in s.format_summary(False)


def test_status_line_window_since_previous_call():
    s = TickStats(8)
    for _ in range(5):
        s.record(900_000, 10_000)
    line1 = s.status_line()
    assert "\n" not in line1 and "\r" not in line1
    assert "tick         5" in line1
    assert "900.0" in line1  # max lateness 900 us in this window
    for _ in range(12):  # wraps the ring of 8
        s.record(3_000, 20_000)
    line2 = s.status_line()
    assert "900.0" not in line2
    assert "3.0" in line2 and "20.0" in line2
    assert "tick        17" in line2
    assert ">1ms 0" in line2
    line3 = s.status_line()  # nothing new
    assert "tick        17" in line3


def test_summary_text_mentions_rt():
    s = TickStats(4)
    s.record(1000, 1000)
    assert "SCHED_FIFO" in s.format_summary(True)
    assert math.isclose(s.summary(False)["lateness_us"]["max"], 1.0)


def test_record_does_not_grow_memory():
    s = TickStats(4096)
    for k in range(100):
        s.record(k, k)
    tracemalloc.start()
    try:
        base, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        for k in range(20_000):
            s.record(k * 37 + 1_000_000_007, k * 13 + 123_456_789)
        cur, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert cur - base < 512
    assert peak - base < 2048


# --- skipped deadlines count as late (issue 8 item 4) ---------------------------------------------
class _FakeTime:
    """Monotonic fake clock in ns: every now() advances 1 ns; sleep advances exactly; work(ns) is the tick's work."""

    def __init__(self, t0: int) -> None:
        self.t = t0

    def now(self) -> int:
        self.t += 1
        return self.t - 1

    def sleep(self, s: float) -> None:
        self.t += int(round(s * 1e9))

    def work(self, ns: int) -> None:
        self.t += ns


def test_a_3ms_stall_at_1khz_counts_its_skipped_deadlines_as_late():
    from flowtex.runtime.clock import DeadlineClock

    ms = 1_000_000
    t0 = 10 * ms
    ft = _FakeTime(t0)
    clock = DeadlineClock(1000.0, sleep=ft.sleep, now=ft.now)
    s = TickStats(100)
    clock.start()
    lateness = 0
    started = []  # (deadline, the clock's last reading, i.e. when the tick started) of every executed tick
    for k in range(10):  # the live loop's order: record the tick, wait, count what the wait skipped
        started.append((clock.deadline_ns, ft.t - 1))
        s.record(lateness, 50_000)
        ft.work(3_100_000 if k == 5 else 100_000)  # tick 5 stalls for 3.1 ms
        lateness = clock.wait()
        if clock.skipped:
            s.record_skipped(clock.skipped, lateness, clock.period_ns)
    # ground truth from the fake time: tick 5 ran at t0 + 5 ms and its work ended at t0 + 8.1 ms, so the deadlines
    # t0 + 6, 7, 8 ms had no tick; the loop resumed at the next executed tick, whose deadline is t0 + 9 ms
    deadlines = [d for d, _ in started]
    assert deadlines[:7] == [t0 + k * ms for k in range(6)] + [t0 + 9 * ms]
    resumed = started[6][1]
    expected_skipped = [resumed - (t0 + k * ms) for k in (6, 7, 8)]
    assert s.missed == 3 and s.overruns == 1 and s.ticks == 10 and s.deadlines == 13
    ring = sorted(int(v) for v in s.lateness_ns[:s.deadlines])
    executed = [t - d for d, t in started]
    assert ring == sorted(expected_skipped + executed)
    # each skipped deadline is exactly 1 ms apart: 3 ms, 2 ms, 1 ms plus the resumed tick's few-ns lateness
    assert [e - expected_skipped[-1] for e in expected_skipped] == [2 * ms, ms, 0]
    assert 0 <= resumed - (t0 + 9 * ms) < 1_000
    out = s.summary(False)
    assert out["late_over_1ms"] == sum(e > ms for e in expected_skipped) + sum(e > ms for e in executed)
    assert 2 <= out["late_over_1ms"] <= 3
    assert out["longest_stall_us"] == pytest.approx(expected_skipped[0] / 1e3)  # from t0 + 6 ms to the resume
    assert out["longest_stall_us"] == pytest.approx(3000.0, abs=1.0)
    assert out["lateness_us"]["max"] == pytest.approx(expected_skipped[0] / 1e3)
    # p99 over 13 deadlines is interpolated between the two largest: numpy on the same values, computed here
    assert out["lateness_us"]["p99"] == pytest.approx(float(np.percentile(ring, 99)) / 1e3)
    assert out["lateness_window"] == 13 and out["window_ticks"] == 10
    text = s.format_summary(False)
    assert "missed 3 in 1 stall(s), longest 3.00 ms" in text


def test_record_skipped_counts_match_a_brute_force_count():
    # the count of skipped deadlines later than 1 ms is computed in closed form; compare with counting each one
    for period in (1_000_000, 500_000, 333_333, 2_000_000):
        for late in (0, 1, 999_999, 1_000_000, 1_000_001, 250_000, 3_000_000):
            for skipped in (1, 2, 3, 7):
                s = TickStats(64)
                s.record_skipped(skipped, late, period)
                values = [j * period + late for j in range(skipped, 0, -1)]
                assert s.late_over_1ms == sum(v > 1_000_000 for v in values), (period, late, skipped)
                assert list(s.lateness_ns[:skipped]) == values
                assert s.longest_stall_ns == values[0] == s.lateness_max_ns
                assert s.missed == skipped and s.deadlines == skipped and s.ticks == 0


def test_a_stall_longer_than_the_ring_keeps_exact_counts():
    s = TickStats(8)
    s.record(1_000, 5_000)
    s.record_skipped(20, 500, 1_000_000)  # a 20 ms stall at 1 kHz, 500 ns late on resuming
    s.record(500, 5_000)
    assert s.deadlines == 22 and s.missed == 20 and s.ticks == 2
    assert s.late_over_1ms == 20  # j ms + 500 ns > 1 ms for every j >= 1
    # the ring of 8 holds the latest 8 deadlines: skipped ones 7 ms .. 1 ms (plus 500 ns) and the resumed tick
    assert sorted(int(v) for v in s.lateness_ns) == sorted([j * 1_000_000 + 500 for j in range(1, 8)] + [500])
    out = s.summary(True)
    assert out["lateness_us"]["max"] == pytest.approx(20_000.5) and out["longest_stall_us"] == pytest.approx(20_000.5)
    assert out["compute_us"]["p50"] == pytest.approx(5.0)  # skipped deadlines have no compute sample
    line = s.status_line()
    assert "max  20000.5" not in line and "max   7000.5 us" in line  # the status window is the ring's latest deadlines
    s.record_skipped(0, 123, 1_000_000)  # no skip: nothing changes
    assert s.missed == 20 and s.overruns == 1


def test_no_stall_reports_zero_longest_stall():
    s = TickStats(4)
    s.record(2_000_000, 1_000)  # late, but no deadline skipped
    out = s.summary(False)
    assert out["longest_stall_us"] == 0.0 and out["late_over_1ms"] == 1 and out["deadlines"] == 1
    with pytest.raises(ValueError):
        s.record_skipped(1, 0, 0)
