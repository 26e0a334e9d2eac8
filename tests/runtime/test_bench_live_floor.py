"""benchmarks/bench_live.py's reading of cyclictest output (the machine floor printed beside flowtex's lateness)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_live.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_live", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _output(hist: dict[int, int], rng: int, overflows: int, max_us: int, cycles: str = "") -> str:
    """Text laid out as ``cyclictest -q -t 1 -h RANGE`` (rt-tests 2.4) prints it."""
    lines = ["# /dev/cpu_dma_latency set to 0us", "# Histogram"]
    lines += [f"{v:06d} {hist.get(v, 0):06d}" for v in range(rng)]
    total = sum(hist.values())
    lines += [f"# Total: {total:09d}", "# Min Latencies: 00009", "# Avg Latencies: 00018", f"# Max Latencies: {max_us:05d}",
              f"# Histogram Overflows: {overflows:05d}", "# Histogram Overflow at cycle number:", f"# Thread 0:{cycles}", ""]
    return "\n".join(lines)


def test_percentiles_are_nearest_rank_over_the_histogram(bench):
    rng = np.random.default_rng(3)
    samples = np.concatenate([rng.integers(5, 40, 9_000), rng.integers(40, 1_500, 95), [1_800, 2_500, 2_600, 1_001, 1_000]])
    hist = {int(v): int(c) for v, c in zip(*np.unique(samples, return_counts=True), strict=True)}
    out = bench.parse_cyclictest(_output(hist, 5_000, 0, int(samples.max())))
    # the reference: numpy's nearest-rank percentile ("inverted_cdf") of the expanded samples
    for key, q in (("p50", 50), ("p99", 99), ("p999", 99.9)):
        assert out[key] == float(np.percentile(samples, q, method="inverted_cdf")), key
    assert out["count"] == samples.size and out["max"] == 2_600.0 and out["overflows"] == 0
    assert out["over_1ms"] == int(np.sum(samples > 1_000))  # the 1000 us bin is not later than 1 ms


def test_overflows_count_as_late_and_hide_the_percentiles_they_contain(bench):
    hist = {20: 990, 30: 6}  # 996 in range, 4 beyond a 50 us range: p99.9 falls among the overflows
    out = bench.parse_cyclictest(_output(hist, 50, 4, 3_000, " 00188 00890 00987 00990"))
    assert out["count"] == 1_000
    assert out["p50"] == 20.0 and out["p99"] == 20.0  # rank 990 is the last 20 us sample
    assert out["p999"] is None  # rank 999 > 996 samples in range
    assert out["max"] == 3_000.0
    assert out["over_1ms"] is None  # the overflows lie beyond 50 us: whether they are later than 1 ms is unknown
    out = bench.parse_cyclictest(_output(hist | {1_500: 1}, 2_000, 4, 30_000))  # a 2 ms range: overflows are > 1 ms
    assert out["over_1ms"] == 5 and out["count"] == 1_001
    assert bench._num(None).strip() == f">{bench.CYCLICTEST_RANGE_US}"


def test_a_real_cyclictest_layout_with_its_comment_lines_parses(bench):
    # rt-tests 2.4 on this machine: 1 s at 1 kHz, SCHED_FIFO 80 on CPU 1, -h 50 (three wake-ups beyond 50 us)
    text = "# /dev/cpu_dma_latency set to 0us\n# Histogram\n" + "".join(
        f"{v:06d} {c:06d}\n" for v, c in enumerate([0] * 9 + [5, 40, 200, 400, 250, 60, 20, 10, 5, 3, 3] + [0] * 30))
    text += ("# Total: 000000996\n# Min Latencies: 00009\n# Avg Latencies: 00018\n# Max Latencies: 01203\n"
             "# Histogram Overflows: 00003\n# Histogram Overflow at cycle number:\n# Thread 0: 00188 00890 00987\n")
    out = bench.parse_cyclictest(text)
    assert out["count"] == 999 and out["overflows"] == 3 and out["max"] == 1_203.0
    assert out["p50"] == 12.0  # cumulative 5, 45, 245, 645 >= rank 500 at 12 us


def test_output_without_a_histogram_is_an_error(bench):
    with pytest.raises(ValueError):
        bench.parse_cyclictest("sched_setscheduler: Operation not permitted\n")
    with pytest.raises(ValueError):
        bench.parse_cyclictest("# Max Latencies: 00100\n")  # summary without -h
