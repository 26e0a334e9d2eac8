"""Graph engine benchmark: offline throughput, per-tick step cost, start-up time.

    python benchmarks/bench_engine.py [--samples 1000000] [--runs 5] [--ticks 200000]

Every speed is measured side by side with its baseline in this process and
reported as a ratio, with the numerical error the configuration buys.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from numba import njit
from scipy import signal

import flowtex

RATE = 10_000.0
CUTOFFS = [3000, 2800, 2600, 2400, 2200, 2000, 1800, 1600, 1400, 1200]  # Hz, one 2nd-order lowpass each
REPO = Path(__file__).resolve().parents[1]


def chain_yaml() -> str:
    nodes = "\n".join(f"  s{k}: {{type: butterworth, params: {{kind: lowpass, order: 2, cutoff_hz: {c}}}}}" for k, c in enumerate(CUTOFFS))
    edges = "\n".join(["  - x -> s0.x"] + [f"  - s{k - 1}.y -> s{k}.x" for k in range(1, len(CUTOFFS))])
    return f"flowtex: 1\nname: chain10\nrate: {RATE}\ninputs:\n  x: {{}}\nnodes:\n{nodes}\nedges:\n{edges}\noutputs:\n  y: s{len(CUTOFFS) - 1}.y\n"


def chain_sos() -> np.ndarray:
    return np.vstack([signal.butter(2, c, fs=RATE, output="sos") for c in CUTOFFS])


@njit(cache=True)
def fused_tick(sos: np.ndarray, z: np.ndarray, x: float) -> float:
    """The floor: one hand-written numba function doing the 10 sections for one sample."""
    for k in range(sos.shape[0]):
        y = sos[k, 0] * x + z[k, 0]
        z[k, 0] = sos[k, 1] * x - sos[k, 4] * y + z[k, 1]
        z[k, 1] = sos[k, 2] * x - sos[k, 5] * y
        x = y
    return x


def bench_offline(graph: flowtex.Graph, samples: int, runs: int) -> dict:
    x = np.random.default_rng(0).standard_normal(samples)
    sos = chain_sos()
    graph.run({"x": x[:1000]})
    signal.sosfilt(sos, x[:1000])
    ours, ref_t, ratios = [], [], []
    for _ in range(runs):  # paired: both on the same data, back to back
        t0 = time.perf_counter()
        y = graph.run({"x": x})["y"]
        t1 = time.perf_counter()
        ref = signal.sosfilt(sos, x)
        t2 = time.perf_counter()
        ours.append(t1 - t0)
        ref_t.append(t2 - t1)
        ratios.append((t1 - t0) / (t2 - t1))
    err = float(np.max(np.abs(y - ref)) / np.max(np.abs(ref)))
    return {"flowtex_ms": 1e3 * np.median(ours), "sosfilt_ms": 1e3 * np.median(ref_t),
            "ratio": float(np.median(ratios)), "ns_per_sample": 1e9 * np.median(ours) / samples, "rel_err": err}


def bench_step(graph: flowtex.Graph, ticks: int) -> dict:
    x = np.random.default_rng(1).standard_normal(ticks)
    sos = chain_sos()
    z = np.zeros((sos.shape[0], 2))
    fused_tick(sos, z, 0.0)
    graph.reset()
    step = graph.step
    values = [{"x": float(v)} for v in x]
    floor_ns, step_ns = [], []
    out_step = np.empty(ticks)
    out_floor = np.empty(ticks)
    per = 1000
    for start in range(0, ticks, per):  # interleave chunks so both see the same machine state
        t0 = time.perf_counter_ns()
        for k in range(start, start + per):
            out_step[k] = step(values[k])["y"]
        t1 = time.perf_counter_ns()
        for k in range(start, start + per):
            out_floor[k] = fused_tick(sos, z, values[k]["x"])
        t2 = time.perf_counter_ns()
        step_ns.append((t1 - t0) / per)
        floor_ns.append((t2 - t1) / per)
    err = float(np.max(np.abs(out_step - out_floor)) / np.max(np.abs(out_floor)))
    s, f = float(np.median(step_ns)), float(np.median(floor_ns))
    return {"step_ns": s, "floor_ns": f, "ratio": s / f, "rel_err_vs_floor": err}


def bench_startup(graph_path: Path, input_path: Path) -> dict:
    env = dict(os.environ)
    tmp = Path(tempfile.mkdtemp(prefix="flowtex-bench-"))
    env["FLOWTEX_CACHE_DIR"] = str(tmp / "flowtex")
    env["NUMBA_CACHE_DIR"] = str(tmp / "numba")
    cmd = [sys.executable, "-m", "flowtex", "run", str(graph_path), "--input", str(input_path), "--output", str(tmp / "out.npz")]
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, env=env, capture_output=True)
        times.append(time.perf_counter() - t0)
    shutil.rmtree(tmp, ignore_errors=True)
    return {"cold_s": times[0], "warm_s": min(times[1:])}


def bench_warm_build(tmpdir: Path) -> dict:
    """Build a graph, then one that differs only in parameter values: the second reuses compiled code."""
    base = chain_yaml()
    a, b = tmpdir / "a.yaml", tmpdir / "b.yaml"
    a.write_text(base)
    b.write_text(base.replace("cutoff_hz: 3000", "cutoff_hz: 2900"))
    flowtex.load_graph(a)
    t0 = time.perf_counter()
    flowtex.load_graph(b)
    return {"warm_build_s": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--ticks", type=int, default=200_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "chain10.yaml"
        path.write_text(chain_yaml())
        graph = flowtex.load_graph(path)
        off = bench_offline(graph, args.samples, args.runs)
        step = bench_step(graph, args.ticks)
        warm = bench_warm_build(Path(d))
    start = bench_startup(REPO / "graphs" / "accel_preprocess.yaml", REPO / "graphs" / "data" / "accel_demo.npz")
    print(textwrap.dedent(f"""\
    10 cascaded 2nd-order Butterworth sections as 10 nodes, {args.samples:,} samples, median of {args.runs} paired runs
      flowtex run()         {off['flowtex_ms']:8.2f} ms  ({off['ns_per_sample']:.2f} ns/sample)
      scipy sosfilt         {off['sosfilt_ms']:8.2f} ms
      ratio flowtex/scipy   {off['ratio']:8.3f}   (target <= 1.0)   max rel. error vs sosfilt {off['rel_err']:.1e}
    per-tick step() from Python (mapping in, mapping out), median over {args.ticks:,} ticks
      flowtex step()        {step['step_ns'] / 1000:8.3f} us
      fused numba floor     {step['floor_ns'] / 1000:8.3f} us
      ratio step/floor      {step['ratio']:8.2f}   (target <= 3, and <= 3 us)   max rel. error vs floor {step['rel_err_vs_floor']:.1e}
    start-up of 'flowtex run graphs/accel_preprocess.yaml' (wall time, new process)
      cold (empty caches)   {start['cold_s']:8.2f} s
      warm                  {start['warm_s']:8.2f} s    (target < 2 s)
    second graph differing only in parameters, same process
      warm build            {warm['warm_build_s']:8.3f} s    (target <= 0.5 s)"""))


if __name__ == "__main__":
    main()
