"""``Node.processor()``: one node's build and kernel on plain arrays, state kept between calls.

The same Python build and the same compiled kernel that a graph runs, without a
graph: call the processor with arrays (one row per tick) and get the node's
outputs back; its state carries over to the next call, as an ezmsg processor's
does. Offline graphs, live graphs and processors all call one kernel, so they
cannot drift apart: a processor built with the graph's node name, rate, seed,
``every`` and input rates gives that node's output in the graph bit for bit. A
node that runs every k ticks runs its kernel on the ticks a graph runs it on and
holds its outputs in between, as the graph's generated schedule does.

The kernel gets the processor's own copy of every input, never the caller's
array: a kernel that writes its input (a plugin mistake) cannot change the
caller's data.
"""

from __future__ import annotations

import inspect
import math
import zlib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .dsp.nonfinite import NONFINITE_POLICIES, apply_nonfinite_policy
from .errors import DataError, FlowtexError, InputError, ParamError
from .limits import check_ticks, close_names, excerpt, port_values_problem
from .node_decl import BuildContext, PortSpec, expected_shape, suggest
from .node_params import checked_params, load_files
from .nodecheck import check_kernel_compiles, checked_outputs, is_plugin, plugin_raised, scheduled_every
from .pyvalues import float_signal, plain, whole_count
from .schema.core import Field, checked
from .schema.graph import GRAPH, NODE


def _params(cls: type, given: dict[str, Any], base_dir: Path) -> tuple[dict[str, Any], dict[str, Path]]:
    """Validated parameter values of node type ``cls`` with files read into objects, and the files read
    (flowtex.node_params); ParamError names the first wrong one, as a graph file's message does."""
    values, problems = checked_params(cls, {k: plain(v) for k, v in given.items()}, base_dir)
    if problems:
        raise ParamError(problems[0].key, f"node type {cls.type_name!r}: {problems[0].message}")
    try:
        return load_files(cls, values)
    except ParamError as exc:
        raise _labelled(cls, exc) from None


def _labelled(cls: type, exc: FlowtexError) -> FlowtexError:
    """``exc`` (raised by the node's own code: a file it reads, a value its ``resolve`` or ``build`` refuses) with the
    node type and the parameter it names in front, as a graph names the node and places it at the parameter's line."""
    param = getattr(exc, "param", None)
    text = f"node type {cls.type_name!r} processor: " + (f"parameter {param!r}: " if param else "") + str(exc)
    return ParamError(param, text) if isinstance(exc, ParamError) else DataError(text)  # a subclass may take other arguments


def given_params(cls: type, mapping: Any, keywords: dict[str, Any]) -> dict[str, Any]:
    """Node parameters given as ``params={...}`` and as keywords, merged; a parameter given both ways, or a ``params``
    that is not a mapping, is a :class:`ParamError`. ``params=`` reaches every parameter, including one named like a
    processor setting (``rate``, ``seed``, ...), which the keyword form cannot set."""
    where = f"node type {cls.type_name!r} processor"
    for key in keywords:  # a misspelt setting (rat=, evry=) is named as the setting, not as a node parameter
        meant = close_names(key, [*cls.params, *PROCESSOR_SETTINGS], 1) if key not in cls.params else []
        if meant and meant[0] in PROCESSOR_SETTINGS:
            raise ParamError(key, f"{where}: {key!r} is neither a parameter nor a setting (did you mean the setting "
                                  f"{meant[0]!r}?); settings: {', '.join(PROCESSOR_SETTINGS)}; parameters: "
                                  f"{', '.join(cls.params) or 'none'}")
    if mapping is None:
        return keywords
    if not isinstance(mapping, Mapping):
        raise ParamError("params", f"{where}: params must be a mapping of parameter name to value, e.g. "
                                   f"params={{'k': 2.0}}; got {excerpt(mapping)}")
    twice = [k for k in keywords if k in mapping]
    if twice:
        raise ParamError(twice[0], f"{where}: parameter {twice[0]!r} is given twice, as a keyword and in params=; give it once")
    return {**mapping, **keywords}


def _graph_setting(cls: type, key: str, value: Any, declared: Field, **fmt: Any) -> Any:
    """``value`` as a graph file's ``declared`` field reads it (flowtex.schema.graph: its kind, bounds and message), or a
    :class:`ParamError` naming ``key`` and the node type."""
    value, problem = checked(plain(value), declared, key=key, **fmt)
    if problem is not None:
        raise ParamError(key.split("[")[0], f"node type {cls.type_name!r} processor: {problem}")
    return value


def _settings(cls: type, rate: Any, seed: Any, name: Any, nonfinite: Any) -> tuple[float, int, str]:
    """``rate`` (Hz), ``seed`` and ``name`` checked as a graph file's ``rate``, ``seed`` and node name are."""
    rate = _graph_setting(cls, "rate", rate, GRAPH.keys["rate"])
    seed = _graph_setting(cls, "seed", seed, GRAPH.keys["seed"])
    where = f"node type {cls.type_name!r} processor"
    if name is not None and (not isinstance(name, str) or not name):
        raise ParamError("name", f"{where}: name must be a non-empty string (the node's name in a graph), got {excerpt(name)}")
    if nonfinite not in NONFINITE_POLICIES:
        raise ParamError("nonfinite", f"{where}: nonfinite must be one of {', '.join(NONFINITE_POLICIES)}, got {excerpt(nonfinite)}")
    return float(rate), seed, name or cls.type_name


INPUT_EVERY = replace(NODE.keys["every"], message="")
"""An ``input_every`` value: its producer's ``every``, bounded as a graph node's (the generic message names the input)."""


def _schedule(cls: type, name: str, values: dict[str, Any], rate: float, every: Any,
              input_every: Any) -> tuple[int, dict[str, int]]:
    """The node's ``every`` and its inputs' ``every`` (port -> the producer's divider, 1 for the base rate), as a
    graph resolves them: the node's own schedule (:meth:`Node.own_every`) wins over ``every=1``, and contradicts any
    other ``every`` in one error."""
    every = _graph_setting(cls, "every", every, NODE.keys["every"], name=name)
    if input_every is None:
        input_every = {}
    if not isinstance(input_every, Mapping):
        raise ParamError("input_every", f"node type {cls.type_name!r} processor: input_every must map input names to "
                                        f"their producer's every, e.g. {{'x': 4}}; got {excerpt(input_every)}")
    unknown = [k for k in input_every if k not in cls.inputs]
    if unknown:
        raise ParamError("input_every", f"node type {cls.type_name!r} has no input {unknown[0]!r}"
                                        f"{suggest(str(unknown[0]), list(cls.inputs))}; its inputs are: {', '.join(cls.inputs) or 'none'}")
    ports = {port: _graph_setting(cls, f"input_every[{port!r}]", input_every.get(port, 1), INPUT_EVERY) for port in cls.inputs}
    try:
        own = scheduled_every(cls, name, values, rate, ports)
    except ParamError as exc:
        raise _labelled(cls, exc) from None
    if own is not None and every not in (1, own):
        raise ParamError("every", f"node type {cls.type_name!r} processor: its parameters make it run every {own} ticks, "
                                  f"but every={every} was given; drop every=")
    return own or every, ports


def _as_rows(name: str, value: Any) -> np.ndarray:
    """A port's array as a new (ticks, width) float64 C-contiguous array (a 1-D array is one value per tick)."""
    x = float_signal(name, value)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise InputError(f"input {name!r}: pass one row per tick, shape (ticks,) or (ticks, width); got shape {x.shape}")
    return np.array(x, dtype=np.float64, order="C")  # a copy: the kernel never gets the caller's memory


class Processor:
    """A built node on plain arrays. Call it with one array per input (keyword = port name); it returns a dict
    of output arrays (ticks, width). Unconnected optional inputs read their declared default; a call without input
    arrays runs ``ticks=`` ticks (default 1).

    The node is built on the first call, for the widths of the arrays given then; each later call must give the same
    inputs with the same widths. ``nonfinite`` is what a call does with NaN/inf input samples, as in ``Graph.run``:
    ``error`` (refuse, naming the input; the default), ``zero``, ``hold`` (the last finite value, held from one call
    into the next) or ``pass``.
    Rows are ticks of the base ``rate``, as in a graph. ``every`` is the node's rate divider (a graph's ``every:``) and
    ``input_every`` each input's producer's (1: the input changes every tick); a node that runs every k ticks, by
    ``every`` or by its own schedule (``Node.own_every``), runs its kernel on ticks 0, k, 2k, ... counted from the
    first call (or :meth:`reset`) and holds its outputs in between, as a graph does.
    A call that raises leaves the state as it was before the call (a kernel that raised part-way included).
    """

    def __init__(self, cls: type, params: dict[str, Any], rate: float = 1000.0, seed: int = 0,
                 name: str | None = None, base_dir: str | Path = ".", nonfinite: str = "error", every: int = 1,
                 input_every: Mapping[str, int] | None = None):
        self.cls = cls
        rate, self.seed, self.name = _settings(cls, rate, seed, name, nonfinite)
        self.nonfinite = nonfinite
        values, files = _params(cls, params, Path(base_dir))
        self.every, ports_every = _schedule(cls, self.name, values, rate, every, input_every)
        self.context = BuildContext(rate=rate, base_dir=Path(base_dir), every=self.every, input_every=ports_every, files=files)
        self.node = self._node_call("__init__", cls, self.name, values, self.context)
        self.kernel = cls.get_kernel()
        self.input_specs: dict[str, PortSpec] | None = None
        self.output_specs: dict[str, PortSpec] = {}
        self._held: dict[str, np.ndarray] = {}
        """Input -> its last value after ``nonfinite="hold"``, held into the next call."""
        self._tick = 0
        """Ticks run since the build or the last reset: the schedule's phase for ``every`` > 1."""
        self._holds: dict[str, np.ndarray] = {}
        """Output -> its value at the node's last run (``every`` > 1), held over the ticks it does not run."""

    def _specs(self, arrays: dict[str, np.ndarray]) -> dict[str, PortSpec]:
        """Every input's spec, as the graph's resolver gives them: a given array's width checked against the declared
        shape (a kernel indexes its columns unchecked), an unconnected input its declared shape."""
        specs: dict[str, PortSpec] = {}
        for port_name, port in self.cls.inputs.items():
            want = expected_shape(port, specs)
            if port_name not in arrays:
                if not port.optional:
                    raise InputError(f"node type {self.cls.type_name!r}: input {port_name!r} is required "
                                     f"(inputs: {', '.join(self.cls.inputs)})")
                specs[port_name] = PortSpec(want or (), port.unit if port.unit not in ("*",) and not port.unit.startswith("=") else "")
                continue
            width = arrays[port_name].shape[1]
            if want is None:
                shape: tuple[int, ...] = () if width == 1 else (width,)
            elif math.prod(want) == width:
                shape = want
            else:
                takes = "1 value per tick (a scalar)" if want == () else f"{math.prod(want)} values per tick (shape {want})"
                raise InputError(f"node type {self.cls.type_name!r}: input {port_name!r} has {width} column(s), but the node "
                                 f"takes {takes} there; pass shape (ticks, {math.prod(want)})" + (
                                     f" (the shape of input {port.shape[1:]!r})" if isinstance(port.shape, str) else ""))
            problem = port_values_problem(shape)
            if problem:
                raise InputError(f"node type {self.cls.type_name!r}: input {port_name!r}: {problem}")
            specs[port_name] = PortSpec(shape, port.unit if port.unit not in ("*",) and not port.unit.startswith("=") else "")
        return specs

    def _build(self, arrays: dict[str, np.ndarray]) -> None:
        """Build the node for the inputs given; nothing is kept unless every step succeeds (a failed first call can be
        retried with other arrays)."""
        specs = self._specs(arrays)
        outputs = checked_outputs(self.cls, self.name, self._node_call("resolve", self.node.resolve, specs))  # a wrong result: at its line
        if is_plugin(self.cls):  # a kernel that does not compile: its own line and numba's reason, not a TypingError
            check_kernel_compiles(self.cls)
        for port_name, spec in outputs.items():
            problem = port_values_problem(spec.shape)
            if problem:
                raise InputError(f"node type {self.cls.type_name!r}: output {port_name!r}: {problem}")
        built = self._node_call("build", self.node.build, specs, outputs)
        p = np.ascontiguousarray(built.params, dtype=np.float64)
        s = np.ascontiguousarray(built.state, dtype=np.float64)
        si = np.ascontiguousarray(built.istate, dtype=np.int64)
        if self.cls.uses_seed:
            self.node.seed_state(s, si, np.random.SeedSequence([self.seed, zlib.crc32(self.name.encode())]))
        self.p, self.s, self.si = p, s, si
        self._initial = (s.copy(), si.copy())
        self.output_specs = outputs
        self._provided = set(arrays)
        self.input_specs = specs
        self._holds = {k: np.zeros(spec.width) for k, spec in outputs.items()}

    def _node_call(self, method: str, call: Any, *args: Any) -> Any:
        """``call(*args)``: the node's ``__init__``, ``resolve`` or ``build`` (``method``); what it refuses is raised with
        the node type and parameter in front, and a plugin's own exception at its line (as a graph reports both), never
        a bare message or traceback."""
        try:
            return call(*args)
        except (ParamError, DataError) as exc:
            raise _labelled(self.cls, exc) from None
        except FlowtexError:
            raise
        except Exception as exc:
            if not is_plugin(self.cls):
                raise  # flowtex's own bug: an internal error
            raise plugin_raised(self.cls, self.name, method, exc) from None

    def reset(self) -> None:
        """Back to the state right after build (as a graph's ``reset()``): the schedule starts again at tick 0."""
        self._held = {}
        self._tick = 0
        if self.input_specs is not None:
            self.s[:], self.si[:] = self._initial
            self._holds = {k: np.zeros(spec.width) for k, spec in self.output_specs.items()}

    def __call__(self, *args: Any, ticks: int | None = None, **inputs: Any) -> dict[str, np.ndarray]:
        """Run the node over ``inputs`` (port name -> array, one row per tick), or over ``ticks`` ticks when no input
        array is given (a generator; default 1); returns output name -> (ticks, width) array."""
        if args:
            raise InputError(f"node type {self.cls.type_name!r}: pass each input by its port name, e.g. "
                             f"{self.cls.inputs and next(iter(self.cls.inputs)) or 'x'}=array; its inputs are: "
                             f"{', '.join(self.cls.inputs) or 'none'}")
        unknown = [k for k in inputs if k not in self.cls.inputs]
        if unknown:
            raise InputError(f"node type {self.cls.type_name!r} has no input {unknown[0]!r}"
                             f"{suggest(unknown[0], list(self.cls.inputs))}; its inputs are: {', '.join(self.cls.inputs) or 'none'}")
        if ticks is not None:
            ticks = whole_count(f"node type {self.cls.type_name!r}: ticks (the number of ticks to run)", ticks, 0)
        held = dict(self._held)  # kept only if the call succeeds: a refused call leaves the held values as they were
        arrays = apply_nonfinite_policy({k: _as_rows(k, v) for k, v in inputs.items()}, self.nonfinite,
                                        fix="or build the processor with nonfinite='hold' or 'zero'", held=held)
        lengths = {a.shape[0] for a in arrays.values()}
        if len(lengths) > 1:
            raise InputError(f"node type {self.cls.type_name!r}: inputs have different numbers of ticks: "
                             + ", ".join(f"{k} {a.shape[0]}" for k, a in arrays.items()))
        if lengths and ticks is not None and ticks not in lengths:
            raise InputError(f"node type {self.cls.type_name!r}: ticks={ticks}, but the inputs have {next(iter(lengths))} "
                             "rows; drop ticks= (the inputs' rows are the ticks)")
        if self.input_specs is None:
            self._build(arrays)
        elif set(arrays) != self._provided:
            raise InputError(f"node type {self.cls.type_name!r}: call with the same inputs as the first call: "
                             f"{', '.join(sorted(self._provided)) or 'none'}")
        assert self.input_specs is not None
        n = next(iter(lengths)) if lengths else 1 if ticks is None else ticks
        if n > 1:  # n rows of outputs (and of defaulted inputs), whether the rows come from the inputs or from ticks=
            self._check_ticks(n)
        ports = []
        for port_name in self.cls.inputs:
            spec = self.input_specs[port_name]
            if port_name in arrays:
                if arrays[port_name].shape[1] != spec.width:
                    raise InputError(f"node type {self.cls.type_name!r}: input {port_name!r} has "
                                     f"{arrays[port_name].shape[1]} column(s); the processor was built for {spec.width}")
                ports.append(arrays[port_name])
            else:
                ports.append(np.tile(self.node.input_default(port_name, spec), (n, 1)))
        runs = None if self.every == 1 else np.arange((-self._tick) % self.every, n, self.every)  # ticks % every == 0
        if runs is not None:  # the ticks the node runs on: the kernel sees those rows only, as in a graph
            ports = [port[runs] for port in ports]
        rows = n if runs is None else runs.size
        outs = {k: np.zeros((rows, spec.width)) for k, spec in self.output_specs.items()}
        self._run_kernel(ports, outs)
        if runs is not None:
            outs = self._held_between_runs(outs, runs, n)
        self._tick += n
        self._held = held
        return outs

    def _check_ticks(self, n: int) -> None:
        """Refuse a call of ``n`` ticks (``ticks=n`` or inputs of ``n`` rows) whose arrays (defaulted inputs and outputs)
        would hold more than a recording may."""
        assert self.input_specs is not None
        per_tick = sum(spec.width for spec in self.output_specs.values()) + sum(spec.width for spec in self.input_specs.values())
        per_tick = max(per_tick, 1)  # a node without ports still schedules its ticks (every > 1: an index per run)
        check_ticks(f"node type {self.cls.type_name!r}: ticks", n, per_tick,
                    "run fewer ticks per call (the state carries over from one call to the next)")

    def _run_kernel(self, ports: list[np.ndarray], outs: dict[str, np.ndarray]) -> None:
        """One kernel call; if it raises, the state is put back as it was before the call."""
        before = (self.s.copy(), self.si.copy())
        try:
            self.kernel(self.p, self.s, self.si, *ports, *(outs[k] for k in self.cls.outputs))
        except Exception as exc:  # the kernel raised part-way: its state is spoilt, restore the state before this call
            self.s[:], self.si[:] = before
            if isinstance(exc, FlowtexError):
                raise
            raise FlowtexError(f"node type {self.cls.type_name!r}: its kernel raised {type(exc).__name__}: "
                               f"{str(exc).splitlines()[0] if str(exc) else ''}; the processor's state is as before this call") from exc

    def _held_between_runs(self, outs: dict[str, np.ndarray], runs: np.ndarray, n: int) -> dict[str, np.ndarray]:
        """Outputs for all ``n`` ticks from those of the ``runs`` ticks: each tick shows the node's last run up to it
        (before this call's first run, the value held from the previous call), as the graph's schedule copies it."""
        spans = np.diff(runs, prepend=0, append=n)  # ticks showing the held value, then each run's (n rows in all)
        full = {}
        for k, ran in outs.items():
            full[k] = np.repeat(np.vstack([self._holds[k][None, :], ran]), spans, axis=0)
            if runs.size:
                self._holds[k] = ran[-1].copy()
        return full


PROCESSOR_SETTINGS = (*(k for k in inspect.signature(Processor.__init__).parameters if k not in ("self", "cls", "params")),
                      "params")
"""The keywords ``Node.processor`` takes besides the node's parameters (what a misspelt keyword may have meant)."""
