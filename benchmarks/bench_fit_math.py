"""The fitting math of flowtex.dsp against the formulations it replaced, side by side in one process.

    python benchmarks/bench_fit_math.py [--rounds 3] [--seconds 20] [--skip-commands]

What changed, and the baseline each figure is measured against (the old formulation, defined below and swapped in
for the same calls):

- ``poly.power_spectrum`` (every model spectrum: ``arma_psd``, ``arma_psd_rows`` along a path, the resampler's
  checks, GFC): numpy's ``polyval`` over complex z (one array operation per coefficient) and |.| by ``hypot``,
  now one compiled pass per coefficient over the frequencies in real arithmetic.
- ``poly.step_down`` / ``roots_inside`` (the stability test of every ``stabilize``, i.e. of every Whittle step):
  one numpy operation per order, now compiled (the same operations in the same order).
- ``hetero.median_regression``: the median of |r| every iteration for the weights' floor, now only when the floor
  can change a weight (the same weights).
- ``io.figures.save_png`` (the report figures): matplotlib's ``savefig`` of a figure with its layout engine (a pass
  without output that lays it out, then the drawing), now the engine run once and one drawing (the same pixels).

Part 1, each function alone at the sizes the fits use: CPU per call (``time.process_time``, best of ``--rounds``),
the ratio, and whether the new values are the old ones bit for bit (the models' poles and zeros reach 1 - 1e-4 of
the unit circle; the error of both against an extended-precision evaluation is tests/dsp/test_poly.py's).
Part 2, the commands in this process (``flowtex.cli.main``) on generated recordings (``--seconds`` long; a
textured exploration and a friction session), old and new alternating ``--rounds`` times: CPU seconds (median),
the ratio, and the largest relative difference between the numbers the two write (model sets, compare --json,
friction file). The first round of each is a warm-up (numba compiles or cache loads), not counted.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from baseline import cpu_per_call, swapped  # a script beside this one

import flowtex.dsp.anti_imaging as anti_imaging
import flowtex.dsp.arma_estimate as arma_estimate
import flowtex.dsp.arma_resample as arma_resample
import flowtex.dsp.hetero as hetero
import flowtex.dsp.order as order
import flowtex.dsp.poly as poly
import flowtex.fit.compare_report as compare_report
import flowtex.fit.report as report
from flowtex.cli.main import main as flowtex_main

MIN_S = 0.2
"""CPU seconds each round of a function's timing repeats it for at least."""


def numpy_power_spectrum(ar, ma, w):
    """The numpy formulation of power_spectrum that the compiled kernel replaced."""
    z = np.exp(-1j * np.asarray(w, dtype=np.float64))
    num = np.polynomial.polynomial.polyval(z, np.asarray(ma, dtype=np.float64).T)
    den = np.polynomial.polynomial.polyval(z, np.asarray(ar, dtype=np.float64).T)
    return np.abs(num) ** 2 / np.abs(den) ** 2


def numpy_step_down(a, order_):
    """The numpy step-down that the compiled recursion replaced."""
    a = np.asarray(a, dtype=np.float64).copy()
    for m in range(a.shape[0] - 1, order_, -1):
        k = a[m]
        if not abs(k) < 1.0:
            raise ValueError(f"polynomial is not minimum phase (reflection coefficient {k:.6g} at order {m})")
        a = (a[:m] - k * a[m:0:-1]) / (1.0 - k * k)
    return a


def numpy_roots_inside(p, radius=1.0):
    """roots_inside over the numpy step-down, as it was."""
    p = np.asarray(p, dtype=np.float64)
    try:
        numpy_step_down(p / p[0] / (radius ** np.arange(p.shape[0])), 0)
    except ValueError:
        return False
    return True


def median_floored(r):
    """The weights' floor as it was: the median of |r| taken every iteration."""
    return np.maximum(r, 1e-9 * max(float(np.median(r)), 1e-300))


def savefig_png(fig, path, dpi=100):
    """save_png as it was: matplotlib's savefig lays out a figure with a layout engine in a pass of its own."""
    import matplotlib.pyplot as plt

    from flowtex.io.atomic import atomic_output

    if fig.get_layout_engine() is None:
        fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)


def old_math():
    """Every replaced formulation swapped in where the fits call it (module globals and their aliases)."""
    saved = [(poly, "power_spectrum"), (arma_resample, "_model_power_spectrum"), (anti_imaging, "power_spectrum"),
             (poly, "step_down"), (order, "step_down"), (poly, "roots_inside"), (arma_estimate, "roots_inside"),
             (hetero, "_floored"), (report, "save_png"), (compare_report, "save_png")]
    return swapped(dict(zip(saved, [numpy_power_spectrum] * 3 + [numpy_step_down] * 2 + [numpy_roots_inside] * 2
                            + [median_floored] + [savefig_png] * 2, strict=True)))


def _model(rng, pairs: int) -> np.ndarray:
    radius = 1.0 - 10.0 ** -rng.uniform(1.0, 4.0, pairs)
    angle = rng.uniform(0.0, np.pi, pairs)
    return np.real(np.poly(np.r_[radius * np.exp(1j * angle), radius * np.exp(-1j * angle)]))


def part_functions(rounds: int) -> None:
    rng = np.random.default_rng(0)
    print("| function | case | old ms/call | new ms/call | old / new | new against old |")
    print("|---|---|---|---|---|---|")
    for case, m, pairs, nw in (("one model (18, 16), 512 frequencies", 1, (9, 8), 512),
                               ("one model (6, 4), 2049 frequencies", 1, (3, 2), 2049),
                               ("300 models (18, 16) along a path, 1500 frequencies", 300, (9, 8), 1500)):
        ar = np.array([_model(rng, pairs[0]) for _ in range(m)])
        ma = np.array([_model(rng, pairs[1]) for _ in range(m)])
        w = np.linspace(0.01, np.pi - 0.01, nw)
        if m == 1:
            ar, ma = ar[0], ma[0]
        old, new = numpy_power_spectrum(ar, ma, w), poly.power_spectrum(ar, ma, w)
        same = "bit-identical" if np.array_equal(old, new) else f"max rel. diff {np.max(np.abs(new / old - 1.0)):.1e}"
        t_old = cpu_per_call(numpy_power_spectrum, (ar, ma, w), rounds, MIN_S)
        t_new = cpu_per_call(poly.power_spectrum, (ar, ma, w), rounds, MIN_S)
        print(f"| power_spectrum | {case} | {1e3 * t_old:.3f} | {1e3 * t_new:.3f} | {t_old / t_new:.1f} | {same} |")
    for p in (4, 18, 40):
        a = _model(rng, p // 2)
        t_old = cpu_per_call(numpy_roots_inside, (a, poly.MAX_RADIUS), rounds, MIN_S)
        t_new = cpu_per_call(poly.roots_inside, (a, poly.MAX_RADIUS), rounds, MIN_S)
        assert numpy_roots_inside(a, poly.MAX_RADIUS) == poly.roots_inside(a, poly.MAX_RADIUS)
        print(f"| roots_inside | order {p} | {1e3 * t_old:.4f} | {1e3 * t_new:.4f} | {t_old / t_new:.1f} | the same answer |")
    x = rng.uniform(10.0, 400.0, 20000)
    r = rng.standard_t(5, x.size) * (0.1 + 0.01 * x)
    kept = hetero._floored
    hetero._floored = median_floored
    try:
        t_old = cpu_per_call(hetero.fit_scale_function, (x, r), rounds, MIN_S)
        old = hetero.fit_scale_function(x, r)
    finally:
        hetero._floored = kept
    t_new = cpu_per_call(hetero.fit_scale_function, (x, r), rounds, MIN_S)
    same = "bit-identical" if hetero.fit_scale_function(x, r) == old else "DIFFERENT"
    print(f"| median_regression | fit_scale_function, 20,000 samples | {1e3 * t_old:.1f} | {1e3 * t_new:.1f} | "
          f"{t_old / t_new:.1f} | {same} |")


def _numbers(obj) -> list[float]:
    """Every number in a JSON document, in order (strings and keys left out)."""
    if isinstance(obj, dict):
        return [x for k in sorted(obj) for x in _numbers(obj[k])]
    if isinstance(obj, list):
        return [x for v in obj for x in _numbers(v)]
    if isinstance(obj, (int, float)) and not isinstance(obj, bool):
        return [float(obj)]
    return []


def _rel_diff(a: Path, b: Path) -> float:
    x, y = np.array(_numbers(json.loads(a.read_text()))), np.array(_numbers(json.loads(b.read_text())))
    if x.shape != y.shape:
        return float("inf")
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.abs(x - y) / np.maximum(np.abs(x), np.abs(y))
    return float(np.nanmax(d)) if d.size else 0.0


def part_commands(rounds: int, seconds: float) -> None:
    from flowtex.datasets import friction_session
    from flowtex.datasets.resonant import textured_exploration

    tmp = Path(tempfile.mkdtemp(prefix="bench_fit_math_"))
    tex, fric = tmp / "tex.npz", tmp / "fric.npz"
    textured_exploration(seconds, 1000.0, seed=0).save(tex)
    friction_session(duration_s=seconds, seed=0).save(fric)
    sig = ["--accel", "accel", "--speed", "speed", "--force", "normal_force"]
    commands = {
        "fit texture --report": lambda o: ["fit", "texture", *sig, str(tex), "-o", str(o / "surf.json"), "--report", str(o / "rep")],
        "models resample --rate 2000": lambda o: ["models", "resample", "--rate", "2000", "--allow-misses", "-o",
                                                  str(o / "surf2k.json"), str(tmp / "new" / "surf.json")],
        "compare": lambda o: ["compare", *sig, "--json", str(o / "cmp.json"), str(tmp / "new" / "surf.json"), str(tex)],
        "fit friction": lambda o: ["fit", "friction", "--force", "normal_force", "--friction-force", "tangential_force",
                                   str(fric), "-o", str(o / "fric.json")],
    }
    outputs = {"fit texture --report": "surf.json", "models resample --rate 2000": "surf2k.json", "compare": "cmp.json",
               "fit friction": "fric.json"}
    print(f"\n| command ({seconds:g} s recordings) | old CPU s | new CPU s | old / new | max rel. difference of the output |")
    print("|---|---|---|---|---|")
    for name, argv in commands.items():
        cpu: dict[str, list[float]] = {"old": [], "new": []}
        for k in range(rounds + 1):
            for which in ("new", "old"):
                out = tmp / which
                out.mkdir(exist_ok=True)
                t = time.process_time()
                if which == "old":
                    with old_math():
                        rc = flowtex_main(argv(out))
                else:
                    rc = flowtex_main(argv(out))
                if rc:
                    raise SystemExit(f"{name} ({which}) failed with {rc}")
                if k:
                    cpu[which].append(time.process_time() - t)
        o, n = statistics.median(cpu["old"]), statistics.median(cpu["new"])
        diff = _rel_diff(tmp / "old" / outputs[name], tmp / "new" / outputs[name])
        print(f"| {name} | {o:.2f} | {n:.2f} | {o / n:.2f} | {diff:.1e} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--skip-commands", action="store_true")
    args = ap.parse_args()
    part_functions(args.rounds)
    if not args.skip_commands:
        part_commands(args.rounds, args.seconds)


if __name__ == "__main__":
    main()
