"""The IRLS line fits (flowtex.dsp.robust, flowtex.dsp.hetero) against the code they replaced, side by side in one
process.

    python benchmarks/bench_robust.py [--rounds 3] [--seconds 20]

The baseline is the old code itself, kept verbatim in tests/dsp/robust_old.py (the oracle of
tests/dsp/test_robust_speed.py): numpy medians (a partition each) for the MAD scale, numpy weights and reweighted rows
allocated every iteration, batch means over fancy-indexed copies. The new code: the MAD by a compiled selection
within a sampled bracket, the weights and rows by one compiled pass into buffers reused across iterations, batch
means over slices (flowtex/dsp/robust_kernels.py).

Part 1, each fit alone on friction-sized problems (n samples at 1 kHz; noise growing with the normal force, Student
t tails, 1 % spikes): CPU per call (``time.process_time``, best of ``--rounds``), the ratio, and the largest absolute
difference between the old and new outputs (must be 0).
Part 2, ``flowtex fit friction`` in this process on generated recordings (``flowtex.datasets.friction_session`` and
``flowtex.datasets.dragging.stiction_drag``, ``--seconds`` long), old and new alternating ``--rounds`` times after a
warm-up round: CPU seconds (median), the ratio, and whether the two friction files are identical byte for byte.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]  # this tree's flowtex and the tests' oracle
from baseline import cpu_per_call, swapped  # noqa: E402  (a script beside this one)

from flowtex.cli.main import main as flowtex_main  # noqa: E402
from flowtex.dsp import hetero, robust  # noqa: E402
from tests.dsp import robust_old  # noqa: E402

MIN_S = 0.3
"""CPU seconds each round of a function's timing repeats it for at least."""


def old_code():
    """The old irls, MAD scale and median-regression floor swapped in wherever the fits call them."""
    return swapped({(robust, "irls"): robust_old.irls, (hetero, "irls"): robust_old.irls,
                    (robust, "robust_scale"): robust_old.robust_scale, (hetero, "_floored"): robust_old._floored})


def _problem(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = np.abs(rng.normal(1.5, 0.8, n)) + 0.05
    y = 0.4 * x + 0.04 * x * rng.standard_t(5.0, n)
    spikes = rng.random(n) < 0.01
    y[spikes] += rng.normal(0.0, 1.0, int(spikes.sum()))
    return x, y


def _flat(v) -> np.ndarray:
    """Every number of a fit's output, flattened (dataclasses, tuples, arrays)."""
    if hasattr(v, "__dataclass_fields__"):
        return np.concatenate([_flat(getattr(v, f)) for f in v.__dataclass_fields__])
    if isinstance(v, tuple | list):
        return np.concatenate([_flat(a) for a in v]) if v else np.zeros(0)
    return np.asarray(v, float).reshape(-1)


def part_functions(rounds: int) -> None:
    print("| fit | n | old ms/call | new ms/call | old / new | max abs. difference |")
    print("|---|---|---|---|---|---|")
    for n in (4000, 20000):
        x, y = _problem(n)
        X2 = np.column_stack([x, np.ones_like(x)])
        A = np.vander(np.log(x / np.median(x)), 2, increasing=True)
        b = np.log(np.abs(y - 0.4 * x) + 1e-12)
        cases = {
            "irls_line (slope only)": (robust.irls, robust_old.irls, (x[:, None], y)),
            "irls (slope + intercept)": (robust.irls, robust_old.irls, (X2, y)),
            "irls_line_hetero": (hetero.irls_line_hetero, robust_old.irls_line_hetero, (x, y)),
            "median_regression": (hetero.median_regression, robust_old.median_regression, (A, b)),
            "robust_scale": (robust.robust_scale, robust_old.robust_scale, (y,)),
        }
        for name, (new, old, args) in cases.items():
            diff = float(np.max(np.abs(_flat(new(*args)) - _flat(old(*args))), initial=0.0))
            o, w = cpu_per_call(old, args, rounds, MIN_S), cpu_per_call(new, args, rounds, MIN_S)
            print(f"| {name} | {n} | {o * 1e3:.2f} | {w * 1e3:.2f} | {o / w:.2f} | {diff:.1e} |")


def part_command(rounds: int, seconds: float) -> None:
    from flowtex.datasets import friction_session
    from flowtex.datasets.dragging import stiction_drag

    tmp = Path(tempfile.mkdtemp(prefix="bench_robust_"))
    recordings = {"friction_session": tmp / "session.npz", "stiction_drag": tmp / "drag.npz"}
    friction_session(duration_s=seconds, seed=0).save(recordings["friction_session"])
    stiction_drag(duration_s=seconds, seed=0).save(recordings["stiction_drag"])
    print(f"\n| fit friction ({seconds:g} s recording) | old CPU s | new CPU s | old / new | files identical |")
    print("|---|---|---|---|---|")
    for name, rec in recordings.items():
        cpu: dict[str, list[float]] = {"old": [], "new": []}
        for k in range(rounds + 1):
            for which in ("new", "old"):
                out = tmp / f"{name}_{which}.json"
                argv = ["fit", "friction", "--force", "normal_force", "--friction-force", "tangential_force", str(rec),
                        "-o", str(out)]
                t = time.process_time()
                with contextlib.redirect_stdout(io.StringIO()), old_code() if which == "old" else contextlib.nullcontext():
                    rc = flowtex_main(argv)
                if rc:
                    raise SystemExit(f"fit friction on {name} ({which}) failed with {rc}")
                if k:
                    cpu[which].append(time.process_time() - t)
        o, w = statistics.median(cpu["old"]), statistics.median(cpu["new"])
        same = (tmp / f"{name}_old.json").read_bytes() == (tmp / f"{name}_new.json").read_bytes()
        print(f"| {name} | {o:.2f} | {w:.2f} | {o / w:.2f} | {'yes' if same else 'NO'} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=20.0)
    args = ap.parse_args()
    part_functions(args.rounds)
    part_command(args.rounds, args.seconds)


if __name__ == "__main__":
    main()
