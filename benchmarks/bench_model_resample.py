"""Texture-model upsampling (flowtex.dsp.arma_resample): accuracy, orders and time, against the previous method.

    python benchmarks/bench_model_resample.py [--seeds 30] [--ratios 2,2.5,4] [--cork] [--render]
    python benchmarks/bench_model_resample.py --corpus all [--corpus-rates 2000,4000] [--baseline]

For HaTT-like 19/17 models (flowtex.models.synthetic.hatt_like_model: poles to
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
test suite's model sets (the narrow-peak copper-like ones included), seconds per
model fit (median and worst, from the progress callback), fits done, extra order,
worst LSD and misses; ``--baseline`` runs the previous stopping rule of the
log-spectral fit (1e-6 relative, 1e-3 dB, no evaluation budget) beside it. The
machine is shared: quote ``uptime`` with the numbers.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
import scipy.linalg

from flowtex.dsp.arma import arma_psd
from flowtex.dsp.arma_estimate import whittle_refine
from flowtex.dsp.arma_resample import GRID, STOPBAND_FLOOR, _map_roots, _model_power_spectrum, resample_arma_lsf
from flowtex.dsp.lsf import is_valid_lsf, lsf_to_poly_new, poly_to_lsf
from flowtex.fit.arma import min_phase_for_lsf
from flowtex.fit.resample import resample_quality
from flowtex.models.synthetic import hatt_like_model

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
    from flowtex.fit.resample import resample_model_set
    from flowtex.models.synthetic import cork_like_model_set

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
    from flowtex.models.synthetic import cork_like_model_set, hard_model_set, narrow_peak_model_set, synthetic_model_set

    makers = {
        "grid8/6": lambda: synthetic_model_set([60.0, 150.0, 240.0], [0.5, 1.5, 2.5], ar_order=8, ma_order=6),
        "ar2": lambda: synthetic_model_set([60.0, 150.0], [0.5, 1.5], ar_order=2, ma_order=0),
        "hard12/10": lambda: hard_model_set(),
        "narrow6/6": lambda: narrow_peak_model_set(count=20, ar_order=6, ma_order=6, max_pole_radius=0.9995),
        "narrow20/20": lambda: narrow_peak_model_set(count=24, ar_order=20, ma_order=20, max_pole_radius=0.9995),
        "cork19/17": cork_like_model_set,
    }
    return [(n, makers[n]()) for n in names]


def corpus(names, rates, baseline: bool) -> None:
    """Seconds per model fit (median, worst) of resample_model_set on each corpus set, new stopping rule vs the old one."""
    import flowtex.dsp.arma_logfit as logfit
    from flowtex.fit.resample import resample_model_set
    from flowtex.models.synthetic import synthetic_model_set

    resample_model_set(synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2), 2000.0)  # warm-up: numba compiles, imports
    rules = [("new", {})] + ([("old", {"EVALUATIONS": 10**9, "REL_TOL": 1e-6, "GOOD_DB": 1e-3})] if baseline else [])
    print(f"{'set':<12} {'to Hz':>6} {'rule':<4} {'models':>6} {'fits':>5} {'extra':>5} {'LSD max':>8} {'misses':>6} "
          f"{'s/model med':>11} {'worst':>6} {'total s':>8} {'ratio':>6}")
    for name, ms in corpus_sets(names):
        for rate in rates:
            base = None
            for rule, params in rules:
                saved = {k: getattr(logfit, k) for k in params}
                for k, v in params.items():
                    setattr(logfit, k, v)
                stamps = [time.perf_counter()]
                try:
                    out = resample_model_set(ms, rate, progress=lambda d, t, st=stamps: st.append(time.perf_counter()))
                finally:
                    for k, v in saved.items():
                        setattr(logfit, k, v)
                per = np.diff(stamps)
                total = stamps[-1] - stamps[0]
                base = base or total
                info = out.metadata["resample"]
                print(f"{name:<12} {rate:6g} {rule:<4} {ms.num_models:6d} {per.size:5d} {info['extra_order']:5d} "
                      f"{info['worst_lsd_db']:8.3f} {len(info['misses']):6d} {np.median(per):11.3f} {per.max():6.2f} "
                      f"{total:8.1f} {total / base:6.2f}", flush=True)


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
                                                       "cork19/17) or 'all': seconds per model at --corpus-rates, then exit")
    ap.add_argument("--corpus-rates", default="2000,4000")
    ap.add_argument("--baseline", action="store_true", help="with --corpus: also the previous stopping rule (ratio column)")
    args = ap.parse_args()
    if args.corpus:
        names = ["grid8/6", "ar2", "hard12/10", "narrow6/6", "narrow20/20", "cork19/17"] if args.corpus == "all" \
            else args.corpus.split(",")
        corpus(names, [float(r) for r in args.corpus_rates.split(",")], args.baseline)
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
