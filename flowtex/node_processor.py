"""``Node.processor()``: one node's build and kernel on plain arrays, state kept between calls.

The same Python build and the same compiled kernel that a graph runs, without a
graph: call the processor with arrays (one row per tick) and get the node's
outputs back; its state carries over to the next call, as an ezmsg processor's
does. Offline graphs, live graphs and processors all call one kernel, so they
cannot drift apart: a processor built with the graph's node name, rate and seed
gives that node's output in the graph bit for bit.
"""

from __future__ import annotations

import math
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from .dsp.nonfinite import NONFINITE_POLICIES, apply_nonfinite_policy
from .errors import FlowtexError, InputError, ParamError
from .limits import MAX_RATE_HZ, excerpt, port_values_problem
from .node_decl import BuildContext, PortSpec, expected_shape, suggest
from .node_params import checked_params, load_files
from .nodecheck import check_kernel_compiles, checked_outputs, is_plugin
from .pyvalues import float_signal, plain


def _params(cls: type, given: dict[str, Any], base_dir: Path) -> tuple[dict[str, Any], dict[str, Path]]:
    """Validated parameter values of node type ``cls`` with files read into objects, and the files read
    (flowtex.node_params); ParamError names the first wrong one, as a graph file's message does."""
    values, problems = checked_params(cls, {k: plain(v) for k, v in given.items()}, base_dir)
    if problems:
        raise ParamError(problems[0].key, f"node type {cls.type_name!r}: {problems[0].message}")
    return load_files(cls, values)


def _settings(cls: type, rate: Any, seed: Any, name: Any, nonfinite: Any) -> tuple[float, int, str]:
    """``rate`` (Hz), ``seed`` and ``name`` checked as a graph file's ``rate``, ``seed`` and node name are."""
    rate, seed = plain(rate), plain(seed)
    where = f"node type {cls.type_name!r} processor"
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate <= MAX_RATE_HZ:
        raise ParamError("rate", f"{where}: rate must be a number of Hz in (0, {MAX_RATE_HZ:g}], got {excerpt(rate)}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ParamError("seed", f"{where}: seed must be a non-negative integer, got {excerpt(seed)}")
    if name is not None and (not isinstance(name, str) or not name):
        raise ParamError("name", f"{where}: name must be a non-empty string (the node's name in a graph), got {excerpt(name)}")
    if nonfinite not in NONFINITE_POLICIES:
        raise ParamError("nonfinite", f"{where}: nonfinite must be one of {', '.join(NONFINITE_POLICIES)}, got {excerpt(nonfinite)}")
    return float(rate), seed, name or cls.type_name


def _as_rows(name: str, value: Any) -> np.ndarray:
    """A port's array as (ticks, width) float64, C-contiguous (a 1-D array is one value per tick)."""
    x = float_signal(name, value)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise InputError(f"input {name!r}: pass one row per tick, shape (ticks,) or (ticks, width); got shape {x.shape}")
    return np.ascontiguousarray(x)


class Processor:
    """A built node on plain arrays. Call it with one array per input (keyword = port name); it returns a dict
    of output arrays (ticks, width). Unconnected optional inputs read their declared default.

    The node is built on the first call, for the widths of the arrays given then; each later call must give the same
    inputs with the same widths. ``nonfinite`` is what a call does with NaN/inf input samples, as in ``Graph.run``:
    ``error`` (refuse, naming the input; the default), ``zero``, ``hold`` (the last finite value, held from one call
    into the next) or ``pass``.
    A call that raises leaves the state as it was before the call (a kernel that raised part-way included).
    """

    def __init__(self, cls: type, params: dict[str, Any], rate: float = 1000.0, seed: int = 0,
                 name: str | None = None, base_dir: str | Path = ".", nonfinite: str = "error"):
        self.cls = cls
        rate, self.seed, self.name = _settings(cls, rate, seed, name, nonfinite)
        self.nonfinite = nonfinite
        values, files = _params(cls, params, Path(base_dir))
        self.context = BuildContext(rate=rate, base_dir=Path(base_dir), files=files)
        self.node = cls(self.name, values, self.context)
        self.kernel = cls.get_kernel()
        self.input_specs: dict[str, PortSpec] | None = None
        self.output_specs: dict[str, PortSpec] = {}
        self._held: dict[str, np.ndarray] = {}
        """Input -> its last value after ``nonfinite="hold"``, held into the next call."""

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
        outputs = checked_outputs(self.cls, self.name, self.node.resolve(specs))  # a wrong result: at its resolve() line
        if is_plugin(self.cls):  # a kernel that does not compile: its own line and numba's reason, not a TypingError
            check_kernel_compiles(self.cls)
        for port_name, spec in outputs.items():
            problem = port_values_problem(spec.shape)
            if problem:
                raise InputError(f"node type {self.cls.type_name!r}: output {port_name!r}: {problem}")
        built = self.node.build(specs, outputs)
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

    def reset(self) -> None:
        """Back to the state right after build (as a graph's ``reset()``)."""
        self._held = {}
        if self.input_specs is not None:
            self.s[:], self.si[:] = self._initial

    def __call__(self, *args: Any, **inputs: Any) -> dict[str, np.ndarray]:
        if args:
            raise InputError(f"node type {self.cls.type_name!r}: pass each input by its port name, e.g. "
                             f"{self.cls.inputs and next(iter(self.cls.inputs)) or 'x'}=array; its inputs are: "
                             f"{', '.join(self.cls.inputs) or 'none'}")
        unknown = [k for k in inputs if k not in self.cls.inputs]
        if unknown:
            raise InputError(f"node type {self.cls.type_name!r} has no input {unknown[0]!r}"
                             f"{suggest(unknown[0], list(self.cls.inputs))}; its inputs are: {', '.join(self.cls.inputs) or 'none'}")
        arrays = apply_nonfinite_policy({k: _as_rows(k, v) for k, v in inputs.items()}, self.nonfinite,
                                        fix="or build the processor with nonfinite='hold' or 'zero'", held=self._held)
        lengths = {a.shape[0] for a in arrays.values()}
        if len(lengths) > 1:
            raise InputError(f"node type {self.cls.type_name!r}: inputs have different numbers of ticks: "
                             + ", ".join(f"{k} {a.shape[0]}" for k, a in arrays.items()))
        if self.input_specs is None:
            self._build(arrays)
        elif set(arrays) != self._provided:
            raise InputError(f"node type {self.cls.type_name!r}: call with the same inputs as the first call: "
                             f"{', '.join(sorted(self._provided)) or 'none'}")
        assert self.input_specs is not None
        n = lengths.pop() if lengths else 1
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
        outs = {k: np.zeros((n, spec.width)) for k, spec in self.output_specs.items()}
        before = (self.s.copy(), self.si.copy())
        try:
            self.kernel(self.p, self.s, self.si, *ports, *(outs[k] for k in self.cls.outputs))
        except Exception as exc:  # the kernel raised part-way: its state is spoilt, restore the state before this call
            self.s[:], self.si[:] = before
            if isinstance(exc, FlowtexError):
                raise
            raise FlowtexError(f"node type {self.cls.type_name!r}: its kernel raised {type(exc).__name__}: "
                               f"{str(exc).splitlines()[0] if str(exc) else ''}; the processor's state is as before this call") from exc
        return outs
