"""fit_arma speed and accuracy against statsmodels, side by side in one process.

    python benchmarks/bench_fit_arma.py [--models 3] [--repeats 3] [--mle] [--auto]

For HaTT-size models (19/17, poles to r 0.985, MA zeros at |z| = 0.9999 near
z = -1; flowtex.datasets.model_sets.hatt_like_model), 10 s at 1 kHz of data from
scipy.signal.lfilter with a seeded RNG:

1. ``fit_arma(x, order=(19, 17))``: median wall time over repeats (after a
   warm-up call), and the LSD (dB) of its PSD against the true model's;
2. statsmodels ``ARIMA(x, order=(19, 0, 17)).fit(method="hannan_rissanen")``:
   time, LSD, and whether its model is stable and invertible;
3. with ``--mle``: statsmodels' exact-likelihood state-space MLE (the accuracy
   reference) once per model (slow: tens of seconds each);
4. with ``--auto``: ``fit_arma(x)`` with the automatic order (p, q <= 20):
   time, chosen order, LSD.

Prints ratios statsmodels / ours. No assertions (tests/fit/test_arma_fit.py
checks the accuracy). The machine is shared: quote ``uptime`` with the numbers.
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np
import scipy.signal

from flowtex.datasets.model_sets import hatt_like_model
from flowtex.dsp.arma import arma_psd
from flowtex.dsp.spectral import lsd_db
from flowtex.fit import fit_arma

FS = 1000.0
FREQS = np.linspace(0.0, FS / 2, 2049)


def _lsd(ar, ma, var, a, c) -> float:
    return lsd_db(arma_psd(ar, ma, 1.0, var, FREQS, FS), arma_psd(a, c, 1.0, 1.0, FREQS, FS), FREQS)


def _timed(fn, repeats: int):
    """(result, median wall seconds, median CPU seconds of this process) after one warm-up call.

    CPU time is what a quiet machine would show as wall time (single-threaded work); on the shared machine the wall
    time is several times larger when other jobs run.
    """
    out = fn()
    times = []
    cpu = []
    for _ in range(repeats):
        t = time.perf_counter()
        c = time.process_time()
        out = fn()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return out, statistics.median(times), statistics.median(cpu)


def _sm_model(res):
    ar = np.r_[1.0, -np.asarray(res.arparams)]
    ma = np.r_[1.0, np.asarray(res.maparams)]
    return ar, ma, float(res.params[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--mle", action="store_true", help="also run statsmodels' exact MLE (slow)")
    ap.add_argument("--auto", action="store_true", help="also time the automatic order search")
    args = ap.parse_args()
    from statsmodels.tsa.arima.model import ARIMA

    warnings.simplefilter("ignore")
    rows = []
    for seed in range(args.models):
        a, c = hatt_like_model(seed)
        x = scipy.signal.lfilter(c, a, np.random.default_rng(1000 + seed).standard_normal(15000))[5000:]
        ours, t_ours, cpu_ours = _timed(lambda x=x: fit_arma(x, order=(19, 17)), args.repeats)
        lsd_ours = _lsd(ours.ar, ours.ma, ours.gain ** 2 * ours.variance, a, c)
        t = time.perf_counter()
        c0 = time.process_time()
        hr = ARIMA(x, order=(19, 0, 17), trend="n", enforce_stationarity=False, enforce_invertibility=False).fit(method="hannan_rissanen")
        t_hr = time.perf_counter() - t
        cpu_hr = time.process_time() - c0
        ar, ma, var = _sm_model(hr)
        stable = bool(np.all(np.abs(np.roots(ar)) < 1.0))
        invertible = bool(np.all(np.abs(np.roots(ma)) < 1.0))
        lsd_hr = _lsd(ar, ma, var, a, c) if stable else float("nan")  # an unstable model has no PSD
        row = {"seed": seed, "ours_ms": 1e3 * t_ours, "ours_cpu_ms": 1e3 * cpu_ours, "hr_cpu_ms": 1e3 * cpu_hr,
               "ours_lsd": lsd_ours, "hr_ms": 1e3 * t_hr, "hr_lsd": lsd_hr, "hr_stable": stable, "hr_invertible": invertible}
        if args.mle:
            t = time.perf_counter()
            mle = ARIMA(x, order=(19, 0, 17), trend="n").fit()
            row["mle_s"] = time.perf_counter() - t
            row["mle_lsd"] = _lsd(*_sm_model(mle), a, c)
        if args.auto:
            auto, t_auto, cpu_auto = _timed(lambda x=x: fit_arma(x, max_order=20), 1)
            row.update(auto_ms=1e3 * t_auto, auto_cpu_ms=1e3 * cpu_auto, auto_order=auto.order,
                       auto_lsd=_lsd(auto.ar, auto.ma, auto.gain ** 2 * auto.variance, a, c))
        rows.append(row)
        msg = (f"model {seed}: fit_arma(19,17) {row['ours_ms']:7.1f} ms (cpu {row['ours_cpu_ms']:5.1f}) LSD {lsd_ours:5.2f} dB"
               f" | statsmodels HR {row['hr_ms']:7.1f} ms (cpu {row['hr_cpu_ms']:6.1f}) LSD {lsd_hr:6.2f} dB stable={stable}"
               f" min-phase={invertible} | HR/ours wall {t_hr / t_ours:5.1f}x cpu {cpu_hr / cpu_ours:5.1f}x")
        if args.mle:
            msg += f" | MLE {row['mle_s']:.1f} s LSD {row['mle_lsd']:.2f} dB"
        if args.auto:
            msg += f" | auto {row['auto_ms']:.0f} ms (cpu {row['auto_cpu_ms']:.0f}) order {row['auto_order']} LSD {row['auto_lsd']:.2f} dB"
        print(msg, flush=True)
    print(f"median: fit_arma {statistics.median(r['ours_ms'] for r in rows):.1f} ms wall, "
          f"{statistics.median(r['ours_cpu_ms'] for r in rows):.1f} ms cpu (target <= 100 ms), "
          f"LSD {statistics.median(r['ours_lsd'] for r in rows):.2f} dB; statsmodels HR "
          f"{statistics.median(r['hr_ms'] for r in rows):.0f} ms, LSD {statistics.median(r['hr_lsd'] for r in rows):.2f} dB; "
          f"ratio wall {statistics.median(r['hr_ms'] / r['ours_ms'] for r in rows):.1f}x, "
          f"cpu {statistics.median(r['hr_cpu_ms'] / r['ours_cpu_ms'] for r in rows):.1f}x")
    if args.auto:
        print(f"automatic order: median {statistics.median(r['auto_ms'] for r in rows):.0f} ms wall, "
              f"{statistics.median(r['auto_cpu_ms'] for r in rows):.0f} ms cpu (target <= 1000 ms)")


if __name__ == "__main__":
    main()
