"""Safe YAML loading that remembers where every key and value came from.

PyYAML's safe loader silently keeps the last of two equal keys and forgets
positions. Here mappings become :class:`LocDict` and sequences
:class:`LocList`; both remember the (line, column) of each key and value so
that later checks can say ``graph.yaml:14:7: ...``. Duplicate keys and any
tag that would build a Python object are errors.
"""

from __future__ import annotations

from typing import Any

import yaml

from .errors import Diagnostic, GraphError, Location

Pos = tuple[int, int]


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


class _Loader(yaml.SafeLoader):
    """Safe loader building LocDict/LocList and refusing duplicate keys."""

    def __init__(self, stream: str, path: str):
        super().__init__(stream)
        self.path = path
        self.problems: list[Diagnostic] = []

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


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _Loader.construct_loc_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _Loader.construct_loc_sequence)


def load_yaml(text: str, path: str) -> Any:
    """Parse ``text`` (from file ``path``) into LocDict/LocList/scalars.

    Raises :class:`GraphError` for syntax errors, duplicate keys and
    unsafe or unknown tags.
    """
    loader = _Loader(text, path)
    try:
        data = loader.get_single_data()
    except yaml.constructor.ConstructorError as exc:
        mark = exc.problem_mark or exc.context_mark
        tag = ""
        if exc.problem and "tag" in exc.problem:
            tag = exc.problem.split("tag", 1)[1].strip(" '!")
        msg = f"YAML tag {tag!r} is not allowed: graph files may only hold plain data (maps, lists, strings, numbers)"
        raise GraphError([Diagnostic(_loc(path, mark), msg)]) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or "invalid YAML"
        context = f" ({exc.context})" if exc.context else ""
        raise GraphError([Diagnostic(_loc(path, mark), f"YAML syntax error: {problem}{context}")]) from None
    except yaml.YAMLError as exc:
        raise GraphError([Diagnostic(Location(path), f"YAML error: {exc}")]) from None
    finally:
        loader.dispose()
    if loader.problems:
        raise GraphError(loader.problems)
    return data


def _loc(path: str, mark: Any) -> Location:
    if mark is None:
        return Location(path)
    return Location(path, mark.line + 1, mark.column + 1)
