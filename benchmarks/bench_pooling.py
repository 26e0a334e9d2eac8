"""What pooling neighbouring pieces costs ``fit texture``: fit time with ``--pool 1`` (baseline) and the default, side by side.

    python benchmarks/bench_pooling.py [--repeats 3]

Each model is fitted on its piece and its nearest pieces (flowtex.fit.pooling),
so it sees some K times the samples. Fits two generated recordings, 64 s of
plateaus (flowtex.datasets.free_exploration) and 20 s of drifting speed and
force (flowtex.datasets.resonant.textured_exploration), at automatic order
and at order 6,4, alternating the two settings ``--repeats`` times in one
process; prints the median seconds and the ratio. The accuracy each buys is
in ``benchmarks/bench_compare.py --surfaces``. The machine is shared: quote
``uptime`` with the numbers.
"""

from __future__ import annotations

import argparse
import statistics
import time

from flowtex.datasets import free_exploration
from flowtex.datasets.resonant import textured_exploration
from flowtex.fit.texture import POOL_PIECES, TextureOptions, fit_texture

RATE = 1000.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    opts = ap.parse_args()
    recordings = (("free_exploration 64 s", free_exploration(64.0, RATE, seed=0)),
                  ("textured_exploration 20 s", textured_exploration(20.0, RATE, seed=1)))
    print(f"{'recording':26} {'order':>6} {'pieces':>6} {'--pool 1 s':>10} {f'--pool {POOL_PIECES} s':>10} {'ratio':>6}")
    for name, rec in recordings:
        a = rec.arrays
        for order in (None, (6, 4)):
            times: dict[int, list[float]] = {1: [], POOL_PIECES: []}
            pieces = 0
            for _ in range(opts.repeats):
                for pool in times:
                    t0 = time.perf_counter()
                    fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=order, pool_pieces=pool))
                    times[pool].append(time.perf_counter() - t0)
                    pieces = len(fit.pieces)
            alone, pooled = statistics.median(times[1]), statistics.median(times[POOL_PIECES])
            label = "auto" if order is None else f"{order[0]},{order[1]}"
            print(f"{name:26} {label:>6} {pieces:6d} {alone:10.2f} {pooled:10.2f} {pooled / alone:6.2f}", flush=True)


if __name__ == "__main__":
    main()
