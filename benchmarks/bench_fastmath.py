"""What FMA contraction (``fastmath={"contract"}``, flowtex.dsp.fastmath) buys: speed and the difference it makes.

    python benchmarks/bench_fastmath.py [--samples 1000000] [--ticks 200000] [--repeats 5] [--no-graph]

1. Side by side in this process, each kernel compiled twice from the same
   Python source (with and without contraction), runs alternated, median ns:
   the 10-biquad filter chain of bench_engine.py (flowtex.dsp.filters.sos_block,
   ns/sample) and the per-tick model conversion of the texture graph
   (lsf_to_poly for AR 19 and MA 17 + lattice_ladder_coefficients, ns/tick).
   With the largest difference between the two builds (relative to RMS / max).
2. The texture graph (speed, force -> texture_lookup -> arma_synth, a new
   model every tick, bench_texture.py's graph) in separate processes:
   FLOWTEX_CONTRACT=1 (default) and 0 on this CPU, and 0 with numba's
   generic x86-64 code (NUMBA_CPU_NAME=generic): ns/tick of ``run`` and the
   largest output difference against the default, relative to RMS.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit
from scipy import signal

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.dsp.arma import lattice_ladder_coefficients
from flowtex.dsp.filters import sos_block, sos_to_params
from flowtex.dsp.lsf import lsf_to_poly

REPO = Path(__file__).resolve().parents[1]
RATE = 10_000.0
CUTOFFS = [3000, 2800, 2600, 2400, 2200, 2000, 1800, 1600, 1400, 1200]  # Hz, as benchmarks/bench_engine.py
BUILDS = {"contract": {"contract"}, "none": False}


def median_ns(fn, repeats: int, per: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        fn()
        times.append((time.perf_counter_ns() - t0) / per)
    return statistics.median(times)


def filter_chain(samples: int, repeats: int) -> None:
    coef = sos_to_params(np.vstack([signal.butter(2, c, fs=RATE, output="sos") for c in CUTOFFS]))
    x = np.random.default_rng(1).standard_normal((samples, 1))
    kernels = {name: njit(fastmath=fm)(sos_block.py_func) for name, fm in BUILDS.items()}
    outs, ns = {}, {name: [] for name in BUILDS}
    for name, k in kernels.items():  # compile and keep one output of each
        outs[name] = np.empty_like(x)
        k(coef, np.zeros(4 * len(CUTOFFS)), x, outs[name])
    for _ in range(repeats):
        for name, k in kernels.items():
            y = np.empty_like(x)
            ns[name].append(median_ns(lambda k=k, y=y: k(coef, np.zeros(4 * len(CUTOFFS)), x, y), 1, samples))
    diff = np.max(np.abs(outs["contract"] - outs["none"])) / np.sqrt(np.mean(outs["none"] ** 2))
    report("filter chain, 10 biquads (ns/sample)", {n: statistics.median(v) for n, v in ns.items()}, f"max|diff| {diff:.2e} x RMS")


def make_conversion(fastmath):
    lsf = njit(fastmath=fastmath)(lsf_to_poly.py_func)
    lattice = njit(fastmath=fastmath)(lattice_ladder_coefficients.py_func)

    @njit
    def convert(ar_lsf, ma_lsf, weights, a, c, k, cc, v, wa, wr, out_k):
        n_models = ar_lsf.shape[0]
        la = np.empty(ar_lsf.shape[1])
        lm = np.empty(ma_lsf.shape[1])
        for t in range(weights.shape[0]):
            i, j = t % n_models, (t + 1) % n_models
            w = weights[t]
            for m in range(la.shape[0]):
                la[m] = (1.0 - w) * ar_lsf[i, m] + w * ar_lsf[j, m]
            for m in range(lm.shape[0]):
                lm[m] = (1.0 - w) * ma_lsf[i, m] + w * ma_lsf[j, m]
            lsf(la, a)
            lsf(lm, c)
            lattice(a, c, 1.0, k, cc, v, wa, wr)
            out_k[t] = k[0]

    return convert


def model_conversion(ticks: int, repeats: int) -> None:
    ms = cork_like_model_set()
    ar_lsf, ma_lsf = np.ascontiguousarray(ms.ar_lsf), np.ascontiguousarray(ms.ma_lsf)
    p, q = ar_lsf.shape[1], ma_lsf.shape[1]
    L = max(p, q)
    weights = np.random.default_rng(2).uniform(0.0, 1.0, ticks)
    funcs = {name: make_conversion(fm) for name, fm in BUILDS.items()}
    outs, ns = {}, {name: [] for name in BUILDS}

    def run(f, out):
        f(ar_lsf, ma_lsf, weights, np.empty(p + 1), np.empty(q + 1), np.empty(L), np.empty(L), np.empty(L + 1),
          np.empty(L + 1), np.empty(L + 1), out)

    for name, f in funcs.items():
        outs[name] = np.empty(ticks)
        run(f, outs[name])
    for _ in range(repeats):
        for name, f in funcs.items():
            ns[name].append(median_ns(lambda f=f: run(f, np.empty(ticks)), 1, ticks))
    diff = np.max(np.abs(outs["contract"] - outs["none"]))
    report("texture model per tick: lsf_to_poly x2 + lattice (ns/tick)", {n: statistics.median(v) for n, v in ns.items()},
           f"max|diff of k_L| {diff:.2e} (|k| <= 1)")


def report(title: str, ns: dict[str, float], error: str) -> None:
    print(f"{title}: contract {ns['contract']:.2f}, none {ns['none']:.2f}, none/contract x{ns['none'] / ns['contract']:.2f}; {error}")


# ----------------------------------------------------------------------------- whole graph, separate processes

def graph_worker(out: Path, ticks: int, repeats: int) -> None:
    sys.path.insert(0, str(REPO / "benchmarks"))
    from bench_texture import GRAPH, trajectory

    import flowtex
    from flowtex.io.modelset import save_model_set

    ms = cork_like_model_set()
    with tempfile.TemporaryDirectory() as tmp:
        models = Path(tmp) / "cork.json"
        save_model_set(ms, models)
        path = Path(tmp) / "g.yaml"
        path.write_text(GRAPH.format(every=1, models=models, extra=""))
        graph = flowtex.load_graph(path)
        inputs = trajectory(ticks, ms.max_speed, ms.max_force)
        y = graph.run(inputs)["accel"]
        ns = statistics.median(median_ns(lambda: graph.run(inputs), 1, ticks) for _ in range(repeats))
    np.save(out, y)
    print(json.dumps({"ns": ns}))


def texture_graph(ticks: int, repeats: int) -> None:
    configs = {"contract (default)": {"FLOWTEX_CONTRACT": "1"}, "FLOWTEX_CONTRACT=0": {"FLOWTEX_CONTRACT": "0"},
               "FLOWTEX_CONTRACT=0, generic CPU": {"FLOWTEX_CONTRACT": "0", "NUMBA_CPU_NAME": "generic"}}
    with tempfile.TemporaryDirectory() as tmp:
        results = {}
        for label, extra in configs.items():
            out = Path(tmp) / f"{len(results)}.npy"
            env = {**os.environ, **extra, "PYTHONPATH": str(REPO)}
            run = subprocess.run([sys.executable, __file__, "--worker", str(out), str(ticks), str(repeats)], env=env,
                                 check=True, capture_output=True, text=True)
            results[label] = (json.loads(run.stdout.strip().splitlines()[-1])["ns"], np.load(out))
    base_ns, base = results["contract (default)"]
    scale = np.sqrt(np.mean(base ** 2))
    print(f"texture graph, new model every tick ({ticks} ticks, separate processes):")
    for label, (ns, y) in results.items():
        print(f"  {label:<34} {ns:8.1f} ns/tick  x{ns / base_ns:.2f}   max|diff| vs default {np.max(np.abs(y - base)) / scale:.2e} x RMS,"
              f" bits differ in {int(np.sum(y != base))} of {y.size}")
    a, b = results["FLOWTEX_CONTRACT=0"][1], results["FLOWTEX_CONTRACT=0, generic CPU"][1]
    print(f"  without contraction, this CPU vs generic: bits differ in {int(np.sum(a != b))} of {a.size}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--ticks", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--no-graph", action="store_true", help="skip part 2 (three processes compiling the texture graph)")
    args = ap.parse_args()
    filter_chain(args.samples, args.repeats)
    model_conversion(args.ticks, args.repeats)
    if not args.no_graph:
        texture_graph(args.ticks, args.repeats)


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--worker":
        graph_worker(Path(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]))
    else:
        main()
