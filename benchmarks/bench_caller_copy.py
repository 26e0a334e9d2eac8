"""What it costs that no kernel gets the caller's array: ``Graph.run``'s copy of a single input, the processor's copy,
the read-only alternative, and ``Graph.step`` (which copies nothing) against another tree's.

    python benchmarks/bench_caller_copy.py [--samples 1000000] [--runs 7] [--ticks 20000] [--baseline-tree /path/to/tree]

``run``: the 10-node chain of bench_engine.py over ``--samples`` samples. The compiled ``run`` entry point is called
on the caller's array itself (the old way) and on a copy made just before (the current way), alternately in this
process; the figure is the copy's share of a run. A read-only view is no alternative there: kernels address the
graph's inputs through the arena's raw pointers, so the flag guards nothing (tests/graph/test_caller_arrays.py).

``processor``: a butterworth processor's call on chunks of 1, 64 and 4096 rows (the copy is inside the call) beside
the bare copy, and beside its kernel called on a read-only view (numba types a read-only array apart: each kernel
compiles once more for it, timed as its first call, a compile or a load from numba's disk cache).

``step``: per-tick ``Graph.step()`` of the chain, in a fresh process per tree, this tree and ``--baseline-tree``
alternately (``--step-rounds`` each); step() copies nothing, so the two should agree within the machine's noise.

Timings taken on a shared machine are load-dependent: every comparison is side by side in one run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import flowtex
from flowtex.graph.arena import OUT_WIDTH
from flowtex.registry import load_registry

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_engine import chain_yaml  # noqa: E402  (a script beside this one)

REPO = Path(__file__).resolve().parents[1]

STEP_SNIPPET = """
import sys, time, numpy as np, flowtex
g = flowtex.load_graph(sys.argv[1])
x = np.random.default_rng(1).standard_normal({ticks})
step = g.step
for v in x[:2000]:
    step({{"x": float(v)}})
per, times = 1000, []
values = [{{"x": float(v)}} for v in x]
for start in range(0, len(x), per):
    t0 = time.perf_counter_ns()
    for k in range(start, start + per):
        step(values[k])
    times.append((time.perf_counter_ns() - t0) / per)
print(float(np.median(times)))
"""


def bench_run(graph: flowtex.Graph, samples: int, runs: int) -> dict:
    x = np.random.default_rng(0).standard_normal(samples)
    run = graph._code.get("run")
    width = int(graph.i[OUT_WIDTH])
    bare, copied, copy_only = [], [], []
    for _ in range(runs):
        for way in (bare, copied):
            graph.reset()
            y = np.empty(samples * width)
            t0 = time.perf_counter()
            run(graph.f, graph.i, x.copy() if way is copied else x, y)
            way.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        np.array(x, dtype=np.float64, order="C")
        copy_only.append(time.perf_counter() - t0)
    b, c = statistics.median(bare), statistics.median(copied)
    return {"bare_ms": 1e3 * b, "copied_ms": 1e3 * c, "copy_ms": 1e3 * statistics.median(copy_only), "ratio": c / b}


def bench_processor(runs: int) -> list[dict]:
    cls = load_registry().types["butterworth"]
    rows = []
    for n in (1, 64, 4096):
        x = np.random.default_rng(2).standard_normal(n)
        proc = cls.processor(order=4, cutoff_hz=50.0)
        proc(x=x)
        ro = x[:, None].copy()
        ro.flags.writeable = False
        y = np.empty((n, 1))
        t0 = time.perf_counter()
        proc.kernel(proc.p, proc.s, proc.si, ro, y)  # the read-only specialization: compiled or loaded once
        first_ro = time.perf_counter() - t0
        calls, copies, ro_calls = [], [], []
        reps = max(1, 20000 // n)
        for _ in range(runs):
            t0 = time.perf_counter()
            for _ in range(reps):
                proc(x=x)
            t1 = time.perf_counter()
            for _ in range(reps):
                np.array(x[:, None], dtype=np.float64, order="C")
            t2 = time.perf_counter()
            for _ in range(reps):
                proc.kernel(proc.p, proc.s, proc.si, ro, y)
            t3 = time.perf_counter()
            calls.append((t1 - t0) / reps)
            copies.append((t2 - t1) / reps)
            ro_calls.append((t3 - t2) / reps)
        rows.append({"rows": n, "call_us": 1e6 * statistics.median(calls), "copy_us": 1e6 * statistics.median(copies),
                     "ro_kernel_us": 1e6 * statistics.median(ro_calls), "ro_first_ms": 1e3 * first_ro})
    return rows


def bench_step_trees(graph_path: Path, baseline: Path, ticks: int, rounds: int) -> dict:
    code = STEP_SNIPPET.format(ticks=ticks)
    got: dict[str, list[float]] = {"this": [], "baseline": []}
    for _ in range(rounds):
        for label, tree in (("this", REPO), ("baseline", baseline)):
            env = dict(os.environ, PYTHONPATH=str(tree))
            out = subprocess.run([sys.executable, "-c", code, str(graph_path)], cwd=tree, env=env, capture_output=True,
                                 text=True, check=True, timeout=600)
            got[label].append(float(out.stdout.strip().splitlines()[-1]))
    this, base = statistics.median(got["this"]), statistics.median(got["baseline"])
    return {"this_ns": this, "baseline_ns": base, "ratio": this / base, "all": got}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--ticks", type=int, default=20_000)
    ap.add_argument("--step-rounds", type=int, default=3)
    ap.add_argument("--baseline-tree", type=Path, help="a checkout to compare step() with (e.g. main before the change)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "chain10.yaml"
        path.write_text(chain_yaml())
        graph = flowtex.load_graph(path)
        graph.run({"x": np.zeros(1000)})
        r = bench_run(graph, args.samples, args.runs)
        print(f"run, 10-node chain, {args.samples:,} samples, median of {args.runs} (tier {graph.tier}):")
        print(f"  on the caller's array {r['bare_ms']:8.2f} ms   on a copy {r['copied_ms']:8.2f} ms "
              f"(x{r['ratio']:.3f})   the copy alone {r['copy_ms']:.2f} ms")
        print("processor, butterworth order 4 (per call):")
        for p in bench_processor(args.runs):
            print(f"  {p['rows']:5d} rows: call {p['call_us']:8.2f} us, of which the copy ~{p['copy_us']:6.2f} us; "
                  f"kernel on a read-only view {p['ro_kernel_us']:8.2f} us (its first call {p['ro_first_ms']:.1f} ms)")
        if args.baseline_tree:
            s = bench_step_trees(path, args.baseline_tree.resolve(), args.ticks, args.step_rounds)
            print(f"step(), 10-node chain, median ns/tick over {args.step_rounds} fresh processes per tree:")
            print(f"  this tree {s['this_ns']:8.0f} ns   {args.baseline_tree} {s['baseline_ns']:8.0f} ns   "
                  f"(x{s['ratio']:.3f}; runs {s['all']})")


if __name__ == "__main__":
    main()
