"""The fused backend (tier 1): one ``block``/``run``/``step`` generated for a graph's structure, every kernel inlined.

The fastest tick, but each new structure costs a full numba compile (seconds).
:class:`FusedPlan` computes the generated source and its cache key without
compiling; :meth:`FusedPlan.compile` loads or compiles it. Like the dispatch
backend (:mod:`flowtex.graph.dispatch`) it compiles in this process and starts
none: which backend runs, and any background job, is the compile service's
choice (:mod:`flowtex.compile.service`, docs/engine.md).

Both backends call the same kernels on the same arena with the same views in
the same order: their outputs are bit-identical (tests/test_engine_tiers.py).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .arena import Layout
from .codegen import generate
from .jit import generated_digest, load_generated
from .kcache import sealed_compile
from .resolved import ResolvedGraph

BLOCK_SIG = "(float64[::1], int64[::1], int64)"
RUN_SIG = "(float64[::1], int64[::1], float64[::1], float64[::1])"


@dataclass
class Compiled:
    """What a backend hands to :class:`~flowtex.graph.compiled.Graph`."""

    tier: str
    block: Any
    """The numba ``block(f, i, n)`` function (compiled for :data:`BLOCK_SIG`)."""
    run: Any
    """The numba ``run(f, i, X, Y)`` function."""
    step: Callable[..., tuple]
    """``step(f, i, x0, x1, ...)`` -> tuple of scalar outputs (a compiled entry point for ``fused``)."""
    ints: np.ndarray
    """The int arena (the layout's, plus the dispatch table for ``dispatch``)."""
    source: str
    """What runs, for ``flowtex graph --show-code``."""
    rebuilt: list[str] = field(default_factory=list)


def entry(fn: Any) -> Callable[..., Any]:
    """Compiled entry point of a numba function's first signature (skips numba's per-call type dispatch)."""
    return fn.overloads[fn.signatures[0]].entry_point


class FusedPlan:
    """The fused tier's generated source and cache key, computed without compiling anything."""

    def __init__(self, rg: ResolvedGraph, layout: Layout, step_in: list[str], step_out: list[str]):
        kernels: dict[str, Callable] = {}
        names: dict[str, str] = {}
        for idx, (name, rn) in enumerate(rg.nodes.items()):
            names[name] = f"k{idx}"
            kernels[f"k{idx}"] = rn.cls.get_kernel()
            if rg.cyclic and rn.cls.breaks_cycles:
                names[name + ":emit"] = f"k{idx}_emit"
                names[name + ":absorb"] = f"k{idx}_absorb"
                kernels[f"k{idx}_emit"] = rn.cls.get_kernel("emit_kernel")
                kernels[f"k{idx}_absorb"] = rn.cls.get_kernel("absorb_kernel")
        self.kernels = kernels
        self.n_step_in = len(step_in)
        self.source = generate(rg, layout.nodes, names, [layout.graph_inputs[n] for n in step_in],
                               [layout.graph_outputs[n] for n in step_out])
        self.versions = ";".join(f"{rn.cls.type_name}@{rn.cls.version}" for rn in rg.nodes.values())
        self.digest, self.folder = generated_digest(self.source, kernels, self.versions)

    def seal_path(self) -> Path:
        return self.folder / f"g_{self.digest}.seal"

    def cached(self) -> bool:
        """True when this structure's fused code was compiled and sealed before (loading it takes milliseconds)."""
        return self.seal_path().exists()

    def compile(self, ints: np.ndarray) -> Compiled:
        """Load (or compile, sealed) this structure's ``block``, ``run`` and ``step``; ``ints`` is the layout's int arena."""
        module = load_generated(self.source, self.kernels, self.versions)
        if all(f.signatures for f in (module.block, module.run, module.step)):  # compiled (or loaded) earlier in this process
            return Compiled("fused", module.block, module.run, entry(module.step), ints, self.source)
        base = Path(module.block._cache._cache_path)

        def files() -> list[Path]:
            return sorted(base.glob(f"g_{self.digest}.*nb[ic]")) if base.is_dir() else []

        def build() -> None:
            module.block.compile(BLOCK_SIG)
            module.run.compile(RUN_SIG)
            module.step.compile("(float64[::1], int64[::1]" + ", float64" * self.n_step_in + ")")

        _, rebuilt = sealed_compile(self.folder / f"g_{self.digest}", files, build)
        return Compiled("fused", module.block, module.run, entry(module.step), ints, self.source,
                        [self.digest] if rebuilt else [])
