"""What resolving a graph produces (:class:`ResolvedNode`, :class:`ResolvedGraph`) and the diagnostic collector its checks share.

The steps that fill them: names and connections (:mod:`flowtex.graph.wiring`), shapes and
units along the edges (:mod:`flowtex.graph.ports`), the whole pass (:mod:`flowtex.graph.resolve`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx

from ..errors import Location
from ..node_api import Node, NodeState, PortSpec
from ..registry import Registry
from ..schema.core import Collector
from .spec import Endpoint, GraphSpec, NodeSpec


@dataclass
class ResolvedNode:
    spec: NodeSpec
    cls: type[Node]
    params: dict[str, Any]
    node: Node | None = None
    sources: dict[str, Endpoint | None] = field(default_factory=dict)
    """Input port -> producer endpoint, or None for an unconnected optional input."""
    in_specs: dict[str, PortSpec] = field(default_factory=dict)
    out_specs: dict[str, PortSpec] = field(default_factory=dict)
    state: NodeState | None = None
    loaded: tuple[dict[str, Any], dict[str, Path]] | None = None
    """The parameters with files read into objects, and param -> file read (set when the node is first constructed)."""


@dataclass
class ResolvedGraph:
    spec: GraphSpec
    nodes: dict[str, ResolvedNode]
    """Kept nodes, in execution order."""
    dropped: list[str]
    input_specs: dict[str, PortSpec]
    output_specs: dict[str, PortSpec]
    cyclic: bool
    dataflow: nx.DiGraph

    @property
    def order(self) -> list[str]:
        return list(self.nodes)


class GraphChecker(Collector):
    """The schema layer's one diagnostic collector, with the spec and the node types being checked against."""

    def __init__(self, spec: GraphSpec, registry: Registry):
        super().__init__(str(spec.path))
        self.spec = spec
        self.registry = registry

    fail_if_any = Collector.raise_if_any


def files_read(resolved: ResolvedGraph) -> set[Path]:
    """Files the kept nodes of a checked graph read: the value of every path parameter, resolved (a model set, a
    pattern file, a tap library, a plugin's own file; the graph file and plugins are the caller's). A parameter given
    a loaded object (a graph built in Python) reads no file."""
    found: set[Path] = set()
    for rn in resolved.nodes.values():
        for name, decl in rn.cls.params.items():
            value = rn.params.get(name)
            if decl.kind == "path" and isinstance(value, (str, Path)):
                found.add(Path(value).resolve())
    return found


def param_loc(rn: ResolvedNode, param: str | None) -> Location:
    """Where to report a problem with parameter ``param`` of a node (its key, else its params: block, else the node)."""
    if param is not None and param in rn.spec.param_locs:
        return rn.spec.param_locs[param]
    return rn.spec.params_loc if param is not None else rn.spec.loc
