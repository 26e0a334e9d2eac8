"""`fit friction` with a residual scale that grows with the force, against the one-scale fit, side by side.

    python benchmarks/bench_friction_noise.py [--seconds 20,200] [--seed 3]

For each length: a drag of flowtex.datasets.dragging.stiction_drag (t5 noise growing with the force, 5 % drift,
20 stiction spikes per 20 s) fitted by flowtex.fit.friction.fit_friction with ``noise="force"`` (the default) and
``noise="constant"`` (the one-scale fit), then the scale function's median regression of the last cycle solved by
flowtex.dsp.hetero.median_regression (IRLS) and by the least-absolute-deviations linear programme it replaced (the
dual, scipy's HiGHS). Columns: CPU seconds (``time.process_time``: the figure that depends least on the machine's
other load), their ratio, and what each result is worth: mu and its error, the rejected share and the share of
planted spike samples; for the median regression, the sums of absolute residuals (equal at the optimum).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import linprog

from flowtex.datasets.dragging import stiction_drag
from flowtex.dsp.hetero import median_regression
from flowtex.dsp.robust import irls_line
from flowtex.fit.friction import fit_friction


def timed(fn, *args, **kwargs):
    start = time.process_time()
    out = fn(*args, **kwargs)
    return out, time.process_time() - start


def lp_median_regression(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The linear programme median_regression replaced: max b'd subject to A'd = 0, -1 <= d <= 1."""
    res = linprog(-b, A_eq=A.T, b_eq=np.zeros(A.shape[1]), bounds=(-1.0, 1.0), method="highs")
    return -np.asarray(res.eqlin.marginals, float)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", default="20,200")
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args()
    print(f"{'s':>5} {'fit':>9} {'CPU s':>7} {'ratio':>6} {'mu':>8} {'err':>8} {'rejected %':>10} {'planted %':>9}")
    for seconds in (float(v) for v in args.seconds.split(",")):
        rec = stiction_drag(duration_s=seconds, seed=args.seed, spikes=int(round(seconds)))
        n, t = rec.arrays["normal_force"], rec.arrays["tangential_force"]
        spike = rec.truth["spike_mask"]
        rows = {}
        for noise in ("constant", "force"):
            rows[noise] = timed(fit_friction, n, t, noise=noise)
        base = rows["constant"][1]
        for noise, (fit, cpu) in rows.items():
            print(f"{seconds:5.0f} {noise:>9} {cpu:7.2f} {cpu / base:6.1f} {fit.mu:8.5f} {fit.mu - rec.truth['mu']:+8.5f} "
                  f"{100 * fit.rejected_share:10.2f} {100 * spike.mean():9.2f}")
        line = irls_line(n, t)
        r = np.abs(t - line.slope * n)
        lx = np.log(n / np.median(n))
        A = np.vander(lx / np.max(np.abs(lx)), 2, increasing=True)
        b = np.log(np.maximum(r, 1e-12 * r.max()))
        ours, cpu_ours = timed(median_regression, A, b)
        lp, cpu_lp = timed(lp_median_regression, A, b)
        print(f"{seconds:5.0f} median regression: IRLS {cpu_ours:.2f} s, LP {cpu_lp:.2f} s (x {cpu_lp / cpu_ours:.1f}); "
              f"sum |r| {np.sum(np.abs(b - A @ ours)):.6f} vs {np.sum(np.abs(b - A @ lp)):.6f}")


if __name__ == "__main__":
    main()
