"""CPU of a warm graph build, cache keys computed once per function (current) vs every time (the old code).

    python benchmarks/bench_graph_keys.py [--graphs hatt_texture.yaml live_texture.yaml] [--rounds 5]

Building a graph whose code is cached still computes the cache keys of its generated module and of each node type's
wrapper (flowtex/graph/jit.py, flowtex/graph/wrappers.py). The old code read each kernel's source with
``inspect.getsource`` (a tokenize of its file from the definition on), asked LLVM for the CPU's name and features
and read the dispatch driver's source every time a key was computed; the current code keeps each kernel's source
digest by function object and the other two once a process. The old functions are swapped in where the product
calls the new (benchmarks/baseline.py) and the two alternate round after round in one process, so load changes hit
both alike. Figures: CPU ms per ``load_graph`` (best of the rounds), the old/current ratio, and whether both built
graphs with the same cache keys (they must: the keys are what the change must not move).
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import sys
from pathlib import Path

from baseline import cpu_per_call, swapped

from flowtex.graph import dispatch, jit, wrappers
from flowtex.graph.compiled import load_graph

REPO = Path(__file__).resolve().parents[1]


def old_source_digest(func) -> str:
    """The old code: the function's source read (and hashed) every time a key needs it."""
    try:
        source = inspect.getsource(func)
    except (OSError, TypeError):
        source = repr(func.__code__.co_code)
    return hashlib.sha256(source.encode()).hexdigest()


OLD = {(jit, "_source_digest"): old_source_digest, (wrappers, "machine_key"): wrappers.machine_key.__wrapped__,
       (dispatch, "driver_source"): dispatch.driver_source.__wrapped__}


def keys(path: Path, tier: str) -> list[str]:
    """What a build of ``path`` computes from the changed functions (whichever are installed: current or old): every
    kernel fingerprint, which names each wrapper's and generated module's cache entry, and the machine key."""
    seen: list[str] = []

    def recorded(fn):
        def call(*args):
            seen.append(fn(*args))
            return seen[-1]
        return call

    fingerprint, machine = jit.kernel_fingerprint, wrappers.machine_key
    with swapped({(jit, "kernel_fingerprint"): recorded(fingerprint), (wrappers, "kernel_fingerprint"): recorded(fingerprint),
                  (wrappers, "machine_key"): recorded(machine)}):
        build(path, tier)
    return seen


def build(path: Path, tier: str) -> None:
    """One warm build of the graph file at ``path`` on ``tier``."""
    load_graph(path, tier=tier)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--graphs", nargs="+", default=["hatt_texture.yaml", "live_texture.yaml", "surface_render.yaml"])
    ap.add_argument("--tiers", nargs="+", default=["dispatch", "fused"])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    print(f"{'graph':28s} {'tier':9s} {'current ms':>11s} {'old ms':>8s} {'old/current':>12s}  same keys")
    for name in args.graphs:
        path = REPO / "graphs" / name
        for tier in args.tiers:
            build(path, tier)  # compiled or loaded once: what follows is the warm build
            current = keys(path, tier)
            with swapped(OLD):
                old = keys(path, tier)
            t_new = t_old = float("inf")
            for _ in range(args.rounds):  # alternate, so a load change hits both
                t_new = min(t_new, cpu_per_call(build, (path, tier), 1, 0.3))
                with swapped(OLD):
                    t_old = min(t_old, cpu_per_call(build, (path, tier), 1, 0.3))
            print(f"{name:28s} {tier:9s} {1e3 * t_new:11.2f} {1e3 * t_old:8.2f} {t_old / t_new:12.2f}  {current == old}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
