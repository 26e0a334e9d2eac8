"""Which loudness interpolation tracks recordings best: variance (HaTT), power or log_power (docs/fitting.md).

    PYTHONPATH=. python3 benchmarks/bench_interpolation.py [--seeds 6] [--seconds 20] [--holdout 0.3]
    PYTHONPATH=. python3 benchmarks/bench_interpolation.py --resonant [--seeds 6] [--order 4,2]

Person-like recordings of the known 15-dB surface whose resonances move with
speed and force (flowtex.datasets.realistic.human_exploration, one per seed)
are fitted with ``fit texture`` defaults; each fitted set is rendered along
the recorded path with every ``interpolation`` rule (its recorded ``outside``
rule, trend, kept) and compared with the recording (flowtex.fit.compare, 4
excitation seeds): power ratio (dB), LSD above the true surface's own render
(dB) and window-RMS correlation, in-sample and on the held-out tail
(``--holdout``: fitted on the first part only). Mean and worst over seeds.

``--resonant``: recordings that behave like real ones instead
(flowtex.datasets.resonant.textured_exploration: resonances that move with
speed and force, loudness that wanders by seconds, heavy tails), fitted at
``--order``; held out: the mean of two-fold cross-validation over interleaved
one-second blocks (flowtex.fit.crossval), as issue 23 asks.

Caveat printed with the table: the recording itself is rendered from the true
surface's grid with HaTT's rule (variance interpolation between its models),
so the generator favours no rule by construction only where the fitted
pieces coincide with the true grid's models.
"""

from __future__ import annotations

import argparse

import numpy as np

from flowtex.datasets.realistic import human_exploration
from flowtex.fit.compare import CompareOptions, compare_surface
from flowtex.fit.texture import fit_texture
from flowtex.models.rendering import INTERPOLATION_CHOICES

RATE = 1000.0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--holdout", type=float, default=0.3)
    ap.add_argument("--resonant", action="store_true", help="flowtex.datasets.resonant recordings, two-fold CV")
    ap.add_argument("--order", default="4,2", help="P,Q of the fits with --resonant")
    opts = ap.parse_args()
    if opts.resonant:
        resonant(opts.seeds, opts.seconds, tuple(int(v) for v in opts.order.split(",")))
        return
    rows: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    for seed in range(opts.seeds):
        rec = human_exploration(opts.seconds, RATE, seed=seed)
        a = rec.arrays
        cut = int(round((1.0 - opts.holdout) * a["accel"].shape[0]))           # held out: the tail
        for part, fit_slice, cmp_slice in (("in-sample", slice(None), slice(None)),
                                           ("held-out", slice(None, cut), slice(cut, None))):
            ms = fit_texture(a["accel"][fit_slice], a["speed"][fit_slice], a["normal_force"][fit_slice], RATE).model_set
            sig = [a[k][cmp_slice] for k in ("accel", "speed", "normal_force")]
            truth = compare_surface(rec.truth["surface"], *sig, RATE)
            for rule in INTERPOLATION_CHOICES:
                c = compare_surface(ms, *sig, RATE, CompareOptions(lookup={"interpolation": rule}))
                rows.setdefault((part, rule), []).append((c.power_ratio_db, c.lsd_db - truth.lsd_db, c.rms_correlation))
        print(f"seed {seed} done", flush=True)
    print(f"{opts.seeds} seeds x {opts.seconds:g} s, held-out = last {opts.holdout:g}; fitted sets render with outside: trend")
    table(rows)


def table(rows: dict) -> None:
    print(f"{'part':10} {'interpolation':14} {'power dB mean':>13} {'|worst|':>8} {'LSD-truth dB':>13} {'worst':>6} {'RMS corr':>9}")
    for (part, rule), vals in rows.items():
        v = np.array(vals)
        print(f"{part:10} {rule:14} {v[:, 0].mean():13.2f} {np.abs(v[:, 0]).max():8.2f} {v[:, 1].mean():13.2f} "
              f"{v[:, 1].max():6.2f} {v[:, 2].mean():9.3f}")


def resonant(seeds: int, seconds: float, order: tuple[int, int]) -> None:
    """The same table on flowtex.datasets.resonant recordings; held out = mean of two-fold CV (module docstring)."""
    from flowtex.datasets.resonant import textured_exploration
    from flowtex.fit.crossval import evaluate_splits, fold_splits
    from flowtex.fit.texture import TextureOptions

    opt = TextureOptions(order=order)
    rows: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    for seed in range(seeds):
        rec = textured_exploration(seconds, RATE, seed=seed)
        sig = [rec.arrays[k] for k in ("accel", "speed", "normal_force")]
        truth = compare_surface(rec.truth["surface"], *sig, RATE)
        ms = fit_texture(*sig, RATE, opt).model_set
        for rule in INTERPOLATION_CHOICES:
            ins = compare_surface(ms, *sig, RATE, CompareOptions(lookup={"interpolation": rule}))
            rows.setdefault(("in-sample", rule), []).append((ins.power_ratio_db, ins.lsd_db - truth.lsd_db, ins.rms_correlation))
            cs = evaluate_splits(*sig, RATE, fold_splits(sig[0].shape[0], RATE, 2), opt,
                                 compare=CompareOptions(lookup={"interpolation": rule})).comparisons
            rows.setdefault(("2-fold", rule), []).append((float(np.mean([c.power_ratio_db for c in cs])),
                                                           float(np.mean([c.lsd_db for c in cs])) - ins.lsd_db,
                                                           float(np.nanmean([np.nan if c.rms_correlation is None else c.rms_correlation
                                                                             for c in cs]))))
        print(f"seed {seed} done", flush=True)
    print(f"{seeds} resonant recordings x {seconds:g} s, order {order[0]},{order[1]}; fitted sets render with outside: trend; "
          "2-fold LSD column: mean fold LSD minus in-sample LSD")
    table(rows)


if __name__ == "__main__":
    main()
