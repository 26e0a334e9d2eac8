"""Texture-model upsampling (flowtex.dsp.arma_resample): accuracy, orders and time, against the previous method.

    python benchmarks/bench_model_resample.py [--seeds 30] [--ratios 2,2.5,4] [--cork] [--render]
    python benchmarks/bench_model_resample.py --corpus all [--hatt DIR] [--corpus-rates 2000,500] [--baseline-every N] [--table OUT.csv] [--between]

For HaTT-like 19/17 models (flowtex.datasets.model_sets.hatt_like_model: poles to
r = 0.985, an MA zero pair at 0.9999 near z = -1) at 1 kHz, side by side in one
process on the same models, for each target rate:

* ``new``: :func:`resample_arma_lsf` (default orders), measured as texture_lookup
  renders it: the polynomials rebuilt from the stored LSFs by lsf_to_poly;
* ``keep``: the same with ``keep_order=True`` (19/17 whatever the ratio);
* ``old``: the previous method, re-implemented here as it was: Whittle
  (prediction-error) Gauss-Newton at the same order on the target PSD with a
  1e-4 floor above the old Nyquist, from the mapped roots and from Yule-Walker,
  LSFs by min_phase_for_lsf + poly_to_lsf.

Columns: orders, max / median LSD (dB, flowtex.fit.resample.resample_quality:
up to 0.9 x the old Nyquist, frequencies within 40 dB of the peak), worst
band-power error, worst fraction of the power above the old Nyquist, mean / max
seconds per model. ``--cork``: resample_model_set on cork_like_model_set (45
models) 1 kHz -> 2 and 4 kHz. ``--render``: arma_lattice_block ns per tick at
the orders produced (the rendering cost of a higher order). ``--corpus``: the
test suite's model sets (the narrow-peak copper-like, rough and edge-resonance ones included) and, with
``--hatt DIR``, HaTT's published sets (never in the repository): seconds per model fit, wall and CPU (median
and worst, from the progress callback), fits done, orders, worst LSD, band-power error, power above the old
Nyquist, misses, and the LSD of the expected spectra along a path; ``--baseline-every N`` runs the previous
method beside it on every N-th set; ``--table`` writes every model's figures; ``--between`` measures the LSD at
vertices, edge midpoints and centroids; ``--densify 0,auto`` runs those densify modes side by side
(``models resample --densify``).
The machine is shared: quote ``uptime`` with the numbers, and prefer
the CPU seconds under load.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
import scipy.linalg

from flowtex.datasets.model_sets import hatt_like_model
from flowtex.dsp.arma import arma_psd
from flowtex.dsp.arma_estimate import whittle_refine
from flowtex.dsp.arma_resample import GRID, STOPBAND_FLOOR, _map_roots, _model_power_spectrum, resample_arma_lsf
from flowtex.dsp.lsf import is_valid_lsf, lsf_to_poly_new
from flowtex.dsp.lsf_roots import poly_to_lsf
from flowtex.fit.arma import min_phase_for_lsf
from flowtex.fit.resample import resample_quality

FS1 = 1000.0


def old_method(ar, ma, fs2):
    """The pre-change upsampling: Whittle fit at the same order (two starts), LSFs from the polynomials."""
    ratio = FS1 / fs2
    w = 2.0 * math.pi * np.arange(GRID // 2 + 1) / GRID
    f = w * fs2 / (2.0 * math.pi)
    f_lim = FS1 / 2
    shape = _model_power_spectrum(ar, ma, 2.0 * math.pi * np.minimum(f, f_lim) / FS1)
    T = np.where(f < f_lim, shape, STOPBAND_FLOOR * np.mean(shape[f < f_lim]))
    a1, c1, crit = whittle_refine(T, GRID, _map_roots(ar, ratio), _map_roots(ma, ratio), iterations=40, tol=1e-10)
    p = ar.shape[0] - 1
    r = np.fft.irfft(T, GRID)[:p + 1]
    a_yw = np.r_[1.0, scipy.linalg.solve_toeplitz(r[:-1], -r[1:])]
    a2, c2, crit2 = whittle_refine(T, GRID, a_yw, np.r_[1.0, np.zeros(ma.shape[0] - 1)], iterations=40, tol=1e-10)
    if crit2 < crit:
        a1, c1 = a2, c2
    band = f < 0.9 * f_lim
    v = (np.sum(shape[band]) / FS1) / (np.sum(_model_power_spectrum(a1, c1, w[band])) / fs2)
    a1, c1 = min_phase_for_lsf(a1), min_phase_for_lsf(c1)
    return poly_to_lsf(a1), poly_to_lsf(c1), v


def new_method(ar, ma, fs2, keep):
    _, _, la, lc, _, v = resample_arma_lsf(ar, ma, 1.0, 1.0, FS1, fs2, keep_order=keep)
    return la, lc, v


def quality(ar, ma, fs2, la, lc, v):
    """(LSD dB, |band-power error|, fraction of power above the old Nyquist, LSFs valid) of the rendered model."""
    a, c = lsf_to_poly_new(la), lsf_to_poly_new(lc)
    lsd, band = resample_quality(ar, ma, 1.0, 1.0, FS1, a, c, 1.0, v, fs2)
    fa = np.linspace(0.0, fs2 / 2, 200001)
    s = arma_psd(a, c, 1.0, v, fa, fs2)
    above = float(np.trapezoid(s[fa > FS1 / 2], fa[fa > FS1 / 2]) / np.trapezoid(s, fa))
    return lsd, abs(band), above, is_valid_lsf(la) and is_valid_lsf(lc), (len(la), len(lc))


def sweep(fs2: float, seeds: int, name: str) -> None:
    rows, times, orders = [], [], set()
    for s in range(seeds):
        ar, ma = hatt_like_model(s)
        t0 = time.perf_counter()
        la, lc, v = old_method(ar, ma, fs2) if name == "old" else new_method(ar, ma, fs2, name == "keep")
        times.append(time.perf_counter() - t0)
        lsd, band, above, ok, order = quality(ar, ma, fs2, la, lc, v)
        rows.append((lsd, band, above, ok))
        orders.add(order)
    r = np.array(rows, dtype=float)
    print(f"{fs2:7g} {name:<5} {'/'.join(map(str, sorted(orders)[0])):>6} {r[:, 0].max():8.3f} {np.median(r[:, 0]):8.3f} "
          f"{100 * r[:, 1].max():8.3f} {100 * r[:, 2].max():9.4f} {int(r[:, 3].sum()):>3}/{seeds:<3} "
          f"{statistics.mean(times):7.2f} {max(times):6.2f}", flush=True)


def cork(rates) -> None:
    from flowtex.datasets.model_sets import cork_like_model_set
    from flowtex.fit.resample import resample_model_set

    ms = cork_like_model_set()
    for rate in rates:
        t0 = time.perf_counter()
        out = resample_model_set(ms, rate)
        dt = time.perf_counter() - t0
        info = out.metadata["resample"]
        print(f"cork_like_model_set 1 kHz -> {rate:g} Hz: orders {info['from_order']} -> {info['to_order']}, worst LSD "
              f"{info['worst_lsd_db']:.3f} dB, worst band-power error {100 * info['worst_band_power_error']:.3f} %, "
              f"{dt / ms.num_models:.2f} s per model ({dt:.1f} s)", flush=True)


def corpus_sets(names):
    """The model sets the test suite resamples (tests/fit/test_arma_resample.py, test_resample_bounded.py, test_resample_render.py)."""
    from flowtex.datasets.model_sets import (
        cork_like_model_set,
        edge_resonance_model_set,
        hard_model_set,
        narrow_peak_model_set,
        rough_model_set,
        synthetic_model_set,
    )

    makers = {
        "grid8/6": lambda: synthetic_model_set([60.0, 150.0, 240.0], [0.5, 1.5, 2.5], ar_order=8, ma_order=6),
        "ar2": lambda: synthetic_model_set([60.0, 150.0], [0.5, 1.5], ar_order=2, ma_order=0),
        "hard12/10": lambda: hard_model_set(),
        "narrow6/6": lambda: narrow_peak_model_set(count=20, ar_order=6, ma_order=6, max_pole_radius=0.9995),
        "narrow20/20": lambda: narrow_peak_model_set(count=24, ar_order=20, ma_order=20, max_pole_radius=0.9995),
        "cork19/17": cork_like_model_set,
        "rough14/12": rough_model_set,
        "edge10/8": edge_resonance_model_set,
    }
    return [(n, makers[n]()) for n in names]


BASELINE_ATTEMPTS = tuple((e, False) for e in (0, 2, 4, 6, 8))
"""The previous rule up to 2x (before the elliptic edge): more free poles and zeros, 0 to 8, for the whole set."""

BASELINE_GRID = (2000, 1000)
"""The previous fit grid (BAND_POINTS, STOP_POINTS of flowtex.dsp.arma_resample)."""


def hatt_sets(folder: str, every: int = 1, start: int = 0):
    """(name, set) of HaTT's published sets in ``folder`` (Models_*.xml; never in the repository), every ``every``-th from ``start``."""
    import glob
    import os

    from flowtex.io.modelset import load_model_set

    files = sorted(glob.glob(os.path.join(folder, "Models_*.xml")))[start::every]
    return [(os.path.basename(f)[7:-4], load_model_set(f)) for f in files]


def corpus(sets, rates, baseline_every: int, table: str | None, densify: tuple = (0,)) -> None:
    """Seconds per model fit (median, worst; wall and CPU) of resample_model_set on each set, against the previous rule.

    ``baseline_every`` > 0: every that many sets, also the previous method when upsampling (the attempt ladder
    :data:`BASELINE_ATTEMPTS` on the fit grid :data:`BASELINE_GRID`), side by side in this process (with the
    first ``densify`` mode only).
    ``table``: a CSV of every model's figures (set, rate, rule, model, LSD dB, band-power error, power above
    the old Nyquist). "path LSD": flowtex.fit.quality.path_lsd_db along
    lissajous_path, the resampled set against the original (expected spectra as rendered, no noise); "paths":
    the worst over flowtex.fit.resample_densify.CHECK_PATHS.
    ``densify``: the modes run side by side for each set and rate (flowtex.fit.resample_densify.resample_densified:
    0..3 levels or "auto"); "models" counts the densified set's, "set s/model" is the set's time over the
    original's models, "ratio" its time over the first mode's.
    """
    import flowtex.dsp.arma_resample as arma_resample
    import flowtex.fit.resample as resample
    from flowtex.datasets.model_sets import synthetic_model_set
    from flowtex.fit.quality import lissajous_path, path_lsd_db
    from flowtex.fit.resample_densify import CHECK_PATHS, resample_densified

    resample.resample_model_set(synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2), 2000.0)  # warm-up: imports
    print(f"{'set':<22} {'to Hz':>6} {'rule':<9} {'models':>6} {'fits':>5} {'orders':>11} {'LSD max':>8} {'band %':>7} "
          f"{'above %':>7} {'misses':>6} {'wall s/fit med':>14} {'worst':>6} {'cpu s/fit med':>13} {'worst':>6} "
          f"{'set s/model':>11} {'cpu':>6} {'ratio':>6} {'path LSD':>8} {'paths':>6}", flush=True)
    summary = {}
    if table:
        with open(table, "w") as fh:
            fh.write("set,to_hz,rule,model,lsd_db,band_power_error,power_above_old_nyquist\n")
    for k, (name, original) in enumerate(sets):
        walks = [lissajous_path(original, cycles=c, phase=ph) for c, ph in CHECK_PATHS]
        for rate in rates:
            base = None
            grid = (arma_resample.BAND_POINTS, arma_resample.STOP_POINTS)
            rules = [(f"new d{mode}", mode, resample.EDGE_ATTEMPTS, grid) for mode in densify]
            if baseline_every and k % baseline_every == 0 and rate > original.sample_rate:
                rules.append(("old", densify[0], BASELINE_ATTEMPTS, BASELINE_GRID))
            for rule, mode, attempts, (band_points, stop_points) in rules:
                saved = resample.EDGE_ATTEMPTS
                resample.EDGE_ATTEMPTS = attempts
                arma_resample.BAND_POINTS, arma_resample.STOP_POINTS = band_points, stop_points
                wall, cpu = [time.perf_counter()], [time.process_time()]

                def tick(done, total, wall=wall, cpu=cpu):
                    wall.append(time.perf_counter())
                    cpu.append(time.process_time())
                try:
                    ms, out = resample_densified(original, rate, mode, progress=tick)
                finally:
                    resample.EDGE_ATTEMPTS = saved
                    arma_resample.BAND_POINTS, arma_resample.STOP_POINTS = grid
                end, end_cpu = time.perf_counter(), time.process_time()
                per, per_cpu = np.diff(wall), np.diff(cpu)
                total, total_cpu = end - wall[0], end_cpu - cpu[0]
                base = base or total_cpu
                info = out.metadata["resample"]
                q = info["quality"]
                path = path_lsd_db(original, out, *walks[0])
                paths = max([path] + [path_lsd_db(original, out, *w) for w in walks[1:]])
                summary.setdefault((rule, rate), []).append((per, per_cpu, total / original.num_models, len(info["misses"]), path,
                                                             paths, ms.num_models - original.num_models, original.num_models,
                                                             total_cpu / original.num_models, name))
                orders = f"{info['from_order'][0]}/{info['from_order'][1]}->{info['to_order'][0]}/{info['to_order'][1]}"
                print(f"{name[:22]:<22} {rate:6g} {rule:<9} {ms.num_models:6d} {per.size:5d} {orders:>11} "
                      f"{info['worst_lsd_db']:8.3f} {100 * info['worst_band_power_error']:7.3f} "
                      f"{100 * info['worst_power_above_old_nyquist']:7.3f} {len(info['misses']):6d} {np.median(per):14.3f} "
                      f"{per.max():6.2f} {np.median(per_cpu):13.3f} {per_cpu.max():6.2f} {total / original.num_models:11.3f} "
                      f"{total_cpu / original.num_models:6.3f} {total_cpu / base:6.2f} {path:8.3f} {paths:6.3f}", flush=True)
                if table:  # appended set by set: a run stopped early keeps what it measured
                    with open(table, "a") as fh:
                        fh.writelines(",".join(str(x) for x in (name, rate, rule, m, *q[m])) + "\n" for m in range(ms.num_models))
    for (rule, rate), items in sorted(summary.items()):
        per = np.concatenate([i[0] for i in items])
        per_cpu = np.concatenate([i[1] for i in items])
        set_avg = np.array([i[2] for i in items])
        set_cpu = np.array([i[8] for i in items])
        path = np.array([i[4] for i in items])
        paths = np.array([i[5] for i in items])
        worst = items[int(np.argmax(path))]
        print(f"all {rule} -> {rate:g} Hz: {len(items)} sets, {sum(i[7] for i in items)} models + {sum(i[6] for i in items)} added "
              f"({sum(i[6] > 0 for i in items)} sets densified), {per.size} fits, {sum(i[3] for i in items)} models missing; "
              f"s per fit median {np.median(per):.3f} worst {per.max():.2f} (CPU {np.median(per_cpu):.3f} / {per_cpu.max():.2f}); "
              f"set seconds per model median {np.median(set_avg):.3f} worst {set_avg.max():.2f} "
              f"(CPU {np.median(set_cpu):.3f} / {set_cpu.max():.2f}); path LSD median {np.median(path):.3f} "
              f"worst {path.max():.3f} dB ({worst[9]}), {int(np.sum(path > 0.5))} over 0.5; "
              f"check paths worst {paths.max():.3f} dB, {int(np.sum(paths > 0.5))} over 0.5", flush=True)


def between(sets, rate: float) -> None:
    """LSD (dB) between the original and the resampled set's models at the vertices, edge midpoints and centroids.

    The models texture_lookup builds there (flowtex.fit.quality.models_at), over triangles whose three models
    sound: at a vertex each resampled model is fitted to its original; between vertices both sets blend LSFs,
    and resampling need not commute with that blend. Up to 0.9 x the lower Nyquist.
    """
    from flowtex.dsp.spectral import lsd_db
    from flowtex.fit.quality import models_at
    from flowtex.fit.resample import resample_model_set

    f = np.linspace(15.0, 0.45 * min(1000.0, rate), 3000)
    for name, ms in sets:
        out = resample_model_set(ms, rate)
        live = ms.variance > 0
        tri = ms.triangles[np.all(live[ms.triangles], axis=1)]
        pts = np.column_stack([ms.speeds, ms.forces])
        places = {"vertices": pts[live], "edge midpoints": 0.5 * (pts[tri[:, 0]] + pts[tri[:, 1]]),
                  "centroids": pts[tri].mean(axis=1)}
        for label, p in places.items():
            lsd = np.array([lsd_db(arma_psd(a2, c2, g2, v2, f, rate), arma_psd(a1, c1, g1, v1, f, ms.sample_rate), f)
                            for (a1, c1, g1, v1), (a2, c2, g2, v2)
                            in zip(models_at(ms, p[:, 0], p[:, 1]), models_at(out, p[:, 0], p[:, 1]), strict=True)])
            print(f"{name:<22} {rate:6g} {label:<15} {lsd.size:4d} points: LSD median {np.median(lsd):.3f} "
                  f"worst {lsd.max():.3f} dB", flush=True)


def render(orders) -> None:
    from flowtex.dsp.arma import arma_lattice_block, new_state
    from flowtex.dsp.rng import seed_rng

    n = 200_000
    base = None
    for p, q in orders:
        ar, ma = hatt_like_model(1, p, q, max_pole_radius=0.9)
        A = np.repeat(ar[None, :], n, axis=0)
        C = np.repeat(ma[None, :], n, axis=0)
        g = np.ones((n, 1))
        y = np.empty((n, 1))
        best = math.inf
        for _ in range(4):
            s, si = new_state(p, q)
            seed_rng(si, s[0:1], np.random.SeedSequence(1))
            t0 = time.perf_counter()
            arma_lattice_block(s, si, A, C, g, g, y)
            best = min(best, time.perf_counter() - t0)
        ns = 1e9 * best / n
        base = base or ns
        print(f"arma_lattice_block {p}/{q}: {ns:.1f} ns per tick ({ns / base:.2f}x of {orders[0][0]}/{orders[0][1]})", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--ratios", default="2,2.5,4", help="target rate / 1 kHz, comma-separated")
    ap.add_argument("--methods", default="new,keep,old")
    ap.add_argument("--cork", action="store_true")
    ap.add_argument("--render", action="store_true")
    ap.add_argument("--corpus", metavar="SETS", help="comma-separated corpus sets (grid8/6, ar2, hard12/10, narrow6/6, narrow20/20, "
                                                       "cork19/17, rough14/12, edge10/8) or 'all': seconds per model at --corpus-rates, then exit")
    ap.add_argument("--corpus-rates", default="2000,500")
    ap.add_argument("--hatt", metavar="DIR", help="with --corpus: HaTT's Models_*.xml in DIR instead of (or, with --corpus SETS, "
                                                  "after) the generated sets; never committed")
    ap.add_argument("--hatt-every", type=int, default=1, help="every N-th HaTT set only")
    ap.add_argument("--hatt-start", type=int, default=0, help="from the K-th (0-based; with --hatt-every: run parts in parallel)")
    ap.add_argument("--hatt-reverse", action="store_true", help="the HaTT sets in reverse order (a second worker from the end)")
    ap.add_argument("--baseline-every", type=int, default=0, metavar="N",
                    help="with --corpus: the previous attempt ladder too, on every N-th set (ratio column)")
    ap.add_argument("--table", metavar="OUT.csv", help="with --corpus: every model's LSD, band-power error and power above")
    ap.add_argument("--densify", default="0", metavar="MODES",
                    help="with --corpus: comma-separated densify modes run side by side (0..3 or auto: models resample "
                         "--densify), e.g. 0,auto")
    ap.add_argument("--between", action="store_true",
                    help="with --corpus/--hatt: LSD at vertices, edge midpoints and centroids instead (first --corpus-rates)")
    args = ap.parse_args()
    if args.corpus or args.hatt:
        names = ["grid8/6", "ar2", "hard12/10", "narrow6/6", "narrow20/20", "cork19/17", "rough14/12", "edge10/8"] \
            if args.corpus == "all" \
            else args.corpus.split(",") if args.corpus else []
        sets = corpus_sets(names) + (hatt_sets(args.hatt, args.hatt_every, args.hatt_start)[::-1 if args.hatt_reverse else 1] if args.hatt else [])
        if args.between:
            between(sets, float(args.corpus_rates.split(",")[0]))
            return
        modes = tuple(m if m == "auto" else int(m) for m in args.densify.split(","))
        corpus(sets, [float(r) for r in args.corpus_rates.split(",")], args.baseline_every, args.table, modes)
        return
    print(f"hatt_like_model seeds 0..{args.seeds - 1}, 19/17 at 1 kHz; LSD and powers of the model rebuilt from its LSFs")
    print(f"{'to Hz':>7} {'meth':<5} {'orders':>6} {'LSD max':>8} {'LSD med':>8} {'band %':>8} {'above %':>9} {'LSF ok':>7} "
          f"{'s mean':>7} {'s max':>6}")
    for ratio in (float(x) for x in args.ratios.split(",")):
        for name in args.methods.split(","):
            sweep(ratio * FS1, args.seeds, name)
    if args.cork:
        cork([2000.0, 4000.0])
    if args.render:
        render([(19, 17), (38, 42)])


if __name__ == "__main__":
    main()
