"""Node declarations: parameters, ports, port specs, build context and state (what a node type declares).

Split from :mod:`flowtex.node_api` (which re-exports every name here) so that code running a node without a
graph (:mod:`flowtex.node_processor`) needs the declarations, not the Node class.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ParamError
from .limits import MAX_INT_PARAM, excerpt, short_number, suggest
from .yamlsource import yaml_bool


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
    objects:
        For ``path``: types of an already loaded object the parameter takes instead of a file (the in-memory API,
        e.g. a ``TextureModelSet`` for ``models``); such a value is passed to the node as it is. A file given
        instead is read into that object before the node is built, by the format registry's reader of the type
        (flowtex.io.formats.OBJECT_FORMATS), so the node always receives the object.
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
    objects: tuple[type, ...] = ()

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
            flag = yaml_bool(value)  # true/false, or a YAML 1.1 spelling (yes, off, ...) that files written for it use
            if flag is not None:
                return flag
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
        if kind == "path" and self.objects and isinstance(value, self.objects):
            return value
        if kind in ("str", "path"):
            if not isinstance(value, str) or not value:
                takes = " or a loaded " + " or ".join(t.__name__ for t in self.objects) if kind == "path" and self.objects else ""
                raise ValueError(f"expected a non-empty string{' (a file path)' if kind == 'path' else ''}{takes}, "
                                 f"got {excerpt(value)}")
            if kind == "path":
                try:
                    path = Path(value).expanduser()
                except RuntimeError:  # '~user/...' of a user that does not exist (or no home folder)
                    raise ValueError(f"cannot expand the '~' of {excerpt(value)}: no such user's home folder; give the full path") from None
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
    files: dict[str, Path] = field(default_factory=dict)
    """Parameter -> the file its object was read from at the graph/io boundary (flowtex.node_params.load_files), for
    messages; a parameter given a loaded object in memory is absent."""

    @property
    def node_rate(self) -> float:
        return self.rate / self.every


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


def expected_shape(port: Port, specs: Mapping[str, PortSpec]) -> tuple[int, ...] | None:
    """The shape input ``port`` takes, given the specs of the inputs resolved before it; None: any shape.

    A ``"=name"`` shape is that input's (any shape while ``name`` is not resolved yet). The one rule the graph's
    resolver (:mod:`flowtex.graph.ports`) and ``Node.processor`` check arriving shapes against.
    """
    shape = port.shape
    if isinstance(shape, str):
        ref = specs.get(shape[1:])
        return ref.shape if ref is not None else None
    return tuple(shape) if shape is not None else None


def outputs_problem(declared: Sequence[str], specs: object) -> str | None:
    """What is wrong with ``specs`` as what :meth:`Node.resolve` returns for outputs ``declared`` (a :class:`PortSpec`
    of a shape of positive integers for each of them, nothing else), or None. The kernel is called with exactly the
    declared outputs, so a missing or extra one would fail later, far from the mistake."""
    if not isinstance(specs, dict):
        return f"returned {excerpt(specs)}, not a dict"
    missing = [n for n in declared if n not in specs]
    extra = [n for n in specs if n not in declared]
    if missing or extra:
        return "returned " + "; ".join(part for part in (
            f"no spec for output(s) {', '.join(map(repr, missing))}" if missing else "",
            f"spec(s) for undeclared output(s) {', '.join(map(repr, extra))}" if extra else "") if part)
    for name, spec in specs.items():
        if not isinstance(spec, PortSpec):
            return f"returned {excerpt(spec)} for output {name!r}, not a PortSpec"
        if not isinstance(spec.shape, tuple) or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 1
                                                        for n in spec.shape):
            return f"returned shape {excerpt(spec.shape)} for output {name!r}; a shape is a tuple of positive integers such as () or (3,)"
    return None


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


def check(condition: bool, param: str | None, message: str) -> None:
    """Raise :class:`ParamError` for ``param`` unless ``condition`` holds."""
    if not condition:
        raise ParamError(param, message)
