"""``flowtex compare`` time for a 60 s recording, beside its baseline: one render of the same path.

    python benchmarks/bench_compare.py [--seconds 60] [--repeats 3]
    python benchmarks/bench_compare.py --surfaces 8 [--surface-seconds 20] [--order 4,2] [--pools 1,5]

``--surfaces N`` prints, instead of times, issue 23's power and LSD table on N
generated recordings that behave like real ones (flowtex.datasets.resonant:
moving resonances, heavy tails, loudness that wanders from second to second),
seeds 0..N-1: in-sample (fit and compare on the whole recording, and the true
surface's own render for reference) and under two-fold cross-validation over
interleaved one-second blocks (flowtex.fit.crossval; the mean over the folds),
once per ``fit texture --pool`` value in ``--pools`` (1: every piece fitted
alone, the method before pooling; 5: the default), side by side on the same
recording.
Targets: in-sample power within +-1 dB and LSD within 0.5 dB of the truth's;
held out, mean power over the folds within +-1 dB and the pooled out-of-fold
LSD (every second once, rendered by the fold's surface that did not see it)
within 1 dB of in-sample. Beside them: the mean of the folds' own LSDs, and
the LSD of the true surface itself on each fold's held-out blocks (what one
fold's data set, whatever the surface).

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
from flowtex.fit.texture import POOL_PIECES, fit_texture


def _median_time(fn, repeats: int) -> float:
    fn()                                              # warm-up: compile or load the cached graph
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def surfaces_table(count: int, seconds: float, order: tuple[int, int], pools: tuple[int, ...]) -> None:
    """Issue 23's power and LSD table on ``count`` generated recordings, one row per seed and ``--pool`` value, the
    fits of one seed side by side on the same recording (module docstring)."""
    from flowtex.datasets.resonant import textured_exploration
    from flowtex.fit.crossval import evaluate_splits, fold_splits, holdout_doc
    from flowtex.fit.texture import TextureOptions

    rate = 1000.0
    print(f"{count} generated recordings of {seconds:g} s at 1 kHz, fitted at order {order[0]},{order[1]}")
    print(f"{'seed':>4} {'pool':>4} | {'in-sample P dB':>14} {'LSD dB':>7} {'truth LSD':>9} {'ok':>3} | "
          f"{'pooled P dB':>11} {'LSD dB':>7} {'- in-sample':>11} {'ok':>3} | {'2-fold mean P dB':>16} {'mean LSD':>8} "
          f"{'truth fold LSDs':>15}")
    for seed in range(count):
        rec = textured_exploration(seconds, rate, seed=seed)
        a = rec.arrays
        sig = (a["accel"], a["speed"], a["normal_force"])
        truth = compare_surface(rec.truth["surface"], *sig, rate)
        splits = fold_splits(a["accel"].shape[0], rate, 2)
        truth_held = [compare_surface(rec.truth["surface"], *sig, rate, ranges=test) for _train, test in splits]
        for pool in pools:
            opt = TextureOptions(order=order, pool_pieces=pool)
            fit = fit_texture(*sig, rate, opt)
            got = compare_surface(fit.model_set, *sig, rate)
            cv = evaluate_splits(*sig, rate, splits, opt)
            mean = holdout_doc("blocks", "folds", 2, cv.comparisons)["mean"]
            pooled = cv.pooled
            assert pooled is not None
            ok_in = abs(got.power_ratio_db) <= 1.0 and got.lsd_db <= truth.lsd_db + 0.5
            ok_cv = abs(mean["power_ratio_db"]) <= 1.0 and pooled.lsd_db <= got.lsd_db + 1.0
            print(f"{seed:4d} {pool:4d} | {got.power_ratio_db:+14.2f} {got.lsd_db:7.2f} {truth.lsd_db:9.2f} "
                  f"{'yes' if ok_in else 'NO':>3} | {pooled.power_ratio_db:+11.2f} {pooled.lsd_db:7.2f} "
                  f"{pooled.lsd_db - got.lsd_db:+11.2f} {'yes' if ok_cv else 'NO':>3} | {mean['power_ratio_db']:+16.2f} "
                  f"{mean['lsd_db']:8.2f} {' / '.join(f'{c.lsd_db:.2f}' for c in truth_held):>15}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--surfaces", type=int, default=0, metavar="N", help="print the power and LSD table on N generated recordings")
    ap.add_argument("--surface-seconds", type=float, default=20.0)
    ap.add_argument("--order", default="4,2", help="P,Q of the fits in the --surfaces table")
    ap.add_argument("--pools", default=f"1,{POOL_PIECES}", help="fit texture --pool values compared in the --surfaces table")
    opts = ap.parse_args()
    if opts.surfaces:
        p, q = (int(v) for v in opts.order.split(","))
        surfaces_table(opts.surfaces, opts.surface_seconds, (p, q), tuple(int(v) for v in opts.pools.split(",")))
        return
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
