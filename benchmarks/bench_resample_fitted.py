"""`models resample` on surfaces fitted by flowtex itself from recordings that behave like real ones.

    python benchmarks/bench_resample_fitted.py [--seeds 0,1,2,3,4,5,6,7] [--rates 2000,500] [--densify 0]

For each seed: a 20-s recording of flowtex.datasets.resonant.textured_exploration (moving resonances, heavy tails,
loudness wandering by the second), fitted by flowtex.fit.texture.fit_texture with its defaults, then the fitted set
resampled by flowtex.fit.resample.resample_model_set to each rate, twice, side by side in this process:

* ``restarts``: the default (:func:`flowtex.fit.resample.with_restarts`: every attempt from the mapped start, then
  the same attempts again with up to RESTARTS more starts for a fit that stays off its band);
* ``single``: the previous method, one start per fit (RESTARTS set to 0 for the call).

Columns: seed, the fit's orders and models, rate, then for each method: models missing (LSD <= 0.5 dB, band power
within 2 %, <= 2 % above the old Nyquist, as the resampler measures them on the rendered models), worst LSD (dB),
the attempt it kept (extra order, edge, restarts) and CPU seconds per model (``time.process_time``: the figure that
does not depend on the machine's other load; quote ``uptime`` with it).
"""

from __future__ import annotations

import argparse
import time

import flowtex.fit.resample as resample
from flowtex.datasets.resonant import textured_exploration
from flowtex.fit.texture import fit_texture
from flowtex.models.densify import densify_set


def _run(ms, rate: float, restarts: bool) -> tuple[int, float, tuple, float]:
    saved = resample.RESTARTS
    resample.RESTARTS = saved if restarts else 0
    try:
        t = time.process_time()
        out = resample.resample_model_set(ms, rate)
        cpu = time.process_time() - t
    finally:
        resample.RESTARTS = saved
    info = out.metadata["resample"]
    return len(info["misses"]), info["worst_lsd_db"], (info["extra_order"], info["edge_lowpass"], info["fit_restarts"]), cpu / ms.num_models


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2,3,4,5,6,7")
    ap.add_argument("--rates", default="2000,500")
    ap.add_argument("--densify", type=int, default=0, help="edge-midpoint levels added first (models resample --densify N)")
    args = ap.parse_args()
    print("| seed | orders | models | rate Hz | restarts: missing, worst LSD, attempt, CPU s/model | single start: missing, "
          "worst LSD, attempt, CPU s/model |")
    print("|---|---|---|---|---|---|")
    for seed in (int(s) for s in args.seeds.split(",")):
        rec = textured_exploration(20, 1000, seed=seed).arrays
        ms = fit_texture(rec["accel"], rec["speed"], rec["normal_force"], 1000.0, None, f"seed {seed}", "generated").model_set
        if args.densify:
            ms = densify_set(ms, args.densify)
        for rate in (float(r) for r in args.rates.split(",")):
            cells = []
            for restarts in (True, False):
                miss, worst, attempt, cpu = _run(ms, rate, restarts)
                cells.append(f"{miss}, {worst:.2f}, {attempt}, {cpu:.3f}")
            print(f"| {seed} | {ms.ar_order}/{ms.ma_order} | {ms.num_models} | {rate:g} | {cells[0]} | {cells[1]} |", flush=True)


if __name__ == "__main__":
    main()
