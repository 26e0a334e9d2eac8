"""The two ways a graph's tick is compiled, and which one runs when (docs/engine.md).

``fused`` (tier 1)
    one ``block``/``run``/``step`` generated for the graph's structure and
    compiled by numba with every kernel inlined: the fastest tick, but each new
    structure costs a full compile (seconds).
``dispatch`` (tier 0)
    one generic driver, compiled once per machine, calls each node's cached
    wrapper through its address (:mod:`flowtex.graph.dispatch`): a structural
    edit compiles nothing new when its node types were seen before.
``auto``
    ``fused`` when this structure's fused code is already in the cache,
    otherwise ``dispatch`` (and, from :func:`flowtex.load_graph`, a background
    compile of the fused code for next time).

Both tiers call the same kernels on the same arena with the same views in the
same order: their outputs are bit-identical (tests/test_engine_tiers.py).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FlowtexError
from .arena import Layout
from .codegen import RUN_SOURCE, generate
from .jit import generated_digest, load_generated
from .kcache import sealed_compile
from .resolve import ResolvedGraph

TIERS = ("fused", "dispatch", "auto")
COMPILE_ENV = "FLOWTEX_COMPILE"
"""Default tier of :func:`flowtex.load_graph` when the caller passes none (``fused`` if unset)."""

BLOCK_SIG = "(float64[::1], int64[::1], int64)"
RUN_SIG = "(float64[::1], int64[::1], float64[::1], float64[::1])"


@dataclass
class Compiled:
    """What a tier hands to :class:`~flowtex.graph.compiled.Graph`."""

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


def check_tier(tier: str) -> str:
    """``tier`` if it is one of :data:`TIERS`, else a :class:`FlowtexError` naming the choices."""
    if tier not in TIERS:
        raise FlowtexError(f"unknown compile tier {tier!r}; use one of {', '.join(TIERS)} (--compile / {COMPILE_ENV})")
    return tier


def default_tier() -> str:
    return check_tier(os.environ.get(COMPILE_ENV, "fused").strip() or "fused")


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


_DISPATCH_RUN: Any = None


def dispatch_run() -> Any:
    """The dispatch tier's ``run``: the fused tier's run loop (one source) over the generic driver."""
    global _DISPATCH_RUN
    if _DISPATCH_RUN is None:
        from . import dispatch

        source = "# Generated by flowtex: the run loop over the dispatch tier's generic driver.\n" \
                 "import numpy as np\nfrom numba import njit\nfrom flowtex.graph.kernels import view\n\n\n" + RUN_SOURCE
        module = load_generated(source, {"block": dispatch.block}, "dispatch-run")
        dispatch.block.compile(BLOCK_SIG)
        module.run.compile(RUN_SIG)
        _DISPATCH_RUN = module.run
    return _DISPATCH_RUN


def dispatch_step(block_entry: Callable[..., Any], in_offsets: list[int], out_offsets: list[int]) -> Callable[..., tuple]:
    """A Python ``step(f, i, x0, ...)`` for the dispatch tier: write the scalars, one driver call, read the scalars.

    A non-number raises ``TypeError`` like the fused tier's compiled ``step``.
    """
    args = "".join(f", x{k}" for k in range(len(in_offsets)))
    lines = [f"def step(f, i{args}):"]
    if in_offsets:
        lines.append("    try:")
        lines += [f"        f[{off}] = float(x{k})" for k, off in enumerate(in_offsets)]
        lines += ["    except ValueError:", "        raise TypeError('step(): scalar inputs must be numbers') from None"]
    lines.append("    BLOCK(f, i, 1)")
    values = [f"f.item({off})" for off in out_offsets] or ["0.0"]
    lines.append(f"    return ({', '.join(values)},)")
    namespace: dict[str, Any] = {"BLOCK": block_entry}
    exec("\n".join(lines), namespace)  # generated from integer offsets only
    return namespace["step"]


def compile_dispatch(rg: ResolvedGraph, layout: Layout, step_in: list[str], step_out: list[str]) -> Compiled:
    """The dispatch tier for ``rg``: load (or compile, once per kernel) its wrappers and build the dispatch table."""
    from . import dispatch, wrappers

    before = len(wrappers.REBUILT)
    ints, lines = dispatch.dispatch_table(rg, layout)
    run = dispatch_run()
    step = dispatch_step(entry(dispatch.block), [layout.graph_inputs[n].offset for n in step_in],
                         [layout.graph_outputs[n].offset for n in step_out])
    source = (f"# Dispatch tier (tier 0) of graph {rg.spec.name!r}: the generic driver below runs the nodes in this order,\n"
              "# calling each node's cached wrapper (source in the named file of the kernel cache) through its address:\n"
              + "".join(f"#   {k}. {line}\n" for k, line in enumerate(lines, start=1)) + "\n" + dispatch.driver_source())
    return Compiled("dispatch", dispatch.block, run, step, ints, source, wrappers.REBUILT[before:])
