"""Declared memory layouts: a node's (or a dsp kernel's) state as named fields, declared once.

A :class:`Layout` lists named fields of one array (float64 state, int64 state or
parameters), each a scalar or a sub-array whose length is a number or an
expression of build-time sizes (``"L"``, ``"p + 1"``). From that one
declaration come

* the array size and a zeroed array (:meth:`Layout.size`, :meth:`Layout.zeros`),
* each field's offset and slice in Python (:meth:`Layout.bind`),
* constant offsets that kernels use as globals, for the fields that precede every
  variable-length field (:meth:`Layout.const`), and
* a generated numba function returning every offset from the sizes
  (:meth:`Layout.kernel_offsets`), so a kernel never adds lengths by hand.

Nothing here imports numba until :meth:`Layout.kernel_offsets` is called, and
nothing indexes memory with a literal: a field that grows (say the random
generator's words) moves every field after it, in Python and in kernels alike.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

_DTYPES = {"float": np.float64, "int": np.int64}
_BOUND_KEEP = 256  # bind() answers kept per layout (distinct sizes seen in one process; then it starts again)


@dataclass(frozen=True)
class Field:
    """One named field: ``size`` values (an int, or an expression of the layout's sizes such as ``"p + 1"``)."""

    name: str
    size: int | str = 1
    doc: str = ""


def _check_expression(text: str, names: tuple[str, ...]) -> None:
    """Refuse a size expression that is not arithmetic on the declared size names (it is evaluated and compiled)."""
    allowed = (ast.Expression, ast.BinOp, ast.Add, ast.Sub, ast.Mult, ast.FloorDiv, ast.Constant, ast.Name, ast.Load,
               ast.Call, ast.UnaryOp, ast.USub)
    for node in ast.walk(ast.parse(text, mode="eval")):
        if not isinstance(node, allowed):
            raise ValueError(f"layout size {text!r}: only + - * // max() min() on {', '.join(names)} are allowed")
        if isinstance(node, ast.Name) and node.id not in names + ("max", "min"):
            raise ValueError(f"layout size {text!r} names {node.id!r}; declared sizes: {', '.join(names) or 'none'}")
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in ("max", "min")):
            raise ValueError(f"layout size {text!r}: only max() and min() may be called")


class Layout:
    """The fields of one array, in order. ``sizes`` names the build-time sizes; ``derived`` defines more from them.

    Example (the ARMA synthesizer's int state)::

        ISTATE = Layout("int", [Field("rng", 5), Field("active"), Field("trial_ok")])
        ISTATE.const("active")   # 5: usable as a global constant inside an @njit kernel
    """

    def __init__(self, kind: str, fields: list[Field], sizes: tuple[str, ...] = (),
                 derived: Mapping[str, str] | None = None):
        if kind not in _DTYPES:
            raise ValueError(f"layout kind {kind!r}: use 'float' or 'int'")
        self.kind = kind
        self.fields = tuple(fields)
        self.sizes = tuple(sizes)
        self.derived = dict(derived or {})
        names = [f.name for f in self.fields]
        if len(set(names)) != len(names):
            raise ValueError(f"layout declares a field twice: {sorted({n for n in names if names.count(n) > 1})}")
        known = self.sizes
        for name, text in self.derived.items():
            _check_expression(text, known)
            known = known + (name,)
        self._names = known
        for f in self.fields:
            if isinstance(f.size, str):
                _check_expression(f.size, known)
            elif not isinstance(f.size, int) or isinstance(f.size, bool) or f.size < 0:
                raise ValueError(f"layout field {f.name!r}: size {f.size!r} is not a count")
        # the checked expressions compiled once (eval of a string parses it on every call), and each bind's
        # answer kept per sizes: node builds and dsp helpers bind the same few sizes again and again
        self._derived_code = {name: compile(text, f"<layout size {name}>", "eval") for name, text in self.derived.items()}
        self._size_code = {f.name: compile(f.size, f"<layout size {f.name}>", "eval")
                           for f in self.fields if isinstance(f.size, str)}
        self._bound: dict[tuple[tuple[str, int], ...], dict[str, slice]] = {}

    # ----------------------------------------------------------------- Python side
    def _dims(self, sizes: Mapping[str, int]) -> dict[str, int]:
        missing = [s for s in self.sizes if s not in sizes]
        if missing:
            raise ValueError(f"layout needs the sizes {', '.join(missing)}")
        dims = {s: int(sizes[s]) for s in self.sizes}
        for name, code in self._derived_code.items():
            dims[name] = int(eval(code, {"max": max, "min": min}, dims))  # checked by _check_expression
        return dims

    def bind(self, **sizes: int) -> dict[str, slice]:
        """Each field's slice of the array for these sizes, in declaration order (a new dict, the caller's to change)."""
        key = tuple((s, int(sizes[s])) for s in self.sizes if s in sizes)
        known = self._bound.get(key) if len(key) == len(self.sizes) else None
        if known is not None:
            return dict(known)
        dims = self._dims(sizes)
        out, at = {}, 0
        for f in self.fields:
            n = f.size if isinstance(f.size, int) else int(eval(self._size_code[f.name], {"max": max, "min": min}, dims))
            if n < 0:
                raise ValueError(f"layout field {f.name!r}: size {f.size!r} is {n} for {sizes}")
            out[f.name] = slice(at, at + n)
            at += n
        if len(self._bound) >= _BOUND_KEEP:
            self._bound.clear()
        self._bound[key] = out
        return dict(out)

    def size(self, **sizes: int) -> int:
        """Length of the array for these sizes."""
        slices = self.bind(**sizes)
        return max((s.stop for s in slices.values()), default=0)

    def zeros(self, **sizes: int) -> np.ndarray:
        """A zeroed array of this layout for these sizes."""
        return np.zeros(self.size(**sizes), dtype=_DTYPES[self.kind])

    def pack(self, values: Mapping[str, Any] | None = None, **sizes: int) -> np.ndarray:
        """An array of this layout for these sizes: zeros, with each field named in ``values`` set.

        A scalar value fills its whole field; an array must have the field's length (ValueError naming the field).
        """
        slices = self.bind(**sizes)
        out = np.zeros(max((s.stop for s in slices.values()), default=0), dtype=_DTYPES[self.kind])
        for name, value in (values or {}).items():
            if name not in slices:
                raise KeyError(f"layout has no field {name!r}; fields: {', '.join(f.name for f in self.fields)}")
            where = slices[name]
            data = np.asarray(value, dtype=out.dtype)
            if data.ndim == 0:
                out[where] = data
                continue
            data = data.ravel()
            if data.size != where.stop - where.start:
                raise ValueError(f"layout field {name!r} holds {where.stop - where.start} values for {sizes}, given {data.size}")
            out[where] = data
        return out

    def const(self, name: str) -> int:
        """Offset of ``name`` when every field before it has a fixed length (a constant kernels may use)."""
        at = 0
        for f in self.fields:
            if f.name == name:
                return at
            if not isinstance(f.size, int):
                raise ValueError(f"layout field {name!r} follows the variable-length field {f.name!r}: "
                                 f"use kernel_offsets()")
            at += f.size
        raise KeyError(f"layout has no field {name!r}; fields: {', '.join(f.name for f in self.fields)}")

    def describe(self) -> list[str]:
        """One line per field (name, length, doc) for ``flowtex nodes`` and docs."""
        return [f"{f.name}[{f.size}]" + (f": {f.doc}" if f.doc else "") for f in self.fields]

    # ----------------------------------------------------------------- kernel side
    def offsets_source(self, func_name: str = "offsets") -> str:
        """Python source of ``func_name(*sizes)`` returning (derived sizes..., offset of each field...)."""
        lines = [f"def {func_name}({', '.join(self.sizes)}):"]
        for name, text in self.derived.items():
            lines.append(f"    {name} = {text}")
        at = "0"
        names = []
        for f in self.fields:
            var = f"o_{f.name}"
            lines.append(f"    {var} = {at}")
            names.append(var)
            at = f"{var} + ({f.size})"
        lines.append(f"    return ({', '.join(list(self.derived) + names)},)")
        return "\n".join(lines) + "\n"

    def kernel_offsets(self) -> Callable[..., Any]:
        """A numba function (inlined into its callers) computing :meth:`offsets_source`'s tuple from the sizes."""
        from numba import njit

        namespace: dict[str, Any] = {}
        exec(compile(self.offsets_source(), f"<layout {self.kind}: {', '.join(f.name for f in self.fields)}>", "exec"),
             {"max": max, "min": min}, namespace)
        return njit(inline="always")(namespace["offsets"])


@dataclass(frozen=True)
class Memory:
    """A node's memory declared once: its parameters ``p`` and float state ``s`` (float layouts), its int state ``si``.

    Each layout takes the build-time sizes it declares (``sizes=``) from one mapping, so a node states its sizes
    once per build (:meth:`pack`), and checks can compare what a build packed with what was declared (:meth:`sizes`).
    """

    params: Layout = Layout("float", [])
    state: Layout = Layout("float", [])
    istate: Layout = Layout("int", [])

    def __post_init__(self) -> None:
        for name, want in (("params", "float"), ("state", "float"), ("istate", "int")):
            if getattr(self, name).kind != want:
                raise ValueError(f"Memory {name}: declare a {want!r} layout, got {getattr(self, name).kind!r}")

    def _pick(self, layout: Layout, sizes: Mapping[str, int]) -> dict[str, int]:
        return {name: sizes[name] for name in layout.sizes if name in sizes}

    def pack(self, sizes: Mapping[str, int] | None = None, params: Mapping[str, Any] | np.ndarray | None = None,
             state: Mapping[str, Any] | np.ndarray | None = None, istate: Mapping[str, Any] | np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(p, s, si) for these build-time sizes, each packed from its field values (:meth:`Layout.pack`).

        An array instead of a mapping is one a helper already packed with the same layout: it is taken as it is,
        after checking that its length is the declared one (ValueError otherwise).
        """
        sizes = dict(sizes or {})
        unknown = sorted(set(sizes) - set(self.params.sizes + self.state.sizes + self.istate.sizes))
        if unknown:
            raise ValueError(f"memory declares no size {', '.join(unknown)}")
        out = []
        for name, layout, values in (("params", self.params, params), ("state", self.state, state),
                                     ("istate", self.istate, istate)):
            dims = self._pick(layout, sizes)
            if isinstance(values, np.ndarray):
                array = np.ascontiguousarray(values, dtype=_DTYPES[layout.kind]).ravel()
                if array.size != layout.size(**dims):
                    raise ValueError(f"{name}: {array.size} values packed, the declared layout holds {layout.size(**dims)} "
                                     f"for {dims}")
                out.append(array)
            else:
                out.append(layout.pack(values, **dims))
        return out[0], out[1], out[2]

    def sizes(self, sizes: Mapping[str, int] | None = None) -> tuple[int, int, int]:
        """Lengths of (p, s, si) for these build-time sizes."""
        sizes = dict(sizes or {})
        return (self.params.size(**self._pick(self.params, sizes)), self.state.size(**self._pick(self.state, sizes)),
                self.istate.size(**self._pick(self.istate, sizes)))
