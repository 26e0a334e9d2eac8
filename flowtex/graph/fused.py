"""The fused backend (tier 1): one ``block``/``run``/``step`` generated for a graph's structure, every kernel inlined.

The fastest tick, but each new structure costs a numba compile (seconds).
:class:`FusedPlan` computes the generated source and its cache key without
compiling; :meth:`FusedPlan.compile` gives a :class:`Compiled` whose entry
points each load or compile on first use (an offline run compiles ``run``
only; live code ``block``; ``step()`` from Python ``step``). Like the dispatch
backend (:mod:`flowtex.graph.dispatch`) it compiles in this process and starts
none: which backend runs, and any background job, is the compile service's
choice (:mod:`flowtex.compile.service`, docs/engine.md).

Both backends call the same kernels on the same arena with the same views in
the same order: their outputs are bit-identical (tests/test_engine_tiers.py).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numba.core import types

from .arena import Layout
from .codegen import block_body, generate
from .jit import generated_digest, load_generated
from .kcache import sealed_compile
from .resolved import ResolvedGraph

F64, I64 = types.float64[::1], types.int64[::1]
BLOCK_SIG = (F64, I64, types.int64)
"""``block(f, i, n)``'s argument types. A tuple of types, not a string: numba keys its disk cache by the signature as
given, and code calling ``block`` (the live tick) asks for these types, so both find one cache entry."""
RUN_SIG = (F64, I64, F64, F64)


ENTRY_POINTS = ("run", "block", "step")
"""What a compiled graph offers: ``run`` (offline, whole recordings), ``block`` (``n`` ticks: live code fuses it into
its own tick) and ``step`` (one tick from Python). Each compiles on its first use."""


class Compiled:
    """What a backend hands to :class:`~flowtex.graph.compiled.Graph`: the int arena, what runs, and the entry points.

    :meth:`get` compiles (or loads from the cache) an entry point on its first request: an offline run never pays
    for ``step`` or a separate ``block``.
    """

    def __init__(self, tier: str, ints: np.ndarray, source: str, load: Callable[[str], Any],
                 rebuilt: list[str] | None = None):
        self.tier = tier
        self.ints = ints
        """The int arena (the layout's, plus the dispatch table for ``dispatch``)."""
        self.source = source
        """What runs, for ``flowtex graph --show-code``."""
        self._load = load
        self._done: dict[str, Any] = {}
        self.rebuilt: list[str] = rebuilt if rebuilt is not None else []
        """Digests of damaged cache entries deleted and compiled afresh (appended as entry points compile)."""

    def get(self, name: str) -> Any:
        """Entry point ``name`` of :data:`ENTRY_POINTS`: ``block``/``run`` as numba functions compiled for
        :data:`BLOCK_SIG`/:data:`RUN_SIG`, ``step`` as a callable ``step(f, i, x0, x1, ...)`` -> tuple of scalar outputs."""
        hit = self._done.get(name)
        if hit is None:
            hit = self._done[name] = self._load(name)
        return hit

    def compiled(self, name: str) -> bool:
        """True once :meth:`get` has returned ``name`` (nothing compiles to answer)."""
        return name in self._done


def entry(fn: Any) -> Callable[..., Any]:
    """Compiled entry point of a numba function's first signature (skips numba's per-call type dispatch)."""
    return fn.overloads[fn.signatures[0]].entry_point


class EntryCompileError(Exception):
    """Raised by a :func:`lazy_entry` stand-in when its entry point fails to compile; its ``__cause__`` is the error.

    The stand-in is called where a kernel's exception is expected and reported as the node's fault: this class keeps a
    compile error from being reported as one."""


def lazy_entry(compile_: Callable[[], Callable[..., Any]], install: Callable[[Callable[..., Any]], None]) -> Callable[..., Any]:
    """A stand-in for a compiled entry point: its first call runs ``compile_()``, hands the result to ``install`` (which
    puts it where the stand-in was, so later calls cost nothing extra) and calls it."""

    def first_call(*args: Any) -> Any:
        try:
            fn = compile_()
        except Exception as exc:
            raise EntryCompileError(str(exc)) from exc
        install(fn)
        return fn(*args)

    return first_call


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
        """Global name (``k0``, ``k1``, ...) -> the kernel it calls."""
        self.signatures = {"block": BLOCK_SIG, "run": RUN_SIG, "step": (F64, I64) + (types.float64,) * len(step_in)}
        self.block_body = block_body(rg, layout.nodes, names)
        """``block``'s body (:func:`~flowtex.graph.codegen.block_body`): code that runs ticks inside its own compiled
        function (the live tick) holds these lines, with :attr:`kernels` and the codegen helpers as globals."""
        self.source = generate(rg, self.block_body, [layout.graph_inputs[n] for n in step_in],
                               [layout.graph_outputs[n] for n in step_out])
        self.versions = ";".join(f"{rn.cls.type_name}@{rn.cls.version}" for rn in rg.nodes.values())
        self.digest, self.folder = generated_digest(self.source, kernels, self.versions)

    def seal_path(self) -> Path:
        return self.folder / f"g_{self.digest}.seal"

    def cached(self, name: str = "run") -> bool:
        """True when this structure's entry point ``name`` was compiled and sealed before (loading it takes milliseconds).

        One seal covers the module's files (:mod:`flowtex.graph.kcache`); numba names each function's files
        ``g_<digest>.<function>-<line>.py<version>.nb[ic]``.
        """
        try:
            sealed = json.loads(self.seal_path().read_text())
        except (OSError, ValueError):
            return False
        return isinstance(sealed, dict) and any(k.startswith(f"g_{self.digest}.{name}-") for k in sealed)

    def compile(self, ints: np.ndarray, guard: Callable[[], contextlib.AbstractContextManager[Any]] = contextlib.nullcontext) -> Compiled:
        """This structure's :class:`Compiled`; ``ints`` is the layout's int arena. Nothing compiles yet: each entry point
        is loaded (or compiled and sealed) on its first :meth:`Compiled.get`, inside ``guard()`` (the service's notice)."""
        module = load_generated(self.source, self.kernels, self.versions)
        rebuilt: list[str] = []

        def load(name: str) -> Any:
            fn = getattr(module, name)
            if not fn.signatures:  # else compiled (or loaded) earlier in this process
                with guard():
                    self._compile(module, name, rebuilt)
            return entry(fn) if name == "step" else fn

        return Compiled("fused", ints, self.source, load, rebuilt)

    def _compile(self, module: ModuleType, name: str, rebuilt: list[str]) -> None:
        """Load or compile ``module``'s function ``name`` under the entry's lock, then seal all of the module's files."""
        base = Path(module.block._cache._cache_path)

        def files() -> list[Path]:
            return sorted(base.glob(f"g_{self.digest}.*nb[ic]")) if base.is_dir() else []

        _, again = sealed_compile(self.folder / f"g_{self.digest}", files,
                                  lambda: getattr(module, name).compile(self.signatures[name]))
        if again:
            rebuilt.append(self.digest)
