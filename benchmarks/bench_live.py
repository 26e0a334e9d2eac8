"""Live loop at the graph's rate against the in-process simulated device, without and with --rt.

    python benchmarks/bench_live.py [SECONDS=60] [--only-rt | --no-rt] [--no-cyclictest]

Graph: graphs/live_texture.yaml with its recording graphs/data/exploration.npz and the
example device (graphs/devices/example.dbc + example_map.yaml). Only if those files are
missing a small stand-in graph (position -> lowpass -> gain -> force, normal force ->
gain -> vibration) and a synthetic 3 s recording run instead; the output says which ran.

Per run it reports:

- the machine's floor, measured just before the session when ``cyclictest`` (Debian/Ubuntu
  package ``rt-tests``) is installed: cyclictest, the standard C measurement of a machine's
  scheduling latency, runs one thread at the session's rate, scheduling policy, priority and
  CPU for as long as the session (at most 60 s); its wake-up latency p50/p99/p99.9/max and
  the wake-ups later than 1 ms are printed beside flowtex's lateness. A stall that both show
  belongs to the machine (steal, another task, an interrupt storm), not to flowtex.
  cyclictest sleeps until each deadline (``clock_nanosleep``) while flowtex sleeps until 200
  us before it and spins, so cyclictest's p50 includes the kernel's timer latency that
  flowtex's spin hides: compare the tails and the stalls, not the medians;
- lateness (tick start - deadline, skipped deadlines included, see docs/live.md) p50/p99/
  p99.9/max, deadlines later than 1 ms, and the longest stall;
- compute p50/p99/p99.9/max: from after the tick's frames were received to before the
  first send: decode into the graph inputs, one graph tick, watchdog, output guard,
  encode into the frames (bus receive and send excluded, see docs/live.md);
- the share of ticks whose actuator frames were all sent before the next deadline
  ("command for tick n sent within tick n");
- the time from each tick's deadline until its last actuator frame was sent;
- sensor-to-actuator latency: for each sensor sample the device published, the tick
  at which the first actuator frame after it was collected, minus the publish tick
  (0 = within the same tick), and the wall time from publish to that frame (the
  in-process device publishes sample n in the slack after tick n-1, so this includes
  the wait for tick n's deadline);
- the machine's noise floor, side by side: right after each session, the same clock
  (same rate, same --rt setting, warming off) runs a fixed busy-wait as long as the
  session's compute p50 in place of the tick, for up to 20 s, and reports how long that
  fixed work measured (p50/p99/p99.9/max): what it shows beyond its p50 is preemption
  and steal on this machine (a busy-wait does not feel cold caches, so it is a lower
  bound on the machine's share of compute's tail);
- whether SCHED_FIFO was granted, the machine's load average before/after and the CPU
  time the hypervisor stole from this virtual machine during the run (``steal`` in
  /proc/stat, Linux): the machine is shared, and the numbers depend on what else runs.

Targets with --rt: lateness p99 <= 50 us, < 0.1 % ticks late > 1 ms, compute p99 <= 20 us,
actuator command for tick n sent within tick n.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from flowtex.graph.compiled import load_graph
from flowtex.runtime.clock import DeadlineClock
from flowtex.runtime.live import LiveConfig, run_live
from flowtex.runtime.realtime import enter_realtime, freeze_gc, leave_realtime

REPO = Path(__file__).resolve().parents[1]
GRAPH = REPO / "graphs" / "live_texture.yaml"
RECORDING = REPO / "graphs" / "data" / "exploration.npz"
DBC = REPO / "graphs" / "devices" / "example.dbc"
MAP = REPO / "graphs" / "devices" / "example_map.yaml"
STAND_IN = """flowtex: 1
name: stand_in
rate: 1000
inputs:
  position: {shape: [3], unit: mm}
  normal_force: {unit: N}
nodes:
  lp: {type: first_order_lowpass, params: {cutoff_hz: 50}}
  k: {type: gain, params: {k: 0.01}}
  v: {type: gain, params: {k: 0.25}}
edges: [position -> lp.x, lp.y -> k.x, normal_force -> v.x]
outputs: {force: k.y, vibration: v.y}
"""


def _files() -> tuple[Path, Path, str]:
    if GRAPH.exists() and RECORDING.exists():
        return GRAPH, RECORDING, f"{GRAPH.relative_to(REPO)} on {RECORDING.relative_to(REPO)}"
    tmp = Path(tempfile.mkdtemp(prefix="flowtex-bench-live-"))
    graph_path, rec = tmp / "stand_in.yaml", tmp / "rec.npz"
    graph_path.write_text(STAND_IN)
    t = np.arange(3000) / 1000.0
    np.savez(rec, position=np.stack([100 * np.sin(2 * np.pi * t), 50 * np.cos(6 * np.pi * t), 10 + 0 * t], axis=1),
             normal_force=3 + np.sin(10 * np.pi * t), rate=np.float64(1000))
    return graph_path, rec, f"STAND-IN graph ({GRAPH.name} or {RECORDING.name} missing) on a synthetic recording"


def _steal_ms() -> float | None:
    """CPU time stolen by the hypervisor from this machine so far (all CPUs, ms), or None where /proc/stat has no steal column."""
    try:
        fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()
        return int(fields[8]) * 1000.0 / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def noise_floor(work_ns: int, seconds: float, rate: float, rt: bool) -> np.ndarray:
    """Measured durations (ns) of a fixed ``work_ns`` busy-wait run once per tick of a :class:`DeadlineClock`."""
    n = int(seconds * rate)
    took = np.zeros(n, dtype=np.int64)
    now = time.perf_counter_ns
    status = enter_realtime(80) if rt else None
    try:
        with freeze_gc():
            clock = DeadlineClock(rate)
            clock.start()
            for k in range(n):
                t0 = now()
                end = t0 + work_ns
                t1 = now()
                while t1 < end:
                    t1 = now()
                took[k] = t1 - t0
                clock.wait()
    finally:
        if status is not None:
            leave_realtime(status)
    return took


CYCLICTEST_RANGE_US = 20_000
"""Histogram range of cyclictest (1 us bins); later wake-ups are counted as overflows, their maximum is still exact."""


def parse_cyclictest(text: str) -> dict:
    """Wake-up latencies (us) from the output of ``cyclictest -q -t 1 -h RANGE``: the histogram and its summary lines.

    Returns ``count`` (wake-ups, overflows included), ``p50``/``p99``/``p999`` (nearest rank over
    the 1 us bins; ``None`` when the rank falls among the overflows, i.e. beyond the histogram
    range), ``max`` (cyclictest's own, exact), ``over_1ms`` (wake-ups in bins above 1000 us plus the
    overflows; None when there are overflows and the range ends below 1 ms) and ``overflows``. Lines it does not know (comments of other versions, the
    overflow cycle list) are ignored; a text without a histogram or a ``Max Latencies`` line
    raises ValueError.
    """
    bins: dict[int, int] = {}
    summary: dict[str, int] = {}
    for line in text.splitlines():
        m = re.fullmatch(r"\s*(\d+)\s+(\d+)(?:\s+\d+)*\s*", line)
        if m:
            bins[int(m.group(1))] = bins.get(int(m.group(1)), 0) + int(m.group(2))
            continue
        m = re.fullmatch(r"#\s*(Total|Min Latencies|Avg Latencies|Max Latencies|Histogram Overflows)\s*:\s*(\d+)(?:\s+\d+)*\s*", line)
        if m:
            summary[m.group(1)] = int(m.group(2))
    if not bins or "Max Latencies" not in summary:
        raise ValueError("no cyclictest histogram (-h) or summary in the output")
    overflows = summary.get("Histogram Overflows", 0)
    in_range = sum(bins.values())
    count = in_range + overflows
    values = np.array(sorted(bins), dtype=np.int64)
    cum = np.cumsum([bins[v] for v in values])

    # cyclictest prints every bin 0 .. RANGE-1, so the overflows are known to be later than 1 ms only for RANGE > 1000
    over_1ms = int(sum(c for v, c in bins.items() if v > 1000)) + overflows if overflows == 0 or values[-1] >= 1000 else None

    def rank(q: float) -> float | None:
        need = max(1, int(np.ceil(q / 100.0 * count)))
        return float(values[np.searchsorted(cum, need)]) if need <= in_range else None

    return {"count": count, "p50": rank(50), "p99": rank(99), "p999": rank(99.9), "max": float(summary["Max Latencies"]),
            "over_1ms": over_1ms, "overflows": overflows}


def machine_floor(seconds: float, rate: float, rt: bool, priority: int, cpu: int | None) -> tuple[dict | None, str]:
    """Run cyclictest for ``seconds`` like the session will run (rate; with ``rt`` SCHED_FIFO ``priority`` on ``cpu``).

    Returns (the parsed latencies or None, one line saying what ran or why nothing did).
    """
    exe = shutil.which("cyclictest")
    if exe is None:
        return None, "machine floor: cyclictest not installed (Debian/Ubuntu: apt-get install rt-tests), not measured"
    interval_us = max(1, int(round(1e6 / rate)))
    cmd = [exe, "-q", "-t", "1", "-i", str(interval_us), "-D", f"{max(1, int(round(seconds)))}", "-h", str(CYCLICTEST_RANGE_US)]
    if rt:
        cmd += ["--policy=fifo", "-p", str(priority)] + (["-a", str(cpu)] if cpu is not None else [])
    else:
        cmd += ["--policy=other", "-p", "0"]
    what = " ".join(["cyclictest"] + cmd[1:])
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=seconds + 30)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"machine floor: {what} failed: {exc}"
    try:
        return parse_cyclictest(p.stdout), f"machine floor: {what}"
    except ValueError:
        why = (p.stderr.strip().splitlines() or [f"exit code {p.returncode}"])[-1]
        return None, f"machine floor: {what} failed: {why}"


def _num(v: float | None, width: int = 9) -> str:
    return f"{v:>{width}.1f}" if v is not None else f"{'>' + str(CYCLICTEST_RANGE_US):>{width}}"


def _dist(d: dict) -> str:
    return f"p50 {d['p50']:.1f} p99 {d['p99']:.1f} p99.9 {d['p999']:.1f} max {d['max']:.1f}"


def run(seconds: float, rt: bool, graph_path: Path, rec: Path, cyclictest: bool = True) -> dict:
    """One session of ``seconds``; prints the report and returns the numbers."""
    g = load_graph(graph_path)
    cpu = max(os.sched_getaffinity(0)) if rt and hasattr(os, "sched_getaffinity") else None  # enter_realtime's own choice
    floor, floor_line = (machine_floor(min(seconds, 60.0), g.rate, rt, 80, cpu) if cyclictest
                         else (None, "machine floor: not measured (--no-cyclictest)"))
    load_before, steal_before = os.getloadavg(), _steal_ms()
    r = run_live(g, LiveConfig(DBC, MAP, simulate=rec, duration_s=seconds, rt=rt, rt_priority=80, rt_cpu=cpu, status=None))
    load_after, steal_after = os.getloadavg(), _steal_ms()
    s = r.summary
    period_ns = 1e9 / g.rate
    within = float(np.mean(r.send_offset_ns < period_ns)) if r.ticks else 0.0
    dev = r.device
    n = min(dev.latency_count, dev.latency_ticks.size)
    lat_ticks = dev.latency_ticks[:n]
    lat_us = dev.latency_s[:n] * 1e6
    print(f"--rt {'on ' if rt else 'off'}: SCHED_FIFO {'granted' if s['rt'] else 'NOT granted'}"
          + (f" ({r.rt_message})" if r.rt_message else ""))
    steal = f", hypervisor steal during the run {steal_after - steal_before:.0f} ms" if steal_before is not None and steal_after is not None else ""
    print(f"  load average before {load_before[0]:.2f} after {load_after[0]:.2f} (1 min), {os.cpu_count()} CPUs{steal}")
    print(f"  ticks {s['ticks']} missed {s['missed']} (longest stall {s['longest_stall_us'] / 1e3:.2f} ms) late>1ms {s['late_over_1ms']} "
          f"({100 * s['late_over_1ms'] / max(1, s['deadlines']):.3f} % of deadlines, skipped ones included)"
          f" watchdog events {s['watchdog_events']} (stale {s['timeouts']}) error {r.error}")
    print(f"  {floor_line}")
    print(f"  {'latency us':<34}{'p50':>9}{'p99':>9}{'p99.9':>9}{'max':>10}   later than 1 ms")
    if floor is not None:
        print(f"  {'machine: cyclictest wake-up':<34}{_num(floor['p50'])}{_num(floor['p99'])}{_num(floor['p999'])}{floor['max']:>10.1f}"
              f"   {floor['over_1ms']} of {floor['count']} ({100 * floor['over_1ms'] / max(1, floor['count']):.3f} %)")
    lat = s["lateness_us"]
    print(f"  {'flowtex: tick start - deadline':<34}{_num(lat['p50'])}{_num(lat['p99'])}{_num(lat['p999'])}{_num(lat['max'], 10)}"
          f"   {s['late_over_1ms']} of {s['deadlines']} ({100 * s['late_over_1ms'] / max(1, s['deadlines']):.3f} %)")
    print(f"  lateness us: {_dist(s['lateness_us'])}")
    print(f"  compute us:  {_dist(s['compute_us'])}")
    print(f"  actuator command for tick n sent within tick n: {100 * within:.3f} % of ticks")
    if r.ticks:
        off = r.send_offset_ns / 1e3
        print(f"  deadline -> last actuator frame of the tick sent, us: p50 {np.percentile(off, 50):.1f} p99 {np.percentile(off, 99):.1f} "
              f"p99.9 {np.percentile(off, 99.9):.1f} max {off.max():.1f}")
    if n:
        hist = np.bincount(np.minimum(lat_ticks, 3), minlength=4)
        print(f"  sensor->actuator latency over {n} samples: ticks 0: {hist[0]}, 1: {hist[1]}, 2: {hist[2]}, >=3: {hist[3]}; "
              f"wall (publish in the slack after tick n-1 -> first actuator frame) p50 {np.percentile(lat_us, 50):.1f} "
              f"p99 {np.percentile(lat_us, 99):.1f} max {lat_us.max():.1f} us")
    work_ns = int(s["compute_us"]["p50"] * 1000)
    if work_ns > 0:
        probe_s = min(seconds, 20.0)
        took = noise_floor(work_ns, probe_s, g.rate, rt) / 1e3
        print(f"  noise floor ({probe_s:g} s, a fixed {work_ns / 1e3:.1f} us busy-wait per tick on the same clock): "
              f"p50 {np.percentile(took, 50):.1f} p99 {np.percentile(took, 99):.1f} p99.9 {np.percentile(took, 99.9):.1f} max {took.max():.1f} us")
    return {"summary": s, "within": within, "latency_ticks_max": int(lat_ticks.max()) if n else None, "floor": floor}


def main(argv: list[str]) -> None:
    seconds = float(argv[0]) if argv and not argv[0].startswith("--") else 60.0
    modes = [True] if "--only-rt" in argv else [False] if "--no-rt" in argv else [False, True]
    graph_path, rec, what = _files()
    print(f"{what}, {seconds:g} s per run")
    # watchdog events are counted in the report; logged one by one they would bury it
    logging.getLogger("flowtex.runtime.safety").setLevel(logging.ERROR)
    for rt in modes:
        run(seconds, rt, graph_path, rec, cyclictest="--no-cyclictest" not in argv)


if __name__ == "__main__":
    main(sys.argv[1:])
