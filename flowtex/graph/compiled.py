"""A built, compiled graph: ``run`` on whole arrays, ``step`` one tick, ``reset``.

The compile service's product: :class:`Graph` lays out a resolved graph and asks
:mod:`flowtex.compile.service` for its tick; this module belongs to the compile
layer (docs/engine.md) and keeps the import path users and plugins know.

Time is the first axis everywhere: a scalar port gives shape ``(n,)``, a
vector port ``(n, *shape)``.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..compile.service import check_tier, compile_in_background, compile_tick, default_tier
from ..dsp.nonfinite import apply_nonfinite_policy  # noqa: F401  (re-exported: its import path before it moved to dsp)
from ..errors import FlowtexError, InputError
from ..limits import check_ticks
from ..node_api import PortSpec, suggest
from ..nodecheck import check_plugin_kernels
from ..pyvalues import float_signal, whole_count
from ..registry import Registry, folder_list, load_registry
from .arena import FAULT, OUT_WIDTH, TICK, Layout, plan_layout
from .faults import dispatch_fault, raised_fault
from .fused import ENTRY_POINTS, EntryCompileError, FusedPlan, entry, lazy_entry
from .pystep import make_py_step
from .resolve import ResolvedGraph, resolve_graph
from .spec import GraphSpec, load_spec

DEFAULT_BLOCK_ROWS = 1024
PROGRESS_CHUNK = 1 << 17


class Graph:
    """A compiled graph. Build one with :func:`flowtex.load_graph`."""

    def __init__(self, resolved: ResolvedGraph, block_rows: int = DEFAULT_BLOCK_ROWS, tier: str | None = None):
        """``tier``: ``fused``, ``dispatch`` or ``auto`` (docs/engine.md); default ``$FLOWTEX_COMPILE`` or ``fused``."""
        block_rows = whole_count("block_rows", block_rows, 1)
        self.resolved = resolved
        self.spec: GraphSpec = resolved.spec
        self.layout: Layout = plan_layout(resolved, block_rows)
        # step() passes scalar inputs as arguments and gets scalar outputs back as a tuple.
        self._step_in = [n for n, spec in resolved.input_specs.items() if spec.shape == ()]
        self._step_out = [n for n, spec in resolved.output_specs.items() if spec.shape == ()]
        self._vector_out = [n for n, spec in resolved.output_specs.items() if spec.shape != ()]
        self.requested_tier = check_tier(tier or default_tier())
        plan = FusedPlan(resolved, self.layout, self._step_in, self._step_out)
        self.fused_plan = plan
        # Choose the tier and make its code ready; the fused tier compiles (or loads from the disk cache) each entry
        # point on its first use: run() compiles run, step() step, live code block (prepare() before its first tick).
        code = compile_tick(resolved, self.layout, plan, self.requested_tier, self._step_in, self._step_out)
        self._code = code
        self.tier = code.tier
        """The tier that runs: ``fused`` or ``dispatch``."""
        self._dispatch = code.tier == "dispatch"
        self.layout.i = code.ints
        self.source = code.source
        self.rebuilt_cache_entries = code.rebuilt
        self._i0 = self.layout.i.copy()  # the float arena's initial values are the layout's (Layout.initial_floats)
        self.f = self.layout.f
        self.i = self.layout.i
        self._in_views = {name: self.f[s.offset:s.offset + s.width] for name, s in self.layout.graph_inputs.items()}
        self._out_views = {name: self.f[s.offset:s.offset + s.width] for name, s in self.layout.graph_outputs.items()}
        # step() fast path: scalar ports are read and written as single arena items.
        self._in_scalar_off = {name: s.offset for name, s in self.layout.graph_inputs.items() if s.width == 1
                               and resolved.input_specs[name].shape == ()}
        self._scalar_in = frozenset(self._in_scalar_off)
        self._scratch: tuple[np.ndarray, np.ndarray] | None = None
        # The compiled step and block entry points start as stand-ins that compile on the first call and put the entry
        # point in their place: calling them skips numba's per-call type dispatch (the arena arrays never change type).
        self._block_entry: Callable[..., Any] = lazy_entry(lambda: entry(code.get("block")), self._set_block_entry)
        self._py_step = make_py_step(self)
        self.step = self._py_step  # type: ignore[method-assign]  # the generated function, one call layer less
        self.seed = self.spec.seed
        self._held: dict[str, np.ndarray] = {}
        """Input -> its last value after ``nonfinite="hold"``, held into the next :meth:`process` chunk."""
        self._seed_nodes()  # the arenas are as placed: a reset's copies would only touch every page of them again

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickling (Dask, a process pool) ships the checked graph, its tier and its state, not compiled code: the
        receiving process compiles (or loads from its cache) and continues from the same tick, bit for bit."""
        return _unpickled, (self.resolved, self.layout.block_rows, self.requested_tier, self.seed, self.f.copy(),
                            self.i.copy(), self._held)

    # --- description -------------------------------------------------
    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def rate(self) -> float:
        """Base tick rate in Hz."""
        return self.spec.rate

    @property
    def inputs(self) -> dict[str, PortSpec]:
        return dict(self.resolved.input_specs)

    @property
    def outputs(self) -> dict[str, PortSpec]:
        return dict(self.resolved.output_specs)

    @property
    def ticks(self) -> int:
        """Ticks run since the last reset."""
        return int(self.i[TICK])

    # --- execution ---------------------------------------------------
    def reset(self, seed: int | None = None) -> None:
        """Restore the initial state; re-seed random nodes with ``seed`` (default: the graph's)."""
        if seed is not None:
            self.seed = whole_count("seed", seed, 0)
        self.layout.initial_floats(self.f)
        self.i[:] = self._i0
        self._held = {}
        self._seed_nodes()

    def _seed_nodes(self) -> None:
        """Seed every random node's state from the graph's seed and the node's name."""
        for name, rn in self.resolved.nodes.items():
            if rn.cls.uses_seed and rn.node is not None:
                slots = self.layout.nodes[name]
                s = self.f[self.i[slots.s[0]]:self.i[slots.s[1]]]
                si = self.i[self.i[slots.si[0]]:self.i[slots.si[1]]]
                rn.node.seed_state(s, si, np.random.SeedSequence([self.seed, zlib.crc32(name.encode())]))

    def run(self, inputs: Mapping[str, Any], seed: int | None = None, progress: bool = False,
            nonfinite: str = "error") -> dict[str, np.ndarray]:
        """Reset (with ``seed``), then run the whole recording ``inputs``.

        ``nonfinite`` says what to do with NaN/inf input samples: ``error``
        (refuse, naming the input, the count and the first index), ``hold``
        (last finite value of the channel, 0 before any), ``zero``, or ``pass``
        (unchanged, for nodes that handle NaN themselves).
        """
        self.reset(seed)
        return self.process(inputs, progress=progress, nonfinite=nonfinite)

    def process(self, inputs: Mapping[str, Any], progress: bool = False, nonfinite: str = "error") -> dict[str, np.ndarray]:
        """Continue from the current state over ``inputs`` (chunked runs equal one pass); ``nonfinite`` as in :meth:`run`."""
        arrays, total = self._check_inputs(inputs)
        arrays = apply_nonfinite_policy(arrays, nonfinite, held=self._held)
        if progress and total > PROGRESS_CHUNK:
            from tqdm import tqdm

            parts = []
            with tqdm(total=total, unit="tick", unit_scale=True, desc=self.name, leave=False) as bar:
                for start in range(0, total, PROGRESS_CHUNK):
                    stop = min(total, start + PROGRESS_CHUNK)
                    parts.append(self._run_chunk({k: a[start:stop] for k, a in arrays.items()}, stop - start))
                    bar.update(stop - start)
            return {name: np.concatenate([p[name] for p in parts]) for name in self.layout.out_columns}
        return self._run_chunk(arrays, total)

    def _run_chunk(self, arrays: dict[str, np.ndarray], total: int, owned: bool = False) -> dict[str, np.ndarray]:
        """Run ``total`` ticks over ``arrays``. Kernels read graph inputs in place in ``X``, through raw pointers that no
        read-only flag guards, so ``X`` is always flowtex's own copy unless ``owned`` says the arrays already are: a
        kernel that writes its input (a plugin mistake) then never reaches the caller's data."""
        if len(arrays) == 1:  # one input: its copy (aligned, C order) is already the layout run() reads
            only = next(iter(arrays.values()))
            X = np.ascontiguousarray(only).reshape(-1) if owned else np.array(only, dtype=np.float64, order="C").reshape(-1)
        else:
            X = np.concatenate([np.ascontiguousarray(arrays[name]).reshape(-1) for name in self.layout.in_columns]) \
                if arrays else np.empty(0)
        Y = np.empty(total * int(self.i[OUT_WIDTH]))
        run = self._code.get("run")  # compiled (or loaded) on the first run
        try:
            run(self.f, self.i, X, Y)
        except Exception as exc:  # a kernel raised (fused tier): the arena still points into X and Y
            self._kernel_raised(exc)
        self._check_fault()
        return self._split_outputs(Y, total)

    def _kernel_raised(self, exc: Exception) -> None:
        """Raise the :class:`~flowtex.graph.faults.KernelError` for ``exc``; reset first (the state is spoilt)."""
        if isinstance(exc, EntryCompileError):  # not a kernel's: the entry point's first compile failed
            raise exc.__cause__ from None  # type: ignore[misc]
        error = raised_fault(self.resolved, exc, self.i)
        self.reset()
        raise error from None

    def _check_fault(self) -> None:
        """Raise the error a dispatch-tier kernel recorded (see :mod:`flowtex.graph.faults`), after a reset."""
        if self.i[FAULT] != 0:
            error = dispatch_fault(self.resolved, self.i)
            self.reset()
            raise error

    def _split_outputs(self, Y: np.ndarray, total: int) -> dict[str, np.ndarray]:
        """Per-output arrays: contiguous views into ``Y`` (no copy)."""
        out = {}
        for name, (col, w) in self.layout.out_columns.items():
            shape = self.resolved.output_specs[name].shape
            out[name] = Y[total * col: total * (col + w)].reshape((total, *shape))
        return out

    def step(self, values: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Advance one tick. ``values`` maps graph input names to numbers/arrays.

        Inputs not given keep their previous value. Returns output name ->
        a float for scalar outputs, or a new array of the port's shape.
        (Replaced per instance by a function generated for this graph's ports.)
        """
        return self._py_step(values)

    def prepare(self, *entries: str) -> Graph:
        """Compile (or load from the disk cache) the named entry points now (``run``, ``block``, ``step``; default
        ``run``), rather than on first use: e.g. before a deadline, or in the background compile. Returns ``self``."""
        for name in entries or ("run",):
            if name not in ENTRY_POINTS:
                raise FlowtexError(f"unknown entry point {name!r}; use one of {', '.join(ENTRY_POINTS)}")
            self._code.get(name)
        return self

    def _set_block_entry(self, fn: Callable[..., Any]) -> None:
        self._block_entry = fn

    def warm(self) -> None:
        """Run one tick on scratch copies of the arenas: no effect on this graph's state.

        The live runtime calls it just before a deadline (when it cannot fuse the tick
        into one call), so that the tick's code and tables are back in the CPU caches
        when the real tick runs.
        """
        f, i = self.scratch_arenas()
        entry(self.block_function)(f, i, 1)  # block, not step: live code compiles block (and fuses it) anyway

    def scratch_arenas(self) -> tuple[np.ndarray, np.ndarray]:
        """Float and int arenas that are copies of this graph's state, for effect-free warm-up ticks.

        Copied once, from the live (seeded) state on the first call: random nodes
        need seeded generators to produce anything.
        """
        if self._scratch is None:
            self._scratch = (self.f.copy(), self.i.copy())
        return self._scratch

    def with_block_rows(self, rows: int) -> Graph:
        """This graph (same structure, parameters and seed; fresh state) laid out for blocks of ``rows`` ticks.

        The generated code is shared (offsets are data), so this costs a layout, not a
        compilation. ``rows=1`` suits tick-by-tick use (the live runtime): every port
        buffer shrinks to one row, and the arena from hundreds of KB to what the
        parameters and state need, so a tick touches a few cache lines per port.
        Returns ``self`` if it already has ``rows``.
        """
        if rows == self.layout.block_rows:
            return self
        other = Graph(self.resolved, rows, self.tier)
        other.reset(self.seed)
        return other

    @property
    def block_function(self) -> Any:
        """The compiled ``block(f, i, n)`` numba function: ``n`` ticks on the arenas ``f`` (float64) and ``i`` (int64).

        For code that fuses a graph tick into its own compiled function (the live runtime). Compiled (or loaded) on
        the first request.
        """
        return self._code.get("block")

    def block_source(self) -> tuple[list[str], dict[str, Any]] | None:
        """``block``'s body and the kernels it calls by name, for code that runs ticks inside its own compiled function
        (the live tick) without compiling ``block`` separately; None on the dispatch tier (call :attr:`block_function`)."""
        if self._dispatch:
            return None
        return list(self.fused_plan.block_body), dict(self.fused_plan.kernels)

    def input_view(self, name: str) -> np.ndarray:
        """Writable view of the current-tick value of graph input ``name`` (live fast path)."""
        return self._in_views[name]

    def output_view(self, name: str) -> np.ndarray:
        """View of the latest value of graph output ``name`` (valid after a step)."""
        return self._out_views[name]

    def step_block(self, n: int = 1) -> None:
        """Advance ``n`` ticks using whatever is in the input views (no Python mapping); the first call compiles ``block``."""
        try:
            self._block_entry(self.f, self.i, n)
        except Exception as exc:  # fused tier: the kernel's exception (costs nothing when none is raised)
            self._kernel_raised(exc)
        if self._dispatch and self.i.item(FAULT):  # dispatch tier: a wrapper recorded one
            self._check_fault()

    def check_inputs(self, inputs: Mapping[str, Any]) -> None:
        """Raise :class:`FlowtexError` unless ``inputs`` has every graph input, time first, in the right shape."""
        self._check_inputs(inputs)

    def _check_inputs(self, inputs: Mapping[str, Any]) -> tuple[dict[str, np.ndarray], int]:
        """Graph inputs as float64 arrays of shape (n, width), with n checked equal."""
        if not (isinstance(inputs, Mapping) or (hasattr(inputs, "keys") and hasattr(inputs, "__getitem__"))):  # a DataFrame too
            raise InputError(f"graph {self.name!r}: pass the inputs as a mapping of input name to array, "
                             f"e.g. {{{next(iter(self.layout.in_columns), 'x')!r}: x}}; got {type(inputs).__name__}")
        unknown = [n for n in inputs if n not in self.layout.in_columns]
        if unknown:
            hints = "".join(suggest(str(n), list(self.layout.in_columns)) for n in unknown)
            raise InputError(f"graph {self.name!r} has no input(s) {', '.join(map(repr, unknown))}{hints}; "
                               f"its inputs are: {', '.join(self.layout.in_columns) or 'none'}")
        missing = [n for n in self.layout.in_columns if n not in inputs]
        if missing:
            raise InputError(f"graph {self.name!r}: recording lacks input(s) {', '.join(missing)}")
        total = None
        arrays = {}
        for name, (_col, w) in self.layout.in_columns.items():
            arr = float_signal(name, inputs[name])
            shape = self.resolved.input_specs[name].shape
            flat_ok = arr.ndim == 2 and arr.shape[1] == w  # e.g. a CSV's name[0..k] columns
            if arr.ndim == 0 or (arr.shape[1:] != shape and not flat_ok):
                turned = "; pass its transpose (x.T): time goes first" if arr.ndim == 2 and arr.shape[::-1][1:] == shape else ""
                raise InputError(
                    f"input {name!r}: expected shape (n, {', '.join(map(str, shape))}) with time first, got {arr.shape}{turned}"
                    if shape else f"input {name!r}: expected a 1-D array over time, got shape {arr.shape}")
            if total is None:
                total = arr.shape[0]
            elif arr.shape[0] != total:
                raise InputError(f"input {name!r} has {arr.shape[0]} samples, others have {total}")
            arrays[name] = arr.reshape(arr.shape[0], w)
        if total is None:
            raise InputError(f"graph {self.name!r} has no inputs; pass n ticks with run_ticks(n) (or process_ticks(n) to continue)")
        return arrays, total

    def run_ticks(self, n: int, seed: int | None = None) -> dict[str, np.ndarray]:
        """Reset and run ``n`` ticks with every graph input held at zero (e.g. a noise generator)."""
        n = self._tick_count("run_ticks", n)
        self.reset(seed)
        return self.process_ticks(n)

    def process_ticks(self, n: int) -> dict[str, np.ndarray]:
        """Continue from the current state for ``n`` ticks with every graph input held at zero: to :meth:`run_ticks`
        what :meth:`process` is to :meth:`run` (``run_ticks(a)`` then ``process_ticks(b)`` equals ``run_ticks(a + b)``
        bit for bit), so a graph without inputs can be rendered in blocks."""
        n = self._tick_count("process_ticks", n)
        zeros = {name: np.zeros((n, w)) for name, (_col, w) in self.layout.in_columns.items()}
        return self._run_chunk(zeros, n, owned=True)

    def _tick_count(self, method: str, n: Any) -> int:
        """``n`` as a tick count for ``method``, refused in one line when it is not a whole number >= 0 or would not fit
        in memory."""
        n = whole_count("n", n, 0)
        check_ticks(f"graph {self.name!r}: {method} n", n, int(self.i[OUT_WIDTH]) + sum(w for _c, w in self.layout.in_columns.values()),
                    "run fewer ticks")
        return n


def _unpickled(resolved: ResolvedGraph, block_rows: int, tier: str, seed: int, f: np.ndarray, i: np.ndarray,
               held: dict[str, np.ndarray]) -> Graph:
    """A pickled :class:`Graph` rebuilt, its arenas (state, tick, held inputs) as they were when it was pickled."""
    graph = Graph(resolved, block_rows, tier)
    graph.seed, graph._held = seed, held
    graph.f[:], graph.i[:] = f, i  # the same resolved graph lays out the same arenas
    return graph


def load_graph(path: str | Path, overrides: Mapping[str, Any] | None = None,
               plugins: tuple[str | Path, ...] = (), block_rows: int = DEFAULT_BLOCK_ROWS, auto_plugins: bool = True,
               tier: str | None = None, before_compile: Callable[[ResolvedGraph], None] | None = None) -> Graph:
    """Read, check and compile the graph file at ``path``.

    ``before_compile`` is called with the checked graph before it is compiled: ``flowtex run`` reads and checks its
    recording there, so that a broken graph is said first and a broken recording before the compile's wait.

    ``tier`` is ``fused``, ``dispatch`` or ``auto`` (docs/engine.md; default
    ``$FLOWTEX_COMPILE`` or ``fused``). When ``auto`` picks ``dispatch``, the fused
    code is compiled for next time in a low-priority background process.

    ``overrides`` maps ``"node.param"`` to a value (as ``--set`` does);
    ``plugins`` adds plugin folders to ``$FLOWTEX_PLUGINS`` and the graph's own
    (its folder's ``plugins/`` and its ``plugins:`` key; ``auto_plugins=False``
    skips the graph's own, as ``--no-plugins``).
    Raises :class:`flowtex.errors.GraphError` listing every problem.
    """
    spec = load_spec(path, dict(overrides or {}))
    resolved = resolve_graph(spec, graph_registry(path, plugins, auto_plugins, spec.plugins))
    if before_compile is not None:
        before_compile(resolved)
    graph = Graph(resolved, block_rows, tier)
    if graph.requested_tier == "auto" and graph.tier == "dispatch":
        compile_in_background(path, dict(overrides or {}), plugins, block_rows, auto_plugins)
    return graph


def check_graph(path: str | Path, overrides: Mapping[str, Any] | None = None,
                plugins: tuple[str | Path, ...] = (), auto_plugins: bool = True) -> ResolvedGraph:
    """Validate without running: what ``flowtex validate`` does (plugin kernels are compiled for their actual ports)."""
    spec = load_spec(path, dict(overrides or {}))
    resolved = resolve_graph(spec, graph_registry(path, plugins, auto_plugins, spec.plugins))
    check_plugin_kernels(rn.cls for rn in resolved.nodes.values())  # validate compiles what it validates
    return resolved


def graph_registry(path: str | Path, plugins: tuple[str | Path, ...] = (), auto_plugins: bool = True,
                   own: Sequence[Path] | None = None) -> Registry:
    """The node registry a graph file is resolved with: ``plugins`` plus, with ``auto_plugins``, the graph's own plugin
    folders: its folder's ``plugins/`` (found wherever flowtex runs from) and ``own``, the folders of its ``plugins:``
    key (read from the file when None). ``.plugin_files`` lists the code it ran."""
    plugins = folder_list(plugins)
    if not auto_plugins:
        return load_registry(plugins)
    from .spec import read_plugin_folders

    beside = Path(path).parent / "plugins"
    folders = (*plugins, *(own if own is not None else read_plugin_folders(path)), *((beside,) if beside.is_dir() else ()))
    return load_registry(folders)
