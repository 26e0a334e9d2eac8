"""A node's parameter values: checked against its declaration, then files read into the objects the node takes.

The one owner of both steps, used where a graph is resolved (:mod:`flowtex.graph.resolve`, which places each
problem at its line of the graph file) and by ``Node.processor`` (:mod:`flowtex.node_processor`, which raises the
first). :func:`checked_params` coerces every value (kinds, bounds, choices, lengths; defaults filled in) and names
unknown, invalid and missing parameters. :func:`load_files` is the graph/io boundary: a path given to a parameter
declared ``Param("path", objects=(T,))`` is read by T's reader from the format registry
(:data:`flowtex.io.formats.OBJECT_FORMATS`), so a node receives the loaded object and never opens a file.
"""

from __future__ import annotations

import difflib
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import FlowtexError, ParamError
from .node_decl import suggest


@dataclass(frozen=True)
class ParamProblem:
    """One wrong parameter: ``key`` as given, ``message`` without the node's name, ``given`` False for a missing one."""

    key: Any
    message: str
    given: bool = True


def checked_params(cls: type, given: Mapping[Any, Any], base_dir: Path | None,
                   from_here: Collection[str] = ()) -> tuple[dict[str, Any], list[ParamProblem]]:
    """Coerced values of node type ``cls``'s parameters (defaults filled in) and the problems, in the order found.

    Unknown keys (with a suggestion, or the list of parameters) and invalid values come first, in ``given``'s
    order, then missing required parameters (not reported when an unknown key looks like a misspelling of one).
    Relative paths resolve against ``base_dir``, those of the keys in ``from_here`` (given on the command line) against
    the current folder. The values are complete only when there is no problem.
    """
    values: dict[str, Any] = {}
    problems: list[ParamProblem] = []
    misspelt: set[str] = set()
    for key, value in given.items():
        decl = cls.params.get(key) if isinstance(key, str) else None
        if decl is None:
            misspelt.update(difflib.get_close_matches(str(key), list(cls.params), n=3, cutoff=0.6))
            hint = suggest(str(key), list(cls.params)) or f"; parameters are: {', '.join(cls.params) or 'none'}"
            problems.append(ParamProblem(key, f"unknown parameter {key!r}{hint}"))
            continue
        try:
            values[key] = decl.coerce(value, Path.cwd() if key in from_here else base_dir)
        except ValueError as exc:
            problems.append(ParamProblem(key, f"parameter {key!r} {exc} (expected {decl.describe_type()})"))
    for key, decl in cls.params.items():
        if key in values or key in given:
            continue
        if decl.required:
            if key not in misspelt:
                problems.append(ParamProblem(key, f"missing required parameter {key!r} ({decl.describe_type()}: {decl.doc})", False))
        else:
            values[key] = decl.coerce(decl.default, base_dir) if decl.default is not None else None
    return values, problems


def load_files(cls: type, values: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Path]]:
    """``values`` with every file given to an object-taking parameter read into its object, and param -> file read.

    A parameter declared ``Param("path", objects=(T, ...))`` whose value is a path is read by the format registry's
    reader of T (:func:`flowtex.io.formats.object_reader`); an object given as it is, and a path parameter whose
    types have no reader (a plugin's own file), are left alone, except that an object with a ``validate()`` method (a
    ``TextureModelSet`` built in memory) is checked by it, as its reader checks a file. The node type's ``check_params`` runs first, so a
    rule between parameters is reported before a file is read. A file that cannot be read raises
    :class:`ParamError` naming the parameter, with the reader's message (file, key or element, and the fix).
    """
    from .io.formats import object_reader

    cls.check_params(dict(values))
    loaded = dict(values)
    files: dict[str, Path] = {}
    for key, decl in cls.params.items():
        value = values.get(key)
        if decl.kind == "path" and decl.objects and isinstance(value, decl.objects) and callable(getattr(value, "validate", None)):
            try:  # an object built in memory gets the checks its file would (validate() only makes its arrays float64)
                loaded[key] = value.validate()
            except FlowtexError as exc:
                raise ParamError(key, str(exc)) from None
            continue
        if decl.kind != "path" or not decl.objects or not isinstance(value, Path):
            continue
        reader = object_reader(decl.objects)
        if reader is None:
            continue
        try:
            loaded[key] = reader(value)
        except FlowtexError as exc:
            raise ParamError(key, str(exc)) from None
        files[key] = value
    return loaded, files
