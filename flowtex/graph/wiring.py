"""Names and connections of a graph spec checked against the node types: types, parameters, edges, outputs, unconnected inputs.

Each problem is reported at its file:line:col into the shared :class:`~flowtex.graph.resolved.GraphChecker`;
:func:`flowtex.graph.resolve.resolve_graph` runs these checks first, then raises them together.
"""

from __future__ import annotations

from typing import Any

from ..errors import Location
from ..limits import close_names
from ..node_api import Node, Port, suggest
from ..node_params import checked_params
from .resolved import GraphChecker, ResolvedNode
from .spec import EdgeSpec, Endpoint, NodeSpec


def typed_nodes(ck: GraphChecker) -> dict[str, ResolvedNode]:
    """One ResolvedNode per spec node whose type is known and whose parameters check out."""
    out: dict[str, ResolvedNode] = {}
    for name, ns in ck.spec.nodes.items():
        cls = ck.registry.get(ns.type)
        if cls is None:
            hint = suggest(ns.type, ck.registry.names())
            ck.error(ns.type_loc, f"node {name!r}: unknown node type {ns.type!r}{hint}; run 'flowtex nodes' to list them "
                                  "(plugin nodes are found in the graph file's plugins/ folder, the folders of its plugins: key, "
                                  "$FLOWTEX_PLUGINS and --plugins DIR)")
            continue
        params = _check_params(ck, ns, cls)
        if params is not None:
            out[name] = ResolvedNode(ns, cls, params)
    return out


def _check_params(ck: GraphChecker, ns: NodeSpec, cls: type[Node]) -> dict[str, Any] | None:
    """The node's coerced parameters (flowtex.node_params), or None after reporting each problem at its line."""
    values, problems = checked_params(cls, ns.params, ck.spec.path.parent, from_here=ns.command_line)
    for problem in problems:
        loc = ns.param_locs.get(problem.key, ns.params_loc) if problem.given else ns.params_loc
        ck.error(loc, f"node {ns.name!r} ({ns.type}): {problem.message}")
    return None if problems else values


def _port_names(ports: dict[str, Port]) -> str:
    return ", ".join(ports) or "none"


def check_edges(ck: GraphChecker, nodes: dict[str, ResolvedNode]) -> dict[tuple[str, str], EdgeSpec]:
    """Every edge's two ends exist and each input takes one edge; returns (node, input) -> its edge."""
    edge_of: dict[tuple[str, str], EdgeSpec] = {}
    for edge in ck.spec.edges:
        ok = _check_source(ck, nodes, edge.src, edge.loc)
        dst = edge.dst
        if dst.node not in ck.spec.nodes:
            ck.error(edge.loc, f"edge {edge.text!r}: no node {dst.node!r}{suggest(str(dst.node), list(ck.spec.nodes))}")
            continue
        if dst.node not in nodes:
            continue
        cls = nodes[dst.node].cls
        if dst.port not in cls.inputs:
            ck.error(edge.loc, f"edge {edge.text!r}: node {dst.node!r} ({cls.type_name}) has no input {dst.port!r}"
                     f"{suggest(dst.port, list(cls.inputs))}; its inputs are: {_port_names(cls.inputs)}")
            continue
        key = (dst.node, dst.port)
        if key in edge_of:
            first = edge_of[key]
            ck.error(edge.loc, f"input {dst.node}.{dst.port} is connected twice (also at {_where(first.loc)}); an input takes exactly one edge")
            continue
        if ok:
            edge_of[key] = edge
    return edge_of


def _check_source(ck: GraphChecker, nodes: dict[str, ResolvedNode], src: Endpoint, loc: Location) -> bool:
    if src.node is None:
        if src.port not in ck.spec.inputs:
            names = list(ck.spec.inputs) + list(ck.spec.nodes)
            ck.error(loc, f"{src.port!r} is not a graph input{suggest(src.port, names)}; name a node output as node.port")
            return False
        return True
    if src.node not in ck.spec.nodes:
        ck.error(loc, f"no node {src.node!r}{suggest(src.node, list(ck.spec.nodes))}")
        return False
    if src.node not in nodes:
        return False
    cls = nodes[src.node].cls
    if src.port not in cls.outputs:
        ck.error(loc, f"node {src.node!r} ({cls.type_name}) has no output {src.port!r}"
                 f"{suggest(src.port, list(cls.outputs))}; its outputs are: {_port_names(cls.outputs)}")
        return False
    return True


def check_outputs(ck: GraphChecker, nodes: dict[str, ResolvedNode]) -> None:
    """Every graph output names a graph input or a node output."""
    for out in ck.spec.outputs.values():
        _check_source(ck, nodes, out.src, out.loc)


def check_unconnected(ck: GraphChecker, nodes: dict[str, ResolvedNode]) -> None:
    """Every required input is connected; fills each node's ``sources`` (input -> producer, None if unconnected).

    A node that an edge aims at an input it lacks (a misspelt port, reported by :func:`check_edges` with its inputs)
    gets no second error for the input that edge meant, nor does the node an edge to a misspelt node name meant
    (the closest name, reported by :func:`check_edges`): one mistake, one message."""
    connected = {(e.dst.node, e.dst.port) for e in ck.spec.edges}
    misaimed = {e.dst.node for e in ck.spec.edges if e.dst.node in nodes and e.dst.port not in nodes[e.dst.node].cls.inputs}
    for e in ck.spec.edges:
        meant = close_names(str(e.dst.node), list(ck.spec.nodes), 1)
        if e.dst.node not in ck.spec.nodes and meant:
            misaimed.add(meant[0])
    for name, rn in nodes.items():
        for port_name, port in rn.cls.inputs.items():
            if (name, port_name) in connected:
                rn.sources[port_name] = None  # filled below
            elif not port.optional:
                if name in misaimed:
                    continue
                ck.error(rn.spec.loc, f"node {name!r} ({rn.cls.type_name}): input {port_name!r} is not connected; "
                                      f"add an edge '... -> {name}.{port_name}'")
            else:
                rn.sources[port_name] = None
    for edge in ck.spec.edges:
        if edge.dst.node in nodes and edge.dst.port in nodes[edge.dst.node].cls.inputs:
            nodes[edge.dst.node].sources[edge.dst.port] = edge.src


def _where(loc: Location) -> str:
    """``line N`` of the same file, or the builder call that placed an item without a line."""
    return f"line {loc.line}" if loc.line > 0 else str(loc)
