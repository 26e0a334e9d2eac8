"""Graphs built in Python: the same checked :class:`GraphSpec` a YAML graph file gives, without a file.

:class:`GraphBuilder` records its calls as the mapping a graph file reads to (inputs, nodes, edges, outputs) and runs
it through the same checks (:func:`flowtex.graph.spec.spec_from_data`, then :func:`flowtex.graph.resolve.resolve_graph`),
so a mistake gives the message a graph file would, placed at the builder call instead of a file:line.
Parameter values may be loaded objects where a node type accepts them (e.g. a ``TextureModelSet`` as
``texture_lookup``'s ``models``), so nothing is written to disk to render a model held in memory.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import Diagnostic, GraphError, Location
from ..limits import close_names, excerpt
from ..pyvalues import plain
from ..schema.graph import FORMAT_VERSION
from ..yamlsource import LocDict, LocList
from .spec import GraphSpec, spec_from_data

__all__ = ["GraphBuilder"]


def _new_key(d: LocDict, kind: str, name: Any, where: Location) -> None:
    """Refuse a second ``kind`` named ``name`` (a graph file refuses a duplicate key the same way)."""
    if name in d:
        raise GraphError([Diagnostic(where, f"duplicate {kind} {name!r} (first defined at {d.key_pos[name]}); "
                                            "remove or rename one of them")])


def _mapping(where: Location) -> LocDict:
    d = LocDict()
    d.pos = where  # type: ignore[assignment]  # Collector.loc takes a Location as a position
    return d


def _put(d: LocDict, key: str, value: Any, where: Location) -> None:
    d[key] = plain(value)  # numpy scalars and arrays, paths: what a graph file would hold (flowtex.pyvalues)
    d.key_pos[key] = where  # type: ignore[assignment]
    d.value_pos[key] = where  # type: ignore[assignment]


def _misspelt_every(name: str, type: str, key: str, value: Any) -> None:
    """Refuse a keyword of :meth:`GraphBuilder.node` that looks like ``every`` (``evry=4``) and that the built-in node
    type does not take, naming ``every``: it would be reported as an unknown parameter of the node type."""
    if key == "every" or not close_names(key, ["every"]):
        return
    from ..registry import load_registry

    cls = load_registry().types.get(type)  # a plugin type (known at build()) is checked there, as any parameter
    if cls is not None and key not in cls.params:
        raise GraphError([Diagnostic(Location(f"GraphBuilder.node({name!r}, {type!r}, {key}=...)"),
                                     f"node {name!r} ({type}): {key!r} is no parameter of {type!r}; did you mean "
                                     f"every={excerpt(value)} (run the node every k ticks)?")])


class GraphBuilder:
    """Build a graph in Python: ``GraphBuilder("g", rate=1000.0).input("x", unit="N").node("f", "gain", k=2.0)
    .edge("x -> f.x").output("y", "f.y").build()``.

    ``rate`` is the base tick rate (Hz), ``seed`` the default noise seed. ``base_dir`` is the folder relative path
    parameters are read from (default: the current folder), as a graph file's own folder is for a file.
    Each method returns the builder, so calls chain.
    """

    def __init__(self, name: str, rate: float = 1000.0, seed: int = 0, base_dir: str | Path | None = None,
                 description: str = ""):
        self.name = name
        self._where = Location(f"GraphBuilder({name!r})")
        if base_dir is not None and not isinstance(base_dir, (str, os.PathLike)):
            raise GraphError([Diagnostic(self._where, f"base_dir must be a folder path (str or pathlib.Path), got "
                                                      f"{excerpt(base_dir)}")])
        self._path = Path(base_dir if base_dir is not None else ".") / f"<GraphBuilder {name}>"
        self._data = _mapping(self._where)
        for key, value in (("flowtex", FORMAT_VERSION), ("name", name), ("rate", rate), ("seed", seed)):
            _put(self._data, key, value, self._where)
        if description:
            _put(self._data, "description", description, self._where)
        self._inputs = _mapping(self._where)
        self._nodes = _mapping(self._where)
        self._edges = LocList()
        self._outputs = _mapping(self._where)

    def input(self, name: str, shape: int | Sequence[int] = (), unit: str = "") -> GraphBuilder:
        """A graph input: ``shape`` of one tick's value (``()`` a scalar, ``(3,)`` a 3-vector), ``unit`` such as ``"mm"``."""
        where = Location(f"GraphBuilder.input({name!r})")
        value = _mapping(where)
        _put(value, "shape", list(shape) if isinstance(shape, (list, tuple)) else shape, where)
        _put(value, "unit", unit, where)
        _new_key(self._inputs, "input", name, where)
        _put(self._inputs, name, value, where)
        return self

    def node(self, name: str, type: str, every: int = 1, **params: Any) -> GraphBuilder:
        """A node of ``type`` (``flowtex nodes`` lists them) run every ``every`` ticks, with its parameters."""
        where = Location(f"GraphBuilder.node({name!r}, {type!r})")
        _new_key(self._nodes, "node", name, where)
        value = _mapping(where)
        _put(value, "type", type, where)
        _put(value, "every", every, where)
        p = _mapping(where)
        for key, v in params.items():
            _misspelt_every(name, type, key, v)
            _put(p, key, v, Location(f"GraphBuilder.node({name!r}, {type!r}, {key}=...)"))
        _put(value, "params", p, where)
        _put(self._nodes, name, value, where)
        return self

    def edge(self, text: str) -> GraphBuilder:
        """An edge ``"producer.port -> consumer.port"`` (a graph input by its bare name), as in a graph file."""
        self._edges.append(text)
        self._edges.item_pos.append(Location(f"GraphBuilder.edge({text!r})"))  # type: ignore[arg-type]
        return self

    def output(self, name: str, source: str) -> GraphBuilder:
        """A graph output ``name`` read from ``source`` (``"node.port"``, or a graph input's name)."""
        where = Location(f"GraphBuilder.output({name!r}, {source!r})")
        _new_key(self._outputs, "output", name, where)
        _put(self._outputs, name, source, where)
        return self

    def spec(self, overrides: dict[str, Any] | None = None) -> GraphSpec:
        """The checked spec (shape checks only, as :func:`flowtex.graph.spec.parse_spec`). Raises ``GraphError``."""
        data = _mapping(self._where)
        data.update(self._data)
        data.key_pos.update(self._data.key_pos)
        data.value_pos.update(self._data.value_pos)
        for key, part in (("inputs", self._inputs), ("nodes", self._nodes), ("edges", self._edges), ("outputs", self._outputs)):
            if part or key != "inputs":
                _put(data, key, part, self._where)
        return spec_from_data(data, self._path, overrides)

    def resolve(self, overrides: dict[str, Any] | None = None, plugins: tuple[str | Path, ...] = ()) -> Any:
        """The checked, built :class:`flowtex.graph.resolved.ResolvedGraph` (what ``check_graph`` gives for a file)."""
        from ..registry import load_registry
        from .resolve import resolve_graph

        return resolve_graph(self.spec(overrides), load_registry(plugins))

    def build(self, overrides: dict[str, Any] | None = None, plugins: tuple[str | Path, ...] = (),
              tier: str | None = None, block_rows: int | None = None) -> Any:
        """The compiled :class:`flowtex.Graph`, as :func:`flowtex.load_graph` gives for a file (``plugins``: plugin
        folders; ``$FLOWTEX_PLUGINS`` is read as for a file; ``tier``: fused, dispatch or auto)."""
        from .compiled import DEFAULT_BLOCK_ROWS, Graph

        return Graph(self.resolve(overrides, plugins), DEFAULT_BLOCK_ROWS if block_rows is None else block_rows, tier)
