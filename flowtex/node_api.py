"""The node contract: declared ports and parameters, build-time Python, a numba kernel.

A node type is a subclass of :class:`Node` with a ``type_name``. It declares

* ``params``: ``{name: Param}`` -- typed, bounded, documented; validated before
  the node is constructed, so ``__init__`` sees clean values in ``self.p``;
* ``inputs`` / ``outputs``: ``{name: Port}`` -- shape and unit of each port;
* ``kernel``: a numba ``@njit`` function called once per block of ticks.

Kernel calling convention (the same offline and live)::

    kernel(p, s, si, in_1, ..., in_k, out_1, ..., out_m)

``p`` (float64[:]) holds the node's parameter values, ``s`` (float64[:]) its
float state and ``si`` (int64[:]) its integer state, all as returned by
:meth:`Node.build`. Each port is a C-contiguous float64 array of shape
``(n, width)``: row ``t`` is tick ``t`` of the block, ``width`` is the product
of the port's shape (1 for a scalar). ``n`` is 1 when the graph is stepped
live and up to the block size offline; a kernel must give the same numbers
either way. Kernels must not allocate.

Build-time Python (``__init__``, :meth:`Node.resolve`, :meth:`Node.build`)
runs once per graph build: load files, design filters, size the state.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .cache import configure_numba_cache
from .errors import ParamError
from .limits import MAX_INT_PARAM, excerpt, short_number

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)


class _Required:
    def __repr__(self) -> str:
        return "required"


REQUIRED: Any = _Required()

PARAM_KINDS = ("float", "int", "bool", "str", "path", "choice", "floats")


@dataclass(frozen=True)
class Param:
    """A node parameter, declared once and used for validation, docs and ``flowtex nodes``.

    kind:
        ``float``, ``int``, ``bool``, ``str``, ``path`` (a file, resolved
        against the graph file's folder), ``choice`` (one of ``choices``), or
        ``floats`` (a number or a list of numbers whose length is in
        ``length``).
    min, max:
        Inclusive bounds unless ``min_exclusive`` / ``max_exclusive``.
    """

    kind: str
    default: Any = REQUIRED
    doc: str = ""
    unit: str = ""
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = False
    max_exclusive: bool = False
    choices: tuple[str, ...] = ()
    length: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        """Refuse a declaration no value could satisfy (raised where the plugin declares it: its file and line)."""
        if self.kind not in PARAM_KINDS:
            raise ValueError(f"unknown parameter kind {self.kind!r}; use one of {', '.join(PARAM_KINDS)}")
        for bound in ("min", "max"):
            value = getattr(self, bound)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value)):
                raise ValueError(f"Param {bound}={excerpt(value)} is not a number")
        if self.min is not None and self.max is not None and (
                self.min > self.max or (self.min == self.max and (self.min_exclusive or self.max_exclusive))):
            raise ValueError(f"Param min={self.min:g} and max={self.max:g} leave no allowed value; swap them")
        if self.kind == "choice" and not self.choices:
            raise ValueError("Param kind 'choice' needs choices=('a', 'b', ...)")
        if not self.required and self.default is not None and self.kind not in ("path",):
            try:
                self.coerce(self.default)
            except ValueError as exc:
                raise ValueError(f"Param default {excerpt(self.default)}: {exc}") from None

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def describe_type(self) -> str:
        """A short human description such as ``float > 0`` or ``lowpass|highpass``."""
        if self.kind == "choice":
            return "|".join(self.choices)
        text = self.kind
        if self.kind == "floats" and self.length is not None:
            lo, hi = self.length
            text = "number" if hi == 1 else f"number or list of {lo}..{hi} numbers"
        bounds = []
        if self.min is not None:
            bounds.append(f"{'>' if self.min_exclusive else '>='} {self.min:g}")
        if self.max is not None:
            bounds.append(f"{'<' if self.max_exclusive else '<='} {self.max:g}")
        return text + (" " + ", ".join(bounds) if bounds else "")

    def coerce(self, value: Any, base_dir: Path | None = None) -> Any:
        """Return ``value`` converted to this parameter's Python type.

        Raises ``ValueError`` with a message fit for a user.
        """
        kind = self.kind
        if kind == "bool":
            if isinstance(value, bool):
                return value
            raise ValueError(f"expected true or false, got {excerpt(value)}")
        if kind == "int":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"expected an integer, got {excerpt(value)}")
            if isinstance(value, float) and not value.is_integer():
                raise ValueError(f"expected an integer, got {excerpt(value)}")
            if isinstance(value, float) and abs(value) > 2.0**53:
                raise ValueError(f"{value:g} is too large for an integer parameter")
            value = int(value)
            self._check_bounds(value)
            return value
        if kind == "float":
            return self._coerce_number(value)
        if kind == "floats":
            values = value if isinstance(value, (list, tuple)) else [value]
            out = tuple(self._coerce_number(v) for v in values)
            if self.length is not None:
                lo, hi = self.length
                if not lo <= len(out) <= hi:
                    want = str(lo) if lo == hi else f"{lo} to {hi}"
                    raise ValueError(f"expected {want} numbers, got {len(out)}")
            return out
        if kind == "choice":
            if not isinstance(value, str) or value not in self.choices:
                hint = suggest(value, self.choices) if isinstance(value, str) else ""
                raise ValueError(f"expected one of {', '.join(self.choices)}, got {excerpt(value)}{hint}")
            return value
        if kind in ("str", "path"):
            if not isinstance(value, str) or not value:
                raise ValueError(f"expected a non-empty string, got {excerpt(value)}")
            if kind == "path":
                path = Path(value).expanduser()
                if not path.is_absolute() and base_dir is not None:
                    path = base_dir / path
                return path
            return value
        raise AssertionError(kind)

    def _coerce_number(self, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"expected a number, got {excerpt(value)}")
        try:
            number = float(value)
        except OverflowError:  # an integer beyond 1.8e308
            number = math.inf
        if not math.isfinite(number):
            raise ValueError(f"expected a finite number, got {excerpt(value, 24)}")
        self._check_bounds(number)
        return number

    def _check_bounds(self, value: float) -> None:
        if self.kind == "int" and self.max is None and value > MAX_INT_PARAM:
            raise ValueError(f"must be <= {MAX_INT_PARAM} (the largest integer parameter), got {short_number(value)}")
        if self.min is not None:
            if value < self.min or (self.min_exclusive and value == self.min):
                op = ">" if self.min_exclusive else ">="
                raise ValueError(f"must be {op} {self.min:g}, got {short_number(value)}")
        if self.max is not None:
            if value > self.max or (self.max_exclusive and value == self.max):
                op = "<" if self.max_exclusive else "<="
                raise ValueError(f"must be {op} {self.max:g}, got {short_number(value)}")


@dataclass(frozen=True)
class Port:
    """A declared input or output.

    shape:
        A tuple (``()`` is a scalar, ``(3,)`` a 3-vector), ``None`` for "any
        shape" (inputs only), or ``"=name"``: the same shape as input ``name``.
    unit:
        A unit string (``""`` is dimensionless), ``"*"`` for "any unit"
        (inputs only), or ``"=name"``: the same unit as input ``name``.
    optional:
        Inputs only: may be left unconnected; then it reads
        :meth:`Node.input_default`.
    """

    shape: tuple[int, ...] | str | None = ()
    unit: str = ""
    doc: str = ""
    optional: bool = False
    default: float = 0.0
    shape_doc: str = ""
    """How the shape is set when the node's ``resolve`` computes it (shown by ``flowtex nodes``), e.g. ``"p+1, from the model file"``."""
    unit_doc: str = ""
    """How the unit is set when ``resolve`` computes it, e.g. ``"unit of x per second"``."""

    def describe(self) -> str:
        shape = "any shape" if self.shape is None else (
            f"shape of {self.shape[1:]}" if isinstance(self.shape, str) else
            ("scalar" if self.shape == () else "x".join(map(str, self.shape))))
        shape = self.shape_doc or shape
        unit = {"*": "any unit", "": "dimensionless"}.get(self.unit, self.unit)
        if self.unit.startswith("="):
            unit = f"unit of {self.unit[1:]}"
        unit = self.unit_doc or unit
        return f"{shape}, {unit}" + (", optional" if self.optional else "")


@dataclass(frozen=True)
class PortSpec:
    """A resolved port: concrete shape and unit."""

    shape: tuple[int, ...] = ()
    unit: str = ""

    @property
    def width(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64)) if self.shape else 1

    def describe(self) -> str:
        shape = "scalar" if not self.shape else "x".join(map(str, self.shape))
        return f"{shape} [{self.unit or 'dimensionless'}]"


@dataclass
class NodeState:
    """What :meth:`Node.build` returns: the arrays the kernel receives.

    ``params``, ``state`` are float64; ``istate`` is int64. Their contents are
    the initial values restored by ``reset()``.
    """

    params: np.ndarray = field(default_factory=lambda: np.zeros(0))
    state: np.ndarray = field(default_factory=lambda: np.zeros(0))
    istate: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


@dataclass(frozen=True)
class BuildContext:
    """Facts about the graph a node is built into."""

    rate: float
    """Base tick rate of the graph in Hz."""
    base_dir: Path
    """Folder of the graph file; relative ``path`` parameters resolve against it."""
    every: int = 1
    """This node runs every ``every`` ticks, so its own rate is ``rate / every``."""
    input_every: dict[str, int] = field(default_factory=dict)
    """Connected input port -> ``every`` of the node (or 1 for a graph input) that produces it:
    the input's sample rate is ``rate / input_every[port]``."""

    @property
    def node_rate(self) -> float:
        return self.rate / self.every


class Node:
    """Base class of every node type. See the module docstring for the contract."""

    type_name: ClassVar[str] = ""
    params: ClassVar[dict[str, Param]] = {}
    inputs: ClassVar[dict[str, Port]] = {}
    outputs: ClassVar[dict[str, Port]] = {}
    version: ClassVar[str] = "1"
    kernel: ClassVar[Callable[..., None]]
    uses_seed: ClassVar[bool] = False
    """True for nodes with random state; they implement :meth:`seed_state`."""
    breaks_cycles: ClassVar[bool] = False
    """True for pure delays: output at tick t depends only on inputs before t.

    Such nodes also provide ``emit_kernel(p, s, si, out)`` and
    ``absorb_kernel(p, s, si, inp)`` used when the graph has a feedback loop.
    """

    latency_doc: ClassVar[str] = ""
    """How the node's latency follows from its parameters (shown by ``flowtex nodes``); see :meth:`latency_samples`."""

    def __init__(self, name: str, params: dict[str, Any], context: BuildContext):
        self.name = name
        self.p = params
        self.context = context

    @classmethod
    def summary(cls) -> str:
        """First line of the class docstring."""
        doc = (cls.__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""

    @classmethod
    def get_kernel(cls, attr: str = "kernel") -> Callable[..., None]:
        for klass in cls.__mro__:
            if attr in klass.__dict__:
                value = klass.__dict__[attr]
                return value.__func__ if isinstance(value, staticmethod) else value
        raise AttributeError(f"node type {cls.type_name!r} defines no {attr}")

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        """Shapes and units of the outputs, given those of the connected inputs.

        The default follows the declared ``Port`` shapes and units (with
        ``"=name"`` references). Override when an output depends on a
        parameter (for example on the order of a loaded model). Raise
        :class:`ParamError` for an input the node cannot accept.
        """
        return {name: resolve_declared(port, inputs) for name, port in self.outputs.items()}

    @classmethod
    def own_every(cls, params: dict[str, Any], rate: float, input_every: dict[str, int]) -> int | None:
        """Ticks between runs for a node whose parameters and inputs fix its schedule (e.g. ``resample``), else None.

        ``params`` are validated; ``rate`` is the graph's base rate in Hz;
        ``input_every`` is as in :attr:`BuildContext.input_every`. The
        graph then runs the node every that many ticks (a different ``every:``
        in the graph file is an error). Raise :class:`ParamError` for a rate
        that does not divide the base rate.
        """
        return None

    def latency_samples(self) -> int:
        """Fixed delay from input to output, in ticks of this node (0: none, the default).

        Nodes that work on frames or FIR filters override it; ``flowtex graph``
        states it in samples and milliseconds. Called after construction, with
        ``self.p`` and ``self.context`` set.
        """
        return 0

    def input_default(self, name: str, spec: PortSpec) -> np.ndarray:
        """Value an unconnected optional input reads (shape ``spec.width``)."""
        return np.full(spec.width, self.inputs[name].default, dtype=np.float64)

    def build(self, inputs: dict[str, PortSpec], outputs: dict[str, PortSpec]) -> NodeState:
        """Allocate parameter and state arrays for the kernel."""
        return NodeState()

    def seed_state(self, state: np.ndarray, istate: np.ndarray, seed: np.random.SeedSequence) -> None:
        """Re-seed random state in place (only for ``uses_seed`` nodes)."""
        raise NotImplementedError


def resolve_declared(port: Port, inputs: dict[str, PortSpec]) -> PortSpec:
    """Resolve a declared output port against resolved input specs."""
    shape = port.shape
    unit = port.unit
    if isinstance(shape, str):
        shape = inputs[shape[1:]].shape
    if unit.startswith("="):
        unit = inputs[unit[1:]].unit
    if shape is None:
        raise TypeError("output ports must declare a shape")
    return PortSpec(tuple(shape), unit)


def unit_product(a: str, b: str) -> str:
    """Unit of a product, simplified: dimensionless factors drop out, powers combine (``mm/s``, ``mm/s`` -> ``mm^2/s^2``)."""
    if not a:
        return simplify_unit(b)
    if not b:
        return simplify_unit(a)
    return simplify_unit(f"{a}*{b}")


_UNIT_FACTOR = re.compile(r"^([A-Za-z_%°µΩ][A-Za-z0-9_%°µΩ]*)(?:\^(-?\d+))?$")


def simplify_unit(unit: str) -> str:
    """Collect powers of a unit written with ``*``, ``/`` and integer ``^n``: ``mm/s*mm/s`` -> ``mm^2/s^2``.

    Read left to right (``a/b*c`` is ``a*c/b``); factors keep the order of their
    first appearance, cancelled factors drop out, ``1`` and empty factors are
    dimensionless. The result has the numerator, then each denominator factor
    after a ``/`` (``N/mm/s``; ``1/s`` when nothing is left above). A unit this
    grammar cannot read (parentheses, decimals, ``*``/``=`` wildcards) is returned unchanged.
    """
    if not unit or unit == "*" or unit.startswith("="):
        return unit
    powers: dict[str, int] = {}
    tokens = re.split(r"([*/])", unit.replace(" ", ""))
    for k in range(0, len(tokens), 2):
        part = tokens[k]
        sign = -1 if k > 0 and tokens[k - 1] == "/" else 1
        if part == "1":
            continue
        m = _UNIT_FACTOR.match(part)
        if m is None:
            return unit
        powers[m.group(1)] = powers.get(m.group(1), 0) + sign * int(m.group(2) or 1)

    def power(name: str, n: int) -> str:
        return name if n == 1 else f"{name}^{n}"
    top = "*".join(power(n, e) for n, e in powers.items() if e > 0)
    bottom = "".join("/" + power(n, -e) for n, e in powers.items() if e < 0)
    if not top and not bottom:
        return ""
    return (top or "1") + bottom


def suggest(word: str, candidates: Sequence[str]) -> str:
    """A ``" (did you mean 'x'?)"`` hint, or ``""`` when nothing is close."""
    close = difflib.get_close_matches(word, list(candidates), n=3, cutoff=0.6)
    if not close:
        return ""
    return " (did you mean " + " or ".join(repr(c) for c in close) + "?)"


def check(condition: bool, param: str | None, message: str) -> None:
    """Raise :class:`ParamError` for ``param`` unless ``condition`` holds."""
    if not condition:
        raise ParamError(param, message)
