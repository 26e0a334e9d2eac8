"""Start-up benchmark: ``flowtex --help``, ``flowtex --version`` and ``import flowtex`` against ``import numpy``.

    python benchmarks/bench_startup.py [--runs 15]

Each command is a new process (wall time, interpreter start included). The
commands run interleaved, round after round, so a load change on a shared
machine hits baseline and candidate alike; the figure is the median per
command and the ratio to the ``python -c "import numpy"`` baseline of the same
rounds. The target (docs/engine.md) is ``--help`` and ``--version`` within 2x
the baseline. What ``--help`` imports is asserted (not timed) by
tests/cli/test_cli_lazy.py.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

COMMANDS = {
    "python -c 'import numpy' (baseline)": [sys.executable, "-c", "import numpy"],
    "python -c 'import flowtex'": [sys.executable, "-c", "import flowtex"],
    "flowtex --version": [sys.executable, "-m", "flowtex", "--version"],
    "flowtex --help": [sys.executable, "-m", "flowtex", "--help"],
    "flowtex run --help (one command module)": [sys.executable, "-m", "flowtex", "run", "--help"],
}


def measure(runs: int) -> dict[str, list[float]]:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for _ in range(runs):
        for name, cmd in COMMANDS.items():
            t0 = time.perf_counter()
            subprocess.run(cmd, env=env, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
            times[name].append(time.perf_counter() - t0)
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15)
    args = parser.parse_args()
    times = measure(args.runs)
    base = statistics.median(next(iter(times.values())))
    print(f"{'command':<44} {'median s':>9} {'min s':>7} {'x numpy':>8}   (load: {os.getloadavg()[0]:.1f})")
    for name, values in times.items():
        med = statistics.median(values)
        print(f"{name:<44} {med:9.3f} {min(values):7.3f} {med / base:8.2f}")


if __name__ == "__main__":
    main()
