"""Evaluating model sets along paths (flowtex.fit.quality), this tree against a baseline tree, side by side.

    python benchmarks/bench_fit_quality.py [--baseline main] [--rounds 3]

What the resampling and fit tests (and ``models resample --densify auto``) spend outside the fits themselves:
a fresh lookup state per point (``initial_state``, which binds the state's declared layout), the models
``texture_lookup`` renders along a path (``models_at``), the PSD of each (``arma_psd``) and the path LSD
(``path_lsd_db``, ``point_lsds``). The baseline is the git revision ``--baseline`` exported to a temporary
folder (bench_compile.alternating_json); each figure is the CPU time (``time.process_time``) of one process, the
processes alternating between the two trees (baseline, this, baseline, ...) so that a change of load on a shared
machine hits both alike. Each process also prints a SHA-256 of every result it computed: the two trees must
agree bit for bit (the script exits with an error otherwise).
"""

from __future__ import annotations

import argparse

from bench_compile import alternating_json

WORK = """
import hashlib, json, time
import numpy as np
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.dsp.arma import arma_psd
from flowtex.dsp.interp import initial_state
from flowtex.fit.quality import lissajous_path, models_at, path_lsd_db, set_lsd_db
from flowtex.fit.resample import resample_model_set
from flowtex.fit.resample_densify import CHECK_PATHS, point_lsds

ms = synthetic_model_set(np.array([60.0, 150.0, 240.0]), np.array([0.5, 1.5, 2.5]), ar_order=19, ma_order=17)
out = resample_model_set(ms, 500.0)          # untimed: the fits are not what is measured
models_at(ms, [1.0], [1.0])                  # untimed: kernels loaded from the cache
h, t = hashlib.sha256(), {}
t0 = time.process_time()
for _ in range(20000):
    s, si = initial_state(19, 17)
t["initial_state x 20000"] = time.process_time() - t0
h.update(s.tobytes() + si.tobytes())
rng = np.random.default_rng(0)
sp, fo = rng.uniform(0, 1.1 * ms.max_speed, 300), rng.uniform(0, 1.1 * ms.max_force, 300)
t0 = time.process_time()
models = models_at(ms, sp, fo)
t["models_at, 300 points"] = time.process_time() - t0
f = np.linspace(1.0, 499.0, 400)
t0 = time.process_time()
for a, c, g, v in models:
    h.update(arma_psd(a, c, g, v, f, 1000.0).tobytes())
t["arma_psd x 300 (unchanged)"] = time.process_time() - t0
t0 = time.process_time()
for cycles, phase in CHECK_PATHS + (((5.0, 7.0), 0.0), ((2.2, 9.5), 1.7)):
    h.update(np.float64(path_lsd_db(ms, out, *lissajous_path(ms, cycles=cycles, phase=phase))).tobytes())
t["path_lsd_db, %d paths of 300 points" % (len(CHECK_PATHS) + 2)] = time.process_time() - t0
t0 = time.process_time()
h.update(point_lsds(ms, out, sp, fo).tobytes())
h.update(set_lsd_db(out, ms, sp, fo).tobytes())
t["point_lsds + set_lsd_db, 300 points"] = time.process_time() - t0
print(json.dumps({"times": t, "sha256": h.hexdigest()}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="main", help="git revision to compare with (default: main)")
    ap.add_argument("--rounds", type=int, default=3, help="processes per tree")
    args = ap.parse_args()
    got = alternating_json(args.baseline, args.rounds, WORK, warm=True)
    hashes = {r["sha256"] for rows in got.values() for r in rows}
    print(f"results bit-identical: {len(hashes) == 1}")
    print(f"{'CPU s (median of ' + str(args.rounds) + ')':44s} {'baseline':>9s} {'this':>9s} {'ratio':>7s}")
    for name in got["baseline"][0]["times"]:
        b, n = (sorted(r["times"][name] for r in got[label])[args.rounds // 2] for label in ("baseline", "this"))
        print(f"{name:44s} {b:9.3f} {n:9.3f} {n / b:7.2f}")
    if len(hashes) != 1:
        raise SystemExit("the two trees computed different results")


if __name__ == "__main__":
    main()
