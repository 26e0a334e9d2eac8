"""Benchmark: a whole surface (64 s of free exploration at 1 kHz) -> model set, as one `flowtex fit texture` process.

Prints, side by side in one run: wall time of the whole process (compiled
code already cached: one warm-up run first) for automatic order (p, q <= 20)
and for a fixed order, with the accuracy each buys (median LSD of the fitted
set against the truth at the plateau points). ``--scaling`` also fits 20
surfaces (64 s each, automatic order) serially and with 1 and 2 Dask workers and prints the speed-ups.

    python benchmarks/bench_fit_surface.py [--scaling]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from flowtex.datasets import free_exploration
from flowtex.fit.quality import set_lsd_db
from flowtex.io.modelset import load_model_set


def run_fit(args: list[str]) -> float:
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "flowtex", "fit", "texture", *args], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scaling", action="store_true", help="also time 20 surfaces serially and with 1 and 2 Dask workers")
    ap.add_argument("--seconds", type=float, default=64.0)
    ap.add_argument("--surface-seconds", type=float, default=64.0, help="length of each of the 20 surfaces of --scaling")
    opts = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rec = free_exploration(opts.seconds, 1000.0, seed=11)
        path = rec.save(tmp / "surface.npz")
        sp = np.array([p.speed for p in rec.truth["plateaus"]])
        fo = np.array([p.force for p in rec.truth["plateaus"]])
        print(f"{opts.seconds:g} s of free exploration at 1 kHz, {len(sp)} plateaus, truth order 6/4; cores: {os.cpu_count()}")
        print(f"{'configuration':28} {'wall s':>7} {'ratio':>6} {'order':>6} {'median LSD vs truth dB':>23}")
        base = None
        for label, extra in (("--order 6,4", ["--order", "6,4"]), ("--order auto --max-order 20", ["--max-order", "20"])):
            out = tmp / "s.json"
            common = [str(path), "--speed", "speed", "-o", str(out), *extra]
            run_fit(common)                       # warm-up: numba caches
            wall = run_fit(common)
            ms = load_model_set(out)
            lsd = float(np.median(set_lsd_db(ms, rec.truth["surface"], sp, fo)))
            base = base or wall
            print(f"{label:28} {wall:7.2f} {wall / base:6.2f} {ms.ar_order:>3},{ms.ma_order:<2} {lsd:23.2f}")
        if opts.scaling:
            folder = tmp / "many"
            for k in range(20):
                free_exploration(opts.surface_seconds, 1000.0, seed=100 + k, plateau_s=(1.5, 2.0)).save(folder / f"s{k:02d}.npz")
            times = {}
            for workers in (0, 1, 2):
                times[workers] = run_fit([str(folder), "--speed", "speed", "--max-order", "20", "--out-dir", str(tmp / f"o{workers}"),
                                          "--workers", str(workers)])
            same = all((tmp / "o0" / f"s{k:02d}.json").read_bytes() == (tmp / f"o{w}" / f"s{k:02d}.json").read_bytes()
                       for k in range(20) for w in (1, 2))
            print(f"20 surfaces x {opts.surface_seconds:g} s (whole process, Dask start-up included): serial {times[0]:.1f} s, "
                  f"1 worker {times[1]:.1f} s, 2 workers {times[2]:.1f} s; speed-up 2 vs 1 worker {times[1] / times[2]:.2f}, "
                  f"2 workers vs serial {times[0] / times[2]:.2f}; files identical to the serial run: {same}")

if __name__ == "__main__":
    main()
