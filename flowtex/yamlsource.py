"""Safe YAML loading that remembers where every key and value came from.

PyYAML's safe loader silently keeps the last of two equal keys and forgets
positions, and reads YAML 1.1's on/off/yes/no as booleans. Here only true/false are booleans (YAML 1.2's core schema,
:data:`BOOL_12`; :func:`yaml_bool` takes the 1.1 spellings where a bool is expected), numbers with an exponent are
numbers as in YAML 1.2 (:data:`FLOAT_12`), Here mappings become :class:`LocDict` and sequences
:class:`LocList`; both remember the (line, column) of each key and value so
that later checks can say ``graph.yaml:14:7: ...``. Duplicate keys and any
tag that would build a Python object are errors.

Bounded: nesting deeper than :data:`flowtex.limits.MAX_DEPTH` and documents
whose aliases expand to more than :data:`flowtex.limits.MAX_YAML_NODES` values
(an "alias bomb") are refused after parsing and before any Python value is built;
a recursive alias (``&a [*a]``) too. Messages quote values with :func:`flowtex.limits.excerpt`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from .errors import Diagnostic, GraphError, Location
from .limits import MAX_DEPTH, MAX_YAML_BYTES, MAX_YAML_INT, MAX_YAML_NODES, excerpt, not_regular

Pos = tuple[int, int]
FLOAT_12 = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")
"""A float with an exponent as YAML 1.2's core schema and JSON write it (``1e6``, ``-3.5E2``, ``.5e-3``)."""
BOOL_12 = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")
"""A boolean as YAML 1.2's core schema writes it: the only unquoted words flowtex's YAML reader reads as booleans."""
YAML11_BOOLS: dict[str, bool] = {**dict.fromkeys(("yes", "Yes", "YES", "on", "On", "ON"), True),
                                 **dict.fromkeys(("no", "No", "NO", "off", "Off", "OFF"), False)}
"""The other spellings PyYAML's YAML 1.1 rules read as booleans: strings to flowtex's reader, booleans where a
parameter or key expects one (:func:`yaml_bool`)."""


def yaml_bool(value: Any) -> bool | None:
    """``value`` where a bool is expected: a bool as itself, a YAML 1.1 spelling (:data:`YAML11_BOOLS`) as the bool it
    spelled; None for anything else (``1``, ``"y"``, ``"maybe"``)."""
    if isinstance(value, bool):
        return value
    return YAML11_BOOLS.get(value) if isinstance(value, str) else None



class LocDict(dict):
    """A dict with ``key_pos[key]`` and ``value_pos[key]`` (1-based line, column)."""

    pos: Pos = (0, 0)

    def __init__(self) -> None:
        super().__init__()
        self.key_pos: dict[Any, Pos] = {}
        self.value_pos: dict[Any, Pos] = {}


class LocList(list):
    """A list with ``item_pos[i]`` (1-based line, column)."""

    pos: Pos = (0, 0)

    def __init__(self) -> None:
        super().__init__()
        self.item_pos: list[Pos] = []


def _pos(node: yaml.Node) -> Pos:
    return node.start_mark.line + 1, node.start_mark.column + 1


class _TooLarge(Exception):
    """The document breaks a limit; ``mark`` is where (or None)."""

    def __init__(self, message: str, mark: Any = None):
        super().__init__(message)
        self.mark = mark


def _children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def check_expansion(root: yaml.Node, max_nodes: int = MAX_YAML_NODES, max_depth: int = MAX_DEPTH) -> None:
    """Refuse a composed YAML tree whose aliases expand past ``max_nodes`` values or ``max_depth`` levels, or recurse.

    Shared (aliased) nodes are counted once per reference, as a reader of the
    built value would see them, but each node is visited once (memoised), so the
    check costs the size of the file, not of the expansion.
    """
    memo: dict[int, tuple[int, int]] = {}  # id(node) -> (expanded values, expanded depth)
    on_path: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            on_path.discard(key)
            kids = [memo[id(c)] for c in _children(node)]
            size = 1 + sum(k[0] for k in kids)
            depth = 1 + max((k[1] for k in kids), default=0)
            if size > max_nodes:
                raise _TooLarge(f"this document holds more than {max_nodes:,} values, counting each alias (*name) "
                                "in full; use fewer nested aliases, or keep large data in a data file", node.start_mark)
            if depth > max_depth:
                raise _TooLarge(f"aliases (*name) nest this document more than {max_depth} levels deep; "
                                "flowtex files nest a few levels", node.start_mark)
            memo[key] = (size, depth)
            continue
        if key in memo:
            continue
        if key in on_path:
            raise _TooLarge("an alias (*name) refers to the value that contains it; remove the recursive alias", node.start_mark)
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in _children(node) if id(c) not in memo)


class _Loader(yaml.SafeLoader):
    """Safe loader building LocDict/LocList, refusing duplicate keys, deep nesting and alias bombs."""

    def __init__(self, stream: str, path: str):
        super().__init__(stream)
        self.path = path
        self.problems: list[Diagnostic] = []
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise _TooLarge(f"lists and maps nest more than {MAX_DEPTH} levels deep here; flowtex files nest a few levels "
                                "(is this the right file?)", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_data(self) -> Any:
        node = self.get_single_node()
        if node is None:
            return None
        check_expansion(node)
        return self.construct_document(node)

    def construct_loc_mapping(self, node: yaml.MappingNode) -> LocDict:
        result = LocDict()
        result.pos = _pos(node)
        self.flatten_mapping(node)
        for key_node, value_node in node.value:
            key = self.construct_object(key_node, deep=True)
            if not isinstance(key, (str, int, float, bool)) and key is not None:
                self.problems.append(Diagnostic(Location(self.path, *_pos(key_node)), "mapping keys must be plain scalars"))
                continue
            if key in result:
                first = result.key_pos[key]
                self.problems.append(Diagnostic(
                    Location(self.path, *_pos(key_node)),
                    f"duplicate key {key!r} (first defined at line {first[0]}); remove or rename one of them",
                ))
                continue
            result[key] = self.construct_object(value_node, deep=True)
            result.key_pos[key] = _pos(key_node)
            result.value_pos[key] = _pos(value_node)
        return result

    def construct_loc_sequence(self, node: yaml.SequenceNode) -> LocList:
        result = LocList()
        result.pos = _pos(node)
        for child in node.value:
            result.append(self.construct_object(child, deep=True))
            result.item_pos.append(_pos(child))
        return result


    def construct_bounded_int(self, node: yaml.ScalarNode) -> int:
        """An integer, refused beyond 1e300 (past any float; numeric checks compare ints with floats)."""
        try:
            value = self.construct_yaml_int(node)
        except ValueError:  # more digits than Python converts
            value = None
        if value is None or abs(value) >= MAX_YAML_INT:
            digits = node.value if len(node.value) <= 24 else node.value[:20] + "..."
            raise _TooLarge(f"the integer {digits} ({len(node.value)} digits) is too large (at most 1e300)", node.start_mark)
        return value

_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_bounded_int)
# Numbers as YAML 1.2 and JSON write them: PyYAML's YAML 1.1 float needs a dot and a signed exponent, so ``1e6``,
# ``3e2`` and ``3.0e2`` would be strings. (Ints, ``.inf`` and the 1.1 forms resolve as before.)
_Loader.add_implicit_resolver("tag:yaml.org,2002:float", FLOAT_12, list("-+0123456789."))
# Booleans as YAML 1.2's core schema and JSON write them: only true/false (True, TRUE, False, FALSE). PyYAML's YAML 1.1
# rules also read on/off/yes/no as booleans, so a node named `on` or a choice `no` became True/False; those are strings
# now. Where a bool is expected, the 1.1 spellings are still taken (yaml_bool), so files written for them keep working.
_BOOL = "tag:yaml.org,2002:bool"
_Loader.yaml_implicit_resolvers = {first: [(tag, rx) for tag, rx in resolvers if tag != _BOOL]
                                   for first, resolvers in _Loader.yaml_implicit_resolvers.items()}
_Loader.add_implicit_resolver(_BOOL, BOOL_12, list("tTfF"))
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _Loader.construct_loc_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _Loader.construct_loc_sequence)


def read_source(path: Path, kind: str) -> str:
    """The text of the YAML file ``path`` (a ``kind`` such as "graph file"); one-line :class:`GraphError` if it cannot be.

    Refuses a missing file, a folder, a file larger than :data:`flowtex.limits.MAX_YAML_BYTES` and text that is not UTF-8.
    """
    where = Location(str(path))
    special = not_regular(path, kind)
    if special is not None:
        raise GraphError([Diagnostic(where, special)])
    try:
        size = path.stat().st_size
        if size > MAX_YAML_BYTES:
            raise GraphError([Diagnostic(where, f"{kind} is {size / 2**20:.1f} MiB; flowtex reads {kind}s up to "
                                                f"{MAX_YAML_BYTES / 2**20:g} MiB (is this the right file?)")])
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise GraphError([Diagnostic(where, f"{kind} not found")]) from None
    except UnicodeDecodeError as exc:
        raise GraphError([Diagnostic(where, f"{kind} is not UTF-8 text (byte {exc.start}); save it as UTF-8")]) from None
    except OSError as exc:
        raise GraphError([Diagnostic(where, f"cannot read {kind}: {exc.strerror or exc}")]) from None


def parse_value(text: str, where: str) -> Any:
    """A value given on the command line (``--set``, ``--knob``): YAML if it parses, else the text itself.

    The limits and tag refusals of :func:`load_yaml` still apply (raised as
    :class:`GraphError` naming ``where``); only a syntax error falls back to the text.
    """
    return load_yaml(text, where, text_if_invalid=True) if text.strip() else ""


def load_yaml(text: str, path: str, text_if_invalid: bool = False) -> Any:
    """Parse ``text`` (from file ``path``) into LocDict/LocList/scalars.

    Raises :class:`GraphError` for syntax errors (unless ``text_if_invalid``:
    then ``text`` itself is returned), duplicate keys, unsafe or unknown tags,
    and documents past the limits.
    """
    try:
        loader = _Loader(text, path)
    except yaml.reader.ReaderError as exc:
        raise GraphError([Diagnostic(_reader_loc(text, path, exc), _reader_message(exc))]) from None
    try:
        data = loader.get_single_data()
    except _TooLarge as exc:
        raise GraphError([Diagnostic(_loc(path, exc.mark), str(exc))]) from None
    except yaml.reader.ReaderError as exc:
        raise GraphError([Diagnostic(_reader_loc(text, path, exc), _reader_message(exc))]) from None
    except yaml.constructor.ConstructorError as exc:
        mark = exc.problem_mark or exc.context_mark
        tag = ""
        if exc.problem and "tag" in exc.problem:
            tag = exc.problem.split("tag", 1)[1].strip(" '!")
        msg = f"YAML tag {excerpt(tag)} is not allowed: graph files may only hold plain data (maps, lists, strings, numbers)"
        raise GraphError([Diagnostic(_loc(path, mark), msg)]) from None
    except yaml.MarkedYAMLError as exc:
        if text_if_invalid:
            return text
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or "invalid YAML"
        context = f" ({exc.context})" if exc.context else ""
        raise GraphError([Diagnostic(_loc(path, mark), f"YAML syntax error: {problem}{context}")]) from None
    except yaml.YAMLError as exc:
        raise GraphError([Diagnostic(Location(path), f"YAML error: {excerpt(' '.join(str(exc).split()), 200)}")]) from None
    finally:
        loader.dispose()
    if loader.problems:
        raise GraphError(loader.problems)
    return data


def _loc(path: str, mark: Any) -> Location:
    if mark is None:
        return Location(path)
    return Location(path, mark.line + 1, mark.column + 1)


def _reader_message(exc: yaml.reader.ReaderError) -> str:
    char = exc.character
    code = f"#x{ord(char):04x}" if isinstance(char, str) else f"#x{char:04x}" if isinstance(char, int) else "?"
    return f"character {code} is not allowed in YAML (binary data or a NUL byte?); remove it or save the file as UTF-8 text"


def _reader_loc(text: str, path: str, exc: yaml.reader.ReaderError) -> Location:
    """Line and column of a ReaderError (which reports only an offset into ``text``)."""
    before = text[: max(0, exc.position)]
    line = before.count("\n") + 1
    return Location(path, line, len(before) - (before.rfind("\n") + 1) + 1)
