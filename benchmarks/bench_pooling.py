"""What pooling neighbouring pieces costs ``fit texture``: fit time with ``--pool 1`` (baseline) and the default, side by side.

    python benchmarks/bench_pooling.py [--repeats 3]
    python benchmarks/bench_pooling.py --realistic 6 [--seconds 20]

Each model is fitted on its piece and its nearest pieces (flowtex.fit.pooling),
so it sees some K times the samples. Fits two generated recordings, 64 s of
plateaus (flowtex.datasets.free_exploration) and 20 s of drifting speed and
force (flowtex.datasets.resonant.textured_exploration), at automatic order
and at order 6,4, alternating the two settings ``--repeats`` times in one
process; prints the median seconds and the ratio. The accuracy each buys is
in ``benchmarks/bench_compare.py --surfaces``. The machine is shared: quote
``uptime`` with the numbers.

``--realistic N`` prints, instead of times, the accuracy on N person-like
recordings of the 15-dB surface (flowtex.datasets.realistic.human_exploration,
seeds 0..N-1; resonances that move little, no wandering loudness): power
(dB) and LSD above the true surface's own render (dB), in-sample and on the
held-out last 30 % (fitted on the first 70 %), ``--pool 1`` and the default
fitted on the same recording: pooling must not cost where there is no
loudness to pool.
"""

from __future__ import annotations

import argparse
import statistics
import time

from flowtex.datasets import free_exploration
from flowtex.datasets.resonant import textured_exploration
from flowtex.fit.texture import POOL_PIECES, TextureOptions, fit_texture

RATE = 1000.0


def realistic(count: int, seconds: float) -> None:
    """The accuracy table of ``--realistic`` (module docstring)."""
    from flowtex.datasets.realistic import human_exploration
    from flowtex.fit.compare import compare_surface

    print(f"{count} person-like recordings of {seconds:g} s; held out: the last 30 %")
    print(f"{'seed':>4} {'pool':>4} | {'in-sample P dB':>14} {'LSD - truth':>11} | {'held-out P dB':>13} {'LSD - truth':>11}")
    for seed in range(count):
        rec = human_exploration(seconds, RATE, seed=seed)
        a = rec.arrays
        sig = [a[k] for k in ("accel", "speed", "normal_force")]
        cut = int(round(0.7 * sig[0].shape[0]))
        truth = [compare_surface(rec.truth["surface"], *part, RATE).lsd_db for part in (sig, [v[cut:] for v in sig])]
        for pool in (1, POOL_PIECES):
            opt = TextureOptions(pool_pieces=pool)
            whole = compare_surface(fit_texture(*sig, RATE, opt).model_set, *sig, RATE)
            head = fit_texture(*[v[:cut] for v in sig], RATE, opt).model_set
            tail = compare_surface(head, *[v[cut:] for v in sig], RATE)
            print(f"{seed:4d} {pool:4d} | {whole.power_ratio_db:+14.2f} {whole.lsd_db - truth[0]:+11.2f} | "
                  f"{tail.power_ratio_db:+13.2f} {tail.lsd_db - truth[1]:+11.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--realistic", type=int, default=0, metavar="N", help="print the accuracy on N person-like recordings")
    ap.add_argument("--seconds", type=float, default=20.0, help="length of each --realistic recording")
    opts = ap.parse_args()
    if opts.realistic:
        realistic(opts.realistic, opts.seconds)
        return
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
