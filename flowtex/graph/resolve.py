"""GraphSpec + registry -> ResolvedGraph: checked, pruned, ordered, with built nodes.

All problems are collected as diagnostics with file:line:col and raised
together as one :class:`GraphError`. The steps: names and connections
(:mod:`flowtex.graph.wiring`), cycles, pruning and order (here), shapes and units
(:mod:`flowtex.graph.ports`), building the kept nodes (here). The result types live in
:mod:`flowtex.graph.resolved` and still import from here.
"""

from __future__ import annotations

import networkx as nx
import numpy as np

from ..errors import DataError, FlowtexError, ParamError
from ..limits import MAX_STATE_VALUES
from ..node_api import PortSpec
from ..nodecheck import checked_state, is_plugin, plugin_raised
from ..registry import Registry
from .ports import resolve_ports
from .resolved import GraphChecker, ResolvedGraph, ResolvedNode, param_loc
from .spec import GraphSpec
from .wiring import check_edges, check_outputs, check_unconnected, typed_nodes

__all__ = ["ResolvedGraph", "ResolvedNode", "resolve_graph"]


def resolve_graph(spec: GraphSpec, registry: Registry) -> ResolvedGraph:
    """Check ``spec`` against the node types in ``registry`` and build its nodes."""
    ck = GraphChecker(spec, registry)
    nodes = typed_nodes(ck)
    edge_of = check_edges(ck, nodes)
    check_outputs(ck, nodes)
    check_unconnected(ck, nodes)
    ck.fail_if_any()

    dataflow = nx.DiGraph()
    dataflow.add_nodes_from(nodes)
    for (dst, _port), edge in edge_of.items():
        if edge.src.node is not None:
            dataflow.add_edge(edge.src.node, dst)
    ordering = dataflow.copy()
    ordering.remove_edges_from([(u, v) for u, v in dataflow.edges if nodes[v].cls.breaks_cycles])
    if not nx.is_directed_acyclic_graph(ordering):
        for cycle in nx.simple_cycles(ordering):
            first = nodes[cycle[0]].spec
            path = " -> ".join(cycle + [cycle[0]])
            ck.error(first.loc, f"cycle {path} does not pass through a delay node; insert a 'delay' node to break the loop")
            break
        ck.fail_if_any()

    wanted = {o.src.node for o in spec.outputs.values() if o.src.node is not None}
    keep: set[str] = set(wanted)
    for name in wanted:
        keep |= nx.ancestors(dataflow, name)
    position = {name: i for i, name in enumerate(spec.nodes)}
    order = list(nx.lexicographical_topological_sort(ordering, key=lambda n: position[n]))
    dropped = [n for n in spec.nodes if n in nodes and n not in keep]

    input_specs = {name: PortSpec(i.shape, i.unit) for name, i in spec.inputs.items()}
    # Ports of every node are checked (a mistake in an unused node is still a mistake);
    # only the nodes an output depends on are built and compiled.
    resolve_ports(ck, {name: nodes[name] for name in order}, input_specs, edge_of)
    ck.fail_if_any()
    kept = {name: nodes[name] for name in order if name in keep}
    cyclic = not nx.is_directed_acyclic_graph(dataflow.subgraph(keep))
    _build_nodes(ck, kept)
    ck.fail_if_any()
    _check_states(ck, kept)

    output_specs: dict[str, PortSpec] = {}
    for name, out in spec.outputs.items():
        if out.src.node is None:
            output_specs[name] = input_specs[out.src.port]
        else:
            output_specs[name] = kept[out.src.node].out_specs[out.src.port]
    return ResolvedGraph(spec, kept, dropped, input_specs, output_specs, cyclic, dataflow)


def _check_states(ck: GraphChecker, nodes: dict[str, ResolvedNode]) -> None:
    """Refuse node parameters and states holding more than :data:`~flowtex.limits.MAX_STATE_VALUES` values together
    before the arenas copy them (a graph file can size a plugin's state by a parameter its declaration does not bound),
    at the largest node's line."""
    sizes = {name: int(np.size(rn.state.params) + np.size(rn.state.state) + np.size(rn.state.istate))
             for name, rn in nodes.items() if rn.state is not None}
    if sum(sizes.values()) > MAX_STATE_VALUES:
        name = max(sizes, key=lambda n: sizes[n])
        ck.error(nodes[name].spec.loc, f"node {name!r} ({nodes[name].cls.type_name}): its parameters and state hold "
                                       f"{sizes[name]:,} values, the graph's nodes {sum(sizes.values()):,}; flowtex allocates "
                                       f"at most {MAX_STATE_VALUES:,} (flowtex.limits.MAX_STATE_VALUES): lower the parameter "
                                       "that sizes it")
        ck.fail_if_any()


def _build_nodes(ck: GraphChecker, nodes: dict[str, ResolvedNode]) -> None:
    for name, rn in nodes.items():
        if rn.node is None:
            continue
        try:
            state = rn.node.build(rn.in_specs, rn.out_specs)
        except ParamError as exc:
            ck.error(param_loc(rn, exc.param), f"node {name!r} ({rn.cls.type_name}): {exc}")
            continue
        except (DataError, FlowtexError) as exc:
            ck.error(rn.spec.loc, f"node {name!r} ({rn.cls.type_name}): {exc}")
            continue
        except Exception as exc:
            if not is_plugin(rn.cls):
                raise  # flowtex's own bug: an internal error
            raise plugin_raised(rn.cls, name, "build", exc) from None
        rn.state = checked_state(rn.cls, name, state, rn.cls.build)
