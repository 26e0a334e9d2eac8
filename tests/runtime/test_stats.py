"""TickStats: counts, percentiles against analytic order statistics, ring wrap, JSON, no per-tick growth."""

from __future__ import annotations

import json
import math
import tracemalloc

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
