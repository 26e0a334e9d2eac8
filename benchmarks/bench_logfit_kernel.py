"""`models resample` with the compiled log-spectrum kernel against the numpy version it replaced, side by side.

    python benchmarks/bench_logfit_kernel.py [--seeds 0,1,2] [--rate 2000]

flowtex.dsp.arma_logfit.log_spectrum_db (the model dB spectrum and its Jacobian, evaluated hundreds of times per
fitted model) is one compiled pass over the roots. The baseline below is the numpy formulation it replaced (an array
per operation over frequencies x roots), swapped in for the same calls. For each seed: a 20-s recording of
flowtex.datasets.resonant.textured_exploration fitted with flowtex.fit.texture.fit_texture's defaults, then
resample_model_set to ``--rate`` with each version. Columns: CPU seconds per model (``time.process_time``, the figure
that does not depend on the machine's other load), their ratio, and what each result is worth: models missing their
target and the worst LSD (dB) as the resampler measures them. The two differ in the last bits of every evaluation,
so Levenberg-Marquardt may take another path to a fit of the same quality.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import flowtex.dsp.arma_logfit as logfit
from flowtex.datasets.resonant import textured_exploration
from flowtex.fit.resample import resample_model_set
from flowtex.fit.texture import fit_texture

DB = 10.0 / math.log(10.0)


def numpy_log_spectrum_db(w, x, lay, jac=False, cs=None):
    """The numpy formulation (one array per operation) that the compiled kernel replaced."""
    cw, sw = cs if cs is not None else (np.cos(w), np.sin(w))
    s = np.full(w.shape[0], x[0])
    J = np.zeros((w.shape[0], lay.size)) if jac else None
    if jac:
        J[:, 0] = 1.0
    for sign, p0, r0, end in ((1.0, lay.zp, lay.zr, lay.pp), (-1.0, lay.pp, lay.pr, lay.size)):
        u, theta = x[p0:r0:2], x[p0 + 1:r0:2]
        if u.shape[0]:
            r, ct, st = -np.expm1(u), np.cos(theta), np.sin(theta)
            a, b = cw[:, None] * ct, sw[:, None] * st
            cm, cp = a + b, a - b
            dm, dp = 1.0 - 2.0 * r * cm + r * r, 1.0 - 2.0 * r * cp + r * r
            s += sign * (DB * np.log(dm * dp)).sum(axis=1)
            if jac:
                dr = DB * ((2.0 * r - 2.0 * cm) / dm + (2.0 * r - 2.0 * cp) / dp)
                c, d = sw[:, None] * ct, cw[:, None] * st
                J[:, p0:r0:2] = sign * dr * (r - 1.0)
                J[:, p0 + 1:r0:2] = sign * DB * 2.0 * r * ((c + d) / dp - (c - d) / dm)
        if end > r0:
            xr = x[r0:end][None, :]
            d = 1.0 - 2.0 * xr * cw[:, None] + xr ** 2
            s += sign * (DB * np.log(d)).sum(axis=1)
            if jac:
                J[:, r0:end] = sign * DB * (2.0 * xr - 2.0 * cw[:, None]) / d
    return s, J


def _run(ms, rate: float) -> tuple[float, int, float]:
    t = time.process_time()
    out = resample_model_set(ms, rate)
    cpu = time.process_time() - t
    info = out.metadata["resample"]
    return cpu / ms.num_models, len(info["misses"]), info["worst_lsd_db"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--rate", type=float, default=2000.0)
    args = ap.parse_args()
    compiled = logfit.log_spectrum_db
    print("| seed | models | compiled: CPU s/model, missing, worst LSD dB | numpy: CPU s/model, missing, worst LSD dB | "
          "numpy / compiled |")
    print("|---|---|---|---|---|")
    _run(fit_texture(*(textured_exploration(4, 1000, seed=99).arrays[k] for k in ("accel", "speed", "normal_force")),
                     1000.0, None, "warm-up", "generated").model_set, args.rate)  # compile and load once, outside the timing
    for seed in (int(s) for s in args.seeds.split(",")):
        rec = textured_exploration(20, 1000, seed=seed).arrays
        ms = fit_texture(rec["accel"], rec["speed"], rec["normal_force"], 1000.0, None, f"seed {seed}", "generated").model_set
        fast = _run(ms, args.rate)
        logfit.log_spectrum_db = numpy_log_spectrum_db
        try:
            slow = _run(ms, args.rate)
        finally:
            logfit.log_spectrum_db = compiled
        print(f"| {seed} | {ms.num_models} | {fast[0]:.3f}, {fast[1]}, {fast[2]:.3f} | {slow[0]:.3f}, {slow[1]}, "
              f"{slow[2]:.3f} | {slow[0] / fast[0]:.2f} |")


if __name__ == "__main__":
    main()
