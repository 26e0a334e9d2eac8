"""``flowtex compare`` time for a 60 s recording, beside its baseline: one render of the same path.

    python benchmarks/bench_compare.py [--seconds 60] [--repeats 3]

A 60-s person-like recording of the 15-dB surface (flowtex.datasets.realistic)
is fitted once (``fit texture`` defaults; its time is printed for scale), then,
median over ``--repeats`` after one warm-up (numba compile or cache load):

* ``render x1`` (baseline): flowtex.fit.compare.render_along with one seed, the
  least a comparison must do (graph build + 60 000 ticks of texture_lookup and
  arma_synth);
* ``compare --seeds 1`` and ``compare --seeds 4`` (the default):
  flowtex.fit.compare.compare_surface, renders + high-passes + Welch PSDs +
  per-window figures;

with the ratio to the baseline and the seconds of recording compared per
second. The machine is shared: quote ``uptime`` with the numbers.
"""

from __future__ import annotations

import argparse
import statistics
import time

from flowtex.datasets.realistic import human_exploration
from flowtex.fit.compare import CompareOptions, compare_surface, render_along
from flowtex.fit.texture import fit_texture


def _median_time(fn, repeats: int) -> float:
    fn()                                              # warm-up: compile or load the cached graph
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--repeats", type=int, default=3)
    opts = ap.parse_args()
    rate = 1000.0
    rec = human_exploration(opts.seconds, rate, seed=0)
    a = rec.arrays
    t0 = time.perf_counter()
    ms = fit_texture(a["accel"], a["speed"], a["normal_force"], rate).model_set
    fit_s = time.perf_counter() - t0
    print(f"{opts.seconds:g} s recording at 1 kHz; fit texture {fit_s:.2f} s ({ms.num_models} models, order {ms.ar_order},{ms.ma_order})")
    base = _median_time(lambda: render_along(ms, a["speed"], a["normal_force"], range(1)), opts.repeats)
    rows = [("render x1 (baseline)", base)]
    for seeds in (1, 4):
        opt = CompareOptions(seeds=seeds)
        rows.append((f"compare --seeds {seeds}",
                     _median_time(lambda opt=opt: compare_surface(ms, a["accel"], a["speed"], a["normal_force"], rate, opt),
                                  opts.repeats)))
    print(f"{'configuration':24} {'seconds':>8} {'x baseline':>10} {'recording s per s':>18}")
    for label, sec in rows:
        print(f"{label:24} {sec:8.3f} {sec / base:10.2f} {opts.seconds / sec:18.1f}")


if __name__ == "__main__":
    main()
