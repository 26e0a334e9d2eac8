"""Compile CPU of a dispatch-tier wrapper: views built before the ``try`` (current) vs inside it (the old form).

    python benchmarks/bench_wrappers.py [--types texture_lookup arma_synth gain] [--rounds 2]

A wrapper (flowtex/graph/wrappers.py) builds one array view per port and calls
the node's kernel inside ``try``/``except`` so that a kernel's exception
reaches the dispatch driver as a fault. numba lowers every call inside a try
block with its own exception check and cleanup, so the old form, which built
the views inside the call's argument list, paid compile time per port. Both
forms run the same kernel on the same views: outputs are bit-identical
(tests/test_engine_tiers.py runs the current form against the fused tier).

The kernel of each type is compiled first (shared by both forms); then the two
forms compile alternately, ``--rounds`` times, each from new source text (no
in-process reuse), in one process, so load changes hit both alike. Figures
are process CPU seconds per wrapper compile and the old/current ratio.
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import tempfile
import time
from pathlib import Path

from numba.core.ccallback import CFunc

from flowtex.graph.jit import import_source
from flowtex.graph.wrappers import WRAPPER_SIG, wrapper_source
from flowtex.registry import load_registry

_counter = itertools.count()


def old_form(source: str, ports: int) -> str:
    """The wrapper as it was: each view built inside the kernel call, within the ``try``."""
    lines = source.splitlines()
    views = {f"v{k}": next(line.split(" = ", 1)[1] for line in lines if line.startswith(f"    v{k} = "))
             for k in range(ports)}
    out = [line for line in lines if not any(line.startswith(f"    {v} = ") for v in views)]
    call = next(i for i, line in enumerate(out) if line.startswith("        kernel("))
    for name in sorted(views, key=lambda v: -int(v[1:])):  # v10 before v1
        out[call] = out[call].replace(name, views[name])
    return "\n".join(out) + "\n"


def compile_cpu(source: str, kernel, folder: Path) -> float:
    n = next(_counter)
    module = import_source(folder / f"w{n}.py", source, {"kernel": kernel}, f"bench_wrapper_{n}")
    t0 = time.process_time()
    CFunc(module.wrapper, WRAPPER_SIG, locals={}, options={}).compile()
    return time.process_time() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--types", nargs="+", default=["texture_lookup", "arma_synth", "gain"])
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    registry = load_registry()
    print(f"{'node type':16s} {'ports':>5s} {'old s':>7s} {'current s':>9s} {'old/current':>11s}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.types:
            cls = registry.get(name)
            ports = len(cls.inputs) + len(cls.outputs)
            current = wrapper_source("k", len(cls.inputs), len(cls.outputs))
            compile_cpu(current, cls.kernel, Path(tmp))  # compiles the kernel itself: not part of either figure
            times: dict[str, list[float]] = {"old": [], "current": []}
            for _ in range(args.rounds):
                times["old"].append(compile_cpu(old_form(current, ports), cls.kernel, Path(tmp)))
                times["current"].append(compile_cpu(current, cls.kernel, Path(tmp)))
            old, cur = statistics.median(times["old"]), statistics.median(times["current"])
            print(f"{name:16s} {ports:5d} {old:7.2f} {cur:9.2f} {old / cur:11.2f}")


if __name__ == "__main__":
    main()
