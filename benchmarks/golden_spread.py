"""How far do the example graphs' outputs move between CPUs? (the data behind flowtex.testing's default tolerance)

    python benchmarks/golden_spread.py

Runs every example graph of tests/test_examples.py twice, each in its own
process: once with numba's code for this CPU (native: AVX2/AVX-512, fused
multiply-add) and once with ``NUMBA_CPU_NAME=generic`` (SSE2 only, no fused
multiply-add: the most different code numba can make on x86-64). Prints, per
output, the largest |difference| relative to the output's RMS between the two
runs and between each run and the committed golden file (made on another
machine). flowtex.testing.DEFAULT_RMS_RTOL must sit far above every figure.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from test_examples import EXAMPLES, GOLDEN, GRAPHS  # noqa: E402

from flowtex.testing import DEFAULT_RMS_RTOL, rms  # noqa: E402


def run_all(folder: Path) -> None:
    """Worker: run every example and save its outputs to folder/NAME.npz."""
    from flowtex.testing import run_graph_on_file

    for name, (recording, options) in EXAMPLES.items():
        out = run_graph_on_file(GRAPHS / name, GRAPHS / recording, plugins=options.get("plugins", ()))
        np.savez(folder / (Path(name).stem + ".npz"), **out)


def load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as d:
        return {k: d[k] for k in d.files}


def spread(a: np.ndarray, b: np.ndarray) -> tuple[float, int]:
    """(max |a - b| / RMS(b), number of values whose bits differ)."""
    differ = ~((a == b) | (np.isnan(a) & np.isnan(b)))
    scale = rms(b)
    d = np.abs(a - b)[differ]
    worst = float(d.max()) if d.size else 0.0
    return (worst / scale if scale > 0 else (0.0 if worst == 0 else float("inf"))), int(differ.sum())


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        runs = {}
        for label, extra in (("native", {}), ("generic", {"NUMBA_CPU_NAME": "generic"})):
            folder = Path(tmp) / label
            folder.mkdir()
            env = {**os.environ, **extra, "PYTHONPATH": str(REPO)}
            subprocess.run([sys.executable, __file__, "--worker", str(folder)], env=env, check=True)
            runs[label] = folder
        print(f"{'graph':<22}{'output':<16}{'n':>7}  {'generic/native':>22}  {'native/golden':>22}  {'generic/golden':>22}")
        print(f"{'':<45}{'max|d|/RMS  bits differ':>24}")
        overall = 0.0
        for name in sorted(EXAMPLES):
            stem = Path(name).stem
            nat, gen, gold = (load(runs["native"] / f"{stem}.npz"), load(runs["generic"] / f"{stem}.npz"), load(GOLDEN / f"{stem}.npz"))
            for out in sorted(gold):
                cells = []
                for a, b in ((gen[out], nat[out]), (nat[out], gold[out]), (gen[out], gold[out])):
                    s, k = spread(a, b)
                    overall = max(overall, s)
                    cells.append(f"{s:10.2e} {k:11d}")
                print(f"{stem:<22}{out:<16}{gold[out].size:>7}  " + "  ".join(cells))
        print(f"largest max|d|/RMS: {overall:.2e}; flowtex.testing.DEFAULT_RMS_RTOL = {DEFAULT_RMS_RTOL:g} "
              f"(margin x{DEFAULT_RMS_RTOL / max(overall, 1e-300):.1e})")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        run_all(Path(sys.argv[2]))
    else:
        main()
