"""Declarations of file formats (keys, kinds, bounds, choices, defaults, units, docs) and the one checker of them.

A file kind is declared once as a tree of :class:`Field` (one value) and :class:`Record` (a mapping with named
keys). The same declaration is used two ways:

* the loaders (graph, scene, device map, audio map, model set, pattern, tap library, friction file) check what they
  read with :func:`check_keys` and :func:`check_value`, and report every problem through one :class:`Collector`,
  which keeps ``file:line:col`` positions (from :mod:`flowtex.yamlsource`'s ``LocDict``/``LocList``);
* :mod:`flowtex.schema.jsonschema` turns it into a JSON Schema (draft 2020-12) for editors.

Messages are part of the declaration (``message``, ``unknown``, ``missing`` templates) so that each file kind keeps
its own wording. Templates are ``str.format`` strings; ``{got}`` is the offending value quoted by
:func:`flowtex.limits.excerpt`, ``{key}`` a key's excerpt, ``{name}`` a key's plain text, ``{hint}`` a did-you-mean.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from ..errors import DataError, Diagnostic, GraphError, Location
from ..limits import excerpt, suggest
from ..yamlsource import yaml_bool

Pos = tuple[int, int]
KINDS = ("number", "int", "bool", "str", "choice", "const", "list", "map", "record", "any_of", "any")


class _NoDefault:
    def __repr__(self) -> str:
        return "no default"


NO_DEFAULT: Any = _NoDefault()
INVALID: Any = type("Invalid", (), {"__repr__": lambda self: "invalid", "__bool__": lambda self: False})()
"""Returned by :func:`check_value` for a value that broke its declaration (the problem is already collected)."""


@dataclass(frozen=True)
class Field:
    """One value of a file: its kind, bounds, choices, default, unit and documentation.

    kind:
        ``number`` (finite int or float, never a bool), ``int`` (never a bool), ``bool``, ``str``, ``choice`` (one of
        ``choices``), ``const`` (``const``, as JSON compares: ``1.0`` is ``1``, ``true`` is not), ``list`` (of ``items``,
        length within ``length``), ``map`` (any keys matching ``names``, values ``values``), ``record`` (``record``),
        ``any_of`` (the first of ``of`` that fits), ``any`` (not checked). An ``int`` may be written as a float with
        no fraction (``4.0``, ``1e3``), as JSON Schema's ``integer`` allows; :func:`check_value` returns it as an int.
    message:
        The problem when the value breaks the declaration, a template with ``{got}``; empty: a generic sentence.
    """

    kind: str
    doc: str = ""
    unit: str = ""
    default: Any = NO_DEFAULT
    min: float | None = None
    max: float | None = None
    min_exclusive: bool = False
    max_exclusive: bool = False
    choices: tuple[Any, ...] = ()
    const: Any = None
    items: Field | None = None
    length: tuple[int, int | None] | None = None
    names: str | None = None
    """map: a regular expression every key must match (JSON Schema ``propertyNames``)."""
    values: Field | None = None
    record: Record | None = None
    of: tuple[Field, ...] = ()
    message: str = ""
    pattern: str | None = None
    """str: a regular expression the text must match (checked by editors; loaders parse the text themselves)."""
    missing: str = ""
    """The problem when this key is required and absent (overrides the record's ``missing``)."""
    json: Mapping[str, Any] | None = None
    """Extra JSON Schema keywords (merged last); for what a loader checks by code and editors should know too."""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"unknown field kind {self.kind!r}; use one of {KINDS}")

    def describe(self) -> str:
        """A short phrase such as ``a number > 0`` for generic messages."""
        return describe(self)


@dataclass(frozen=True)
class Record:
    """A mapping with declared keys: which exist, which are required, what an unknown or missing key says.

    unknown:
        Template for a key that is not declared: ``{key}`` (excerpt), ``{name}`` (text), ``{hint}`` (did-you-mean,
        from ``suggest``), ``{allowed}`` (the declared keys, comma-separated).
    legacy:
        Old spellings still read: ``{old: current}``; accepted by loaders and by the JSON Schema (marked deprecated).
    open:
        Undeclared keys are allowed (free-form metadata).
    """

    keys: Mapping[str, Field]
    required: tuple[str, ...] = ()
    doc: str = ""
    unknown: str = "unknown key {key}{hint}"
    missing: str = "missing key {name!r}"
    legacy: Mapping[str, str] = field(default_factory=dict)
    open: bool = False
    json: Mapping[str, Any] | None = None
    """Extra JSON Schema keywords for the mapping (e.g. ``oneOf`` of required keys that code checks)."""
    suggest: str = "close"
    """How a did-you-mean reads: ``close`` (only close names) or ``close_or_known`` (else the known names)."""

    def allowed(self) -> tuple[str, ...]:
        return (*self.keys, *self.legacy)


def describe(f: Field) -> str:
    if f.kind == "choice":
        return "one of " + ", ".join(map(str, f.choices))
    if f.kind == "const":
        return f"{f.const!r}"
    text = {"number": "a number", "int": "an integer", "bool": "true or false", "str": "a string", "list": "a list",
            "map": "a mapping", "record": "a mapping", "any": "anything"}.get(f.kind, "a value")
    if f.kind == "any_of":
        return " or ".join(describe(o) for o in f.of)
    bounds = []
    if f.min is not None:
        bounds.append(f"{'>' if f.min_exclusive else '>='} {f.min:g}")
    if f.max is not None:
        bounds.append(f"{'<' if f.max_exclusive else '<='} {f.max:g}")
    return text + (" " + ", ".join(bounds) if bounds else "")


class Collector:
    """The one diagnostic collector: problems as ``file:line:col: message``, raised together at the end.

    Positions are ``(line, column)`` pairs (1-based, as :mod:`flowtex.yamlsource` keeps them), a
    :class:`~flowtex.errors.Location`, or None (the file as a whole: JSON readers, which keep no positions).
    """

    def __init__(self, path: str):
        self.path = path
        self.diagnostics: list[Diagnostic] = []

    def loc(self, pos: Pos | Location | None) -> Location:
        if isinstance(pos, Location):
            return pos
        if pos is None:
            return Location(self.path)
        return Location(self.path, pos[0], pos[1])

    def error(self, pos: Pos | Location | None, message: str) -> None:
        self.diagnostics.append(Diagnostic(self.loc(pos), message))

    add = error

    def __len__(self) -> int:
        return len(self.diagnostics)

    def raise_if_any(self) -> None:
        """Raise every problem collected so far as one :class:`~flowtex.errors.GraphError`."""
        if self.diagnostics:
            raise GraphError(self.diagnostics)

    def raise_first_as_data_error(self) -> None:
        """Raise the first problem as a one-line :class:`~flowtex.errors.DataError` (how data-file readers report)."""
        if self.diagnostics:
            raise DataError(str(self.diagnostics[0]))


def is_number(v: Any) -> bool:
    """A finite int or float, never a bool."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return False
    try:
        return math.isfinite(v)
    except OverflowError:  # an int beyond float range
        return False


def _hint(record: Record, name: str) -> str:
    known = list(record.keys)
    hint = suggest(name, record.allowed())
    if not hint and record.suggest == "close_or_known" and known:
        return f"; known: {', '.join(known[:12])}"
    return hint


def check_unknown(c: Collector, data: Mapping[Any, Any], record: Record, **fmt: Any) -> bool:
    """Report every undeclared key of ``data`` (required keys are left to the caller's reader); True if none."""
    return check_keys(c, data, record, required=False, **fmt)


def check_keys(c: Collector, data: Mapping[Any, Any], record: Record, pos: Pos | None = None, required: bool = True,
               **fmt: Any) -> bool:
    """Report every undeclared key of ``data`` and every missing required key; True if none.

    ``fmt`` fills the record's templates (e.g. ``what=f"node {name!r}"``). Positions come from ``data.key_pos``
    when ``data`` is a ``LocDict``; a missing key is reported at ``pos`` (default: the mapping's own position).
    """
    key_pos = getattr(data, "key_pos", {})
    ok = True
    if not record.open:
        for key in data:
            if key not in record.keys and key not in record.legacy:
                name = str(key)
                c.error(key_pos.get(key), record.unknown.format(key=excerpt(key), name=name, hint=_hint(record, name),
                                                                allowed=", ".join(record.keys), **fmt))
                ok = False
    for old, new in record.legacy.items():
        if old in data and new in data:
            c.error(key_pos.get(old), f"{old!r} is the old spelling of {new!r}; give only {new!r}")
            ok = False
    for key in record.required if required else ():
        if key not in data and not any(old in data for old, new in record.legacy.items() if new == key):
            c.error(pos if pos is not None else getattr(data, "pos", None),
                    (record.keys[key].missing or record.missing).format(name=key, **fmt))
            ok = False
    return ok


def get(data: Mapping[Any, Any], record: Record, key: str) -> tuple[Any, str | None]:
    """``(value, spelling)`` of ``key`` in ``data``, also under a legacy spelling; ``(NO_DEFAULT, None)`` if absent."""
    if key in data:
        return data[key], key
    for old, new in record.legacy.items():
        if new == key and old in data:
            return data[old], old
    return NO_DEFAULT, None


def value_of(c: Collector, data: Mapping[Any, Any], record: Record, key: str, **fmt: Any) -> Any:
    """The checked value of ``key`` (or its default when absent); INVALID (problem collected) when it breaks its field."""
    f = record.keys[key]
    value, spelling = get(data, record, key)
    if spelling is None:
        return f.default
    pos = getattr(data, "value_pos", {}).get(spelling)
    return check_value(c, value, pos, f, key=spelling, **fmt)


def fits(value: Any, f: Field) -> bool:
    """True if ``value`` fits ``f`` (kind, bounds, choices, length, items, names, and a record's keys)."""
    return _problem(value, f) is None


def _problem(value: Any, f: Field) -> str | None:
    """None if ``value`` fits ``f``, else a generic phrase of what was expected."""
    k = f.kind
    if k == "any":
        return None
    if k == "any_of":
        return None if any(fits(value, o) for o in f.of) else f"expected {describe(f)}"
    if k == "const":
        return None if _same(value, f.const) else f"expected {f.const!r}"
    if k == "choice":
        return None if isinstance(value, str) and value in f.choices else f"expected {describe(f)}"
    if k == "bool":
        return None if yaml_bool(value) is not None else "expected true or false"
    if k == "str":
        if not isinstance(value, str):
            return "expected a string"
        if f.length is not None and len(value) < f.length[0]:
            return "expected a non-empty string"
        return None
    if k in ("number", "int"):
        if k == "int" and not _integral(value):
            return "expected an integer"
        if not is_number(value):
            return "expected a number"
        return _bounds(value, f)
    if k == "list":
        if not isinstance(value, list):
            return "expected a list"
        if f.length is not None:
            lo, hi = f.length
            if len(value) < lo or (hi is not None and len(value) > hi):
                return f"expected {lo} items" if lo == hi else f"expected {lo} to {hi if hi is not None else 'any number of'} items"
        if f.items is not None and not all(fits(v, f.items) for v in value):
            return f"expected a list of {describe(f.items)}"
        return None
    if k in ("map", "record"):
        if not isinstance(value, dict):
            return "expected a mapping"
        if k == "map":
            if f.length is not None and len(value) < f.length[0]:
                return "expected a non-empty mapping"
            if f.names is not None and not all(isinstance(n, str) and re.match(f.names, n) for n in value):
                return "a key is not a valid name"
            if f.values is not None and not all(fits(v, f.values) for v in value.values()):
                return f"expected values of {describe(f.values)}"
            return None
        rec = f.record
        if rec is None:
            return None
        if not rec.open and any(key not in rec.keys and key not in rec.legacy for key in value):
            return "unknown key"
        if any(key not in value for key in rec.required):
            return "missing key"
        for key, sub in rec.keys.items():
            if key in value and not fits(value[key], sub):
                return f"{key}: {_problem(value[key], sub)}"
        return None
    raise AssertionError(k)


def _same(value: Any, const: Any) -> bool:
    """JSON's equality: numbers by value (``1.0`` is ``1``), but a bool is no number (``true`` is not ``1``)."""
    if isinstance(value, bool) or isinstance(const, bool):
        return type(value) is type(const) and value == const
    if isinstance(const, (int, float)):
        return isinstance(value, (int, float)) and value == const
    return type(value) is type(const) and value == const


def _integral(value: Any) -> bool:
    """An int, or a float with no fraction within float's exact integers (``4.0``, ``1e3``), as JSON Schema's
    ``integer`` and ``Param(kind="int")`` take it; never a bool."""
    if isinstance(value, bool):
        return False
    return isinstance(value, int) or (isinstance(value, float) and value.is_integer() and abs(value) <= 2.0**53)


def _normalized(value: Any, f: Field) -> Any:
    """``value`` (which fits ``f``) with integral floats of ``int`` fields made ints, in lists and alternatives too."""
    if f.kind == "int":
        return int(value)
    if f.kind == "bool":
        return yaml_bool(value)  # a YAML 1.1 spelling (yes, off, ...) as its bool
    if f.kind == "list" and f.items is not None and (f.items.kind == "bool" or any(_integral(v) for v in value)):
        return [_normalized(v, f.items) for v in value]
    if f.kind == "any_of":
        return _normalized(value, next(o for o in f.of if fits(value, o)))
    return value


def _bounds(value: float, f: Field) -> str | None:
    if f.min is not None and (value < f.min or (f.min_exclusive and value == f.min)):
        return f"must be {'>' if f.min_exclusive else '>='} {f.min:g}"
    if f.max is not None and (value > f.max or (f.max_exclusive and value == f.max)):
        return f"must be {'<' if f.max_exclusive else '<='} {f.max:g}"
    return None


def checked(value: Any, f: Field, **fmt: Any) -> tuple[Any, str | None]:
    """(``value`` as ``f`` reads it, None) if it fits ``f``; else (INVALID, the field's message).

    ``fmt`` fills the message template (``{got}`` is always the value's excerpt). For values that come from Python
    rather than a file (``Node.processor``'s graph settings), with no position to collect them at.
    """
    problem = _problem(value, f)
    if problem is None:
        return _normalized(value, f), None
    got = ("true" if value else "false") if isinstance(value, bool) else excerpt(value)  # as the file spells it
    if f.message:
        return INVALID, f.message.format(got=got, **fmt)
    return INVALID, f"{fmt.get('key', 'value')}: {problem}, got {got}"


def check_value(c: Collector, value: Any, pos: Pos | Location | None, f: Field, **fmt: Any) -> Any:
    """``value`` if it fits ``f``; else the field's message is collected at ``pos`` and INVALID returned.

    ``fmt`` fills the message template (``{got}`` is always the value's excerpt).
    """
    value, problem = checked(value, f, **fmt)
    if problem is not None:
        c.error(pos, problem)
    return value
