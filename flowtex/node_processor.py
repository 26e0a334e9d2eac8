"""``Node.processor()``: one node's build and kernel on plain arrays, state kept between calls.

The same Python build and the same compiled kernel that a graph runs, without a
graph: call the processor with arrays (one row per tick) and get the node's
outputs back; its state carries over to the next call, as an ezmsg processor's
does. Offline graphs, live graphs and processors all call one kernel, so they
cannot drift apart: a processor built with the graph's node name, rate and seed
gives that node's output in the graph bit for bit.
"""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ParamError
from .node_decl import BuildContext, PortSpec, suggest
from .node_params import checked_params, load_files


def _params(cls: type, given: dict[str, Any], base_dir: Path) -> tuple[dict[str, Any], dict[str, Path]]:
    """Validated parameter values of node type ``cls`` with files read into objects, and the files read
    (flowtex.node_params); ParamError names the first wrong one, as a graph file's message does."""
    values, problems = checked_params(cls, given, base_dir)
    if problems:
        raise ParamError(problems[0].key, f"node type {cls.type_name!r}: {problems[0].message}")
    return load_files(cls, values)


def _as_rows(name: str, value: Any) -> np.ndarray:
    """A port's array as (ticks, width) float64, C-contiguous (a 1-D array is one value per tick)."""
    x = np.asarray(value, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2:
        raise ValueError(f"input {name!r}: pass one row per tick, shape (ticks,) or (ticks, width); got {x.shape}")
    return np.ascontiguousarray(x)


class Processor:
    """A built node on plain arrays. Call it with one array per input (keyword = port name); it returns a dict
    of output arrays (ticks, width). Unconnected optional inputs read their declared default."""

    def __init__(self, cls: type, params: dict[str, Any], rate: float = 1000.0, seed: int = 0,
                 name: str | None = None, base_dir: str | Path = "."):
        self.cls = cls
        self.name = name or cls.type_name
        self.seed = int(seed)
        values, files = _params(cls, params, Path(base_dir))
        self.context = BuildContext(rate=float(rate), base_dir=Path(base_dir), files=files)
        self.node = cls(self.name, values, self.context)
        self.kernel = cls.get_kernel()
        self.input_specs: dict[str, PortSpec] | None = None
        self.output_specs: dict[str, PortSpec] = {}

    def _build(self, arrays: dict[str, np.ndarray]) -> None:
        specs = {}
        for port_name, port in self.cls.inputs.items():
            if port_name in arrays:
                width = arrays[port_name].shape[1]
                declared = port.shape if isinstance(port.shape, tuple) else None
                shape = declared if declared is not None and int(np.prod(declared)) == width else (() if width == 1 else (width,))
                specs[port_name] = PortSpec(shape, port.unit)
            elif not port.optional:
                raise ValueError(f"node type {self.cls.type_name!r}: input {port_name!r} is required "
                                 f"(inputs: {', '.join(self.cls.inputs)})")
        self.output_specs = self.node.resolve(specs)
        full = dict(specs)
        for port_name, port in self.cls.inputs.items():
            if port_name not in full:
                full[port_name] = PortSpec(port.shape if isinstance(port.shape, tuple) else (), port.unit)
        self.input_specs = full
        built = self.node.build(specs, self.output_specs)
        self.p = np.ascontiguousarray(built.params, dtype=np.float64)
        self.s = np.ascontiguousarray(built.state, dtype=np.float64)
        self.si = np.ascontiguousarray(built.istate, dtype=np.int64)
        if self.cls.uses_seed:
            self.node.seed_state(self.s, self.si, np.random.SeedSequence([self.seed, zlib.crc32(self.name.encode())]))
        self._initial = (self.s.copy(), self.si.copy())
        self._provided = set(specs)

    def reset(self) -> None:
        """Back to the state right after build (as a graph's ``reset()``)."""
        if self.input_specs is not None:
            self.s[:], self.si[:] = self._initial

    def __call__(self, **inputs: Any) -> dict[str, np.ndarray]:
        unknown = [k for k in inputs if k not in self.cls.inputs]
        if unknown:
            raise ValueError(f"node type {self.cls.type_name!r} has no input {unknown[0]!r}"
                             f"{suggest(unknown[0], list(self.cls.inputs))}; its inputs are: {', '.join(self.cls.inputs)}")
        arrays = {k: _as_rows(k, v) for k, v in inputs.items()}
        lengths = {a.shape[0] for a in arrays.values()}
        if len(lengths) > 1:
            raise ValueError(f"inputs have different numbers of ticks: {sorted(lengths)}")
        if self.input_specs is None:
            self._build(arrays)
        elif set(arrays) != self._provided:
            raise ValueError(f"call with the same inputs as the first call: {', '.join(sorted(self._provided))}")
        n = lengths.pop() if lengths else 1
        ports = []
        for port_name in self.cls.inputs:
            spec = self.input_specs[port_name]
            if port_name in arrays:
                if arrays[port_name].shape[1] != spec.width:
                    raise ValueError(f"input {port_name!r}: width {arrays[port_name].shape[1]}, built for {spec.width}")
                ports.append(arrays[port_name])
            else:
                ports.append(np.tile(self.node.input_default(port_name, spec), (n, 1)))
        outs = {k: np.zeros((n, spec.width)) for k, spec in self.output_specs.items()}
        self.kernel(self.p, self.s, self.si, *ports, *(outs[k] for k in self.cls.outputs))
        return outs
