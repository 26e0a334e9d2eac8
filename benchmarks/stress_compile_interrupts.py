"""Ctrl-C at random moments of numba compiles, then compiling again in the same process (docs/engine.md).

A notebook or script goes on after Ctrl-C. A compile cut short used to leave numba's half-built code behind, and
every later compile that linked it failed with "no compiled object yet" until the process restarted.
``flowtex.interrupts.interrupts_deferred`` makes the compile finish first.

Each trial is a fresh process with an empty compile cache. It compiles ``--compiles`` new functions that call the
texture lookup (``flowtex.dsp.interp.lookup_model``), so the first compile builds the whole lookup. A timer sends
SIGINT to the process after a random delay during each compile. The trial passes when every compile either
finishes or ends in KeyboardInterrupt, and none fails otherwise::

    python benchmarks/stress_compile_interrupts.py --trials 6 --compiles 6 --max-delay 4

It prints one line per trial and the number of trials that failed. Compare with a baseline by checking out an
older commit in another folder and running this file there (each trial imports the flowtex that Python finds).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

TRIAL = r"""
import os, random, signal, sys, threading
from numba import njit
from flowtex.dsp import interp

SOURCE = '''
def f{k}(tab, s, si, x, y):
    for t in range(x.shape[0]):
        interp.lookup_model(tab, s, si, x[t] + {k}, y[t])
    return s[0]
'''
rng = random.Random(int(sys.argv[1]))
compiles, max_delay = int(sys.argv[2]), float(sys.argv[3])
finished = interrupted = 0
for k in range(compiles):
    namespace = {"interp": interp}
    exec(SOURCE.format(k=k), namespace)
    function = njit(namespace[f"f{k}"])
    timer = threading.Timer(rng.uniform(0.0, max_delay), lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        function.compile("(float64[::1], float64[::1], int64[::1], float64[::1], float64[::1])")
        finished += 1
    except KeyboardInterrupt:
        interrupted += 1
    finally:
        timer.cancel()
    try:
        timer.join()
    except KeyboardInterrupt:  # the signal came after the compile: not a compile's interrupt
        pass
print(f"finished {finished}, interrupted {interrupted}")
"""


def trial(seed: int, compiles: int, max_delay: float, timeout_s: float) -> tuple[bool, str]:
    """(passed, what the trial printed last) for one process with an empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "FLOWTEX_CACHE_DIR": cache}
        env.pop("NUMBA_CACHE_DIR", None)
        done = subprocess.run([sys.executable, "-c", TRIAL, str(seed), str(compiles), str(max_delay)], env=env,
                              capture_output=True, text=True, timeout=timeout_s)
    lines = (done.stdout if done.returncode == 0 else done.stderr).strip().splitlines()
    return done.returncode == 0, lines[-1] if lines else f"exit {done.returncode}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=6, help="processes (default 6)")
    ap.add_argument("--compiles", type=int, default=6, help="compiles per process (default 6)")
    ap.add_argument("--max-delay", type=float, default=4.0, help="longest wait before a Ctrl-C, s (default 4)")
    ap.add_argument("--seed", type=int, default=4, help="seed of the first trial (default 4)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds a trial may take (default 600)")
    args = ap.parse_args()
    failed = 0
    for seed in range(args.seed, args.seed + args.trials):
        passed, last = trial(seed, args.compiles, args.max_delay, args.timeout)
        failed += not passed
        print(f"trial {seed}: {'ok' if passed else 'FAILED'}: {last}", flush=True)
    print(f"{failed} of {args.trials} trials failed")


if __name__ == "__main__":
    main()
