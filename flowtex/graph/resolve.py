"""GraphSpec + registry -> ResolvedGraph: checked, pruned, ordered, with built nodes.

All problems are collected as diagnostics with file:line:col and raised
together as one :class:`GraphError`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx

from ..errors import DataError, FlowtexError, Location, ParamError
from ..limits import port_values_problem
from ..node_api import BuildContext, Node, NodeState, Port, PortSpec, simplify_unit, suggest
from ..node_params import checked_params, load_files
from ..nodecheck import checked_state, is_plugin, plugin_raised
from ..registry import Registry
from ..schema.core import Collector
from .spec import EdgeSpec, Endpoint, GraphSpec, NodeSpec


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


class _Checker(Collector):
    """The schema layer's one diagnostic collector, with the spec and the node types being checked against."""

    def __init__(self, spec: GraphSpec, registry: Registry):
        super().__init__(str(spec.path))
        self.spec = spec
        self.registry = registry

    fail_if_any = Collector.raise_if_any


def resolve_graph(spec: GraphSpec, registry: Registry) -> ResolvedGraph:
    """Check ``spec`` against the node types in ``registry`` and build its nodes."""
    ck = _Checker(spec, registry)
    nodes = _typed_nodes(ck)
    edge_of = _check_edges(ck, nodes)
    _check_outputs(ck, nodes)
    _check_unconnected(ck, nodes)
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
    _resolve_ports(ck, {name: nodes[name] for name in order}, input_specs, edge_of)
    ck.fail_if_any()
    kept = {name: nodes[name] for name in order if name in keep}
    cyclic = not nx.is_directed_acyclic_graph(dataflow.subgraph(keep))
    _build_nodes(ck, kept)
    ck.fail_if_any()

    output_specs: dict[str, PortSpec] = {}
    for name, out in spec.outputs.items():
        if out.src.node is None:
            output_specs[name] = input_specs[out.src.port]
        else:
            output_specs[name] = kept[out.src.node].out_specs[out.src.port]
    return ResolvedGraph(spec, kept, dropped, input_specs, output_specs, cyclic, dataflow)


def _typed_nodes(ck: _Checker) -> dict[str, ResolvedNode]:
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


def _check_params(ck: _Checker, ns: NodeSpec, cls: type[Node]) -> dict[str, Any] | None:
    """The node's coerced parameters (flowtex.node_params), or None after reporting each problem at its line."""
    values, problems = checked_params(cls, ns.params, ck.spec.path.parent)
    for problem in problems:
        loc = ns.param_locs.get(problem.key, ns.params_loc) if problem.given else ns.params_loc
        ck.error(loc, f"node {ns.name!r} ({ns.type}): {problem.message}")
    return None if problems else values


def _loaded_params(rn: ResolvedNode) -> tuple[dict[str, Any], dict[str, Path]]:
    """The node's parameters with its files read into objects (flowtex.node_params.load_files: the graph/io
    boundary), read once per node; ParamError (naming the parameter) for a file that cannot be read."""
    if rn.loaded is None:
        rn.loaded = load_files(rn.cls, rn.params)
    return rn.loaded


def _port_names(ports: dict[str, Port]) -> str:
    return ", ".join(ports) or "none"


def _check_edges(ck: _Checker, nodes: dict[str, ResolvedNode]) -> dict[tuple[str, str], EdgeSpec]:
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
            ck.error(edge.loc, f"input {dst.node}.{dst.port} is connected twice (also at line {first.loc.line}); an input takes exactly one edge")
            continue
        if ok:
            edge_of[key] = edge
    return edge_of


def _check_source(ck: _Checker, nodes: dict[str, ResolvedNode], src: Endpoint, loc: Location) -> bool:
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


def _check_outputs(ck: _Checker, nodes: dict[str, ResolvedNode]) -> None:
    for out in ck.spec.outputs.values():
        _check_source(ck, nodes, out.src, out.loc)


def _check_unconnected(ck: _Checker, nodes: dict[str, ResolvedNode]) -> None:
    connected = {(e.dst.node, e.dst.port) for e in ck.spec.edges}
    for name, rn in nodes.items():
        for port_name, port in rn.cls.inputs.items():
            if (name, port_name) in connected:
                rn.sources[port_name] = None  # filled below
            elif not port.optional:
                ck.error(rn.spec.loc, f"node {name!r} ({rn.cls.type_name}): input {port_name!r} is not connected; "
                                      f"add an edge '... -> {name}.{port_name}'")
            else:
                rn.sources[port_name] = None
    for edge in ck.spec.edges:
        if edge.dst.node in nodes and edge.dst.port in nodes[edge.dst.node].cls.inputs:
            nodes[edge.dst.node].sources[edge.dst.port] = edge.src


def _port_check(port: Port, name: str, got: PortSpec, specs: dict[str, PortSpec]) -> str | None:
    shape = port.shape
    if isinstance(shape, str):
        ref = specs.get(shape[1:])
        shape = ref.shape if ref is not None else None
    if shape is not None and tuple(shape) != got.shape:
        want = PortSpec(tuple(shape)).describe().split(" [")[0]
        return f"shape mismatch: {got.describe().split(' [')[0]} arrives at input {name!r}, which takes {want}"
    unit = port.unit
    if unit.startswith("="):
        ref = specs.get(unit[1:])
        unit = ref.unit if ref is not None else "*"
    if unit != "*" and simplify_unit(unit) != simplify_unit(got.unit):
        fix = f"declare unit: {unit}" if got.unit == "" else "convert with a gain node or fix the declared unit"
        return (f"unit mismatch: '{got.unit or 'dimensionless'}' arrives at input {name!r}, which takes "
                f"'{unit or 'dimensionless'}' ({fix})")
    return None


def _resolve_ports(ck: _Checker, nodes: dict[str, ResolvedNode], inputs: dict[str, PortSpec],
                   edge_of: dict[tuple[str, str], EdgeSpec]) -> None:
    """Resolve every port; a delay fed back from later in the order takes the shape and unit the loop needs.

    A delay's input in a loop comes from a node resolved after it, so its spec is
    first assumed (a dimensionless scalar), then corrected from what the loop
    asks of it (the port its output feeds) or what actually arrives, until the
    loop is consistent (a few passes; one per delay on the loop at most).
    """
    assumed: dict[str, PortSpec] = {}
    for _ in range(2 + 2 * sum(1 for rn in nodes.values() if rn.cls.breaks_cycles)):
        ck.diagnostics = []
        hints = _resolve_pass(ck, nodes, inputs, edge_of, assumed)
        corrected = {**assumed, **hints}
        if not ck.diagnostics or corrected == assumed:
            return
        assumed = corrected


def _expected(port: Port, specs: dict[str, PortSpec]) -> tuple[tuple[int, ...] | None, str]:
    """Shape (None: any) and unit ("*": any) a port takes, given the inputs resolved before it."""
    shape = port.shape
    if isinstance(shape, str):
        ref = specs.get(shape[1:])
        shape = ref.shape if ref is not None else None
    unit = port.unit
    if unit.startswith("="):
        ref = specs.get(unit[1:])
        unit = ref.unit if ref is not None else "*"
    return (tuple(shape) if shape is not None else None), unit


def _resolve_pass(ck: _Checker, nodes: dict[str, ResolvedNode], inputs: dict[str, PortSpec],
                  edge_of: dict[tuple[str, str], EdgeSpec], assumed: dict[str, PortSpec]) -> dict[str, PortSpec]:
    """One resolution pass; returns corrected specs for fed-back delay inputs that the pass found wrong."""
    provisional: dict[str, PortSpec] = {}
    hints: dict[str, PortSpec] = {}
    done: set[str] = set()
    failed: set[str] = set()  # nodes with an error: their consumers are not checked (no follow-on errors)
    for rn in nodes.values():
        rn.out_specs = {}
    for name, rn in nodes.items():
        done.add(name)
        specs: dict[str, PortSpec] = {}
        bad = False
        if any(src is not None and src.node in failed for src in rn.sources.values()):
            failed.add(name)
            continue
        input_every: dict[str, int] = {}
        for port_name, port in rn.cls.inputs.items():
            src = rn.sources.get(port_name)
            if src is None:
                shape = port.shape if isinstance(port.shape, tuple) else ()
                unit = port.unit if not (port.unit.startswith("=") or port.unit == "*") else ""
                if isinstance(port.shape, str) and port.shape[1:] in specs:
                    shape = specs[port.shape[1:]].shape
                specs[port_name] = PortSpec(tuple(shape), unit)
                continue
            if src.node == name:  # a node (a delay: others are cycles without one) wired to itself
                ck.error(edge_of[(name, port_name)].loc, f"edge {edge_of[(name, port_name)].text!r}: node {name!r} feeds "
                         "itself, so its output would hold its initial value forever; feed it from another node")
                bad = True
                continue
            if src.node is None:
                got = inputs[src.port]
                input_every[port_name] = 1
            elif src.node in done:
                got = nodes[src.node].out_specs[src.port]
                input_every[port_name] = nodes[src.node].spec.every
            else:  # feedback into a delay from a node later in the order
                got = assumed.get(name, PortSpec())
                provisional[name] = got
            problem = _port_check(port, port_name, got, specs)
            if problem:
                _hint_from_mismatch(rn, port, port_name, got, specs, provisional, hints)
                ck.error(edge_of[(name, port_name)].loc, f"edge {edge_of[(name, port_name)].text!r}: {problem}")
                bad = True
            specs[port_name] = got
        if bad:
            failed.add(name)
            continue
        rn.in_specs = specs
        if _too_wide(ck, rn, specs, "input") or not _own_schedule(ck, rn, input_every):
            failed.add(name)
            continue
        method = "__init__"
        try:
            params, files = _loaded_params(rn)
            ctx = BuildContext(rate=ck.spec.rate, base_dir=ck.spec.path.parent, every=rn.spec.every, input_every=input_every,
                               files=files)
            rn.node = rn.cls(name, params, ctx)
            method = "resolve"
            rn.out_specs = rn.node.resolve(specs)
            if _too_wide(ck, rn, rn.out_specs, "output"):
                rn.out_specs = {}
                failed.add(name)
        except ParamError as exc:
            failed.add(name)
            ck.error(_param_loc(rn, exc.param), f"node {name!r} ({rn.cls.type_name}): {exc}")
        except (DataError, FlowtexError) as exc:
            failed.add(name)
            ck.error(rn.spec.loc, f"node {name!r} ({rn.cls.type_name}): {exc}")
        except Exception as exc:
            if not is_plugin(rn.cls):
                raise  # flowtex's own bug: an internal error
            raise plugin_raised(rn.cls, name, method, exc) from None
    for name, took in provisional.items():
        rn = nodes[name]
        for port_name, src in rn.sources.items():
            if src is not None and src.node is not None and src.node not in failed and nodes[src.node].out_specs:
                actual = nodes[src.node].out_specs[src.port]
                if actual != took:
                    hints[name] = actual
                    ck.error(edge_of[(name, port_name)].loc,
                             f"feedback into delay {name!r} carries {actual.describe()}, but the loop needs "
                             f"{took.describe()} at the delay's output; make both sides of the loop agree")
    return hints


def _too_wide(ck: _Checker, rn: ResolvedNode, specs: dict[str, PortSpec], kind: str) -> bool:
    """Report (at the node's line) every port of ``specs`` carrying more than the per-tick limit; True if any."""
    wide = [(port, problem) for port, spec in specs.items() if (problem := port_values_problem(spec.shape)) is not None]
    for port, problem in wide:
        ck.error(rn.spec.loc, f"node {rn.spec.name!r} ({rn.cls.type_name}): {kind} {port!r}: {problem}")
    return bool(wide)


def _hint_from_mismatch(rn: ResolvedNode, port: Port, port_name: str, got: PortSpec, specs: dict[str, PortSpec],
                        provisional: dict[str, PortSpec], hints: dict[str, PortSpec]) -> None:
    """A port check failed: if a fed-back delay's assumed spec is to blame, record what it should be."""
    src = rn.sources.get(port_name)
    want_shape, want_unit = _expected(port, specs)
    if src is not None and src.node in provisional:  # the delay's output arrives here
        hints[src.node] = PortSpec(want_shape if want_shape is not None else got.shape,
                                   got.unit if want_unit == "*" else want_unit)
        return
    for ref in {port.shape[1:] if isinstance(port.shape, str) else None, port.unit[1:] if port.unit.startswith("=") else None}:
        ref_src = rn.sources.get(ref) if ref else None
        if ref_src is not None and ref_src.node in provisional:  # this port must match a delay's output
            hints[ref_src.node] = got


def _own_schedule(ck: _Checker, rn: ResolvedNode, input_every: dict[str, int]) -> bool:
    """Apply a node's own schedule (:meth:`Node.own_every`) to ``rn.spec.every``; False after an error."""
    try:
        own = rn.cls.own_every(rn.params, ck.spec.rate, input_every)
    except ParamError as exc:
        ck.error(_param_loc(rn, exc.param), f"node {rn.spec.name!r} ({rn.cls.type_name}): {exc}")
        return False
    if own is None:
        return True
    if rn.spec.every not in (1, own):
        ck.error(rn.spec.loc, f"node {rn.spec.name!r} ({rn.cls.type_name}): its parameters make it run every {own} ticks, "
                              f"but the graph says every: {rn.spec.every}; drop every:")
        return False
    rn.spec.every = own
    return True


def _param_loc(rn: ResolvedNode, param: str | None) -> Location:
    if param is not None and param in rn.spec.param_locs:
        return rn.spec.param_locs[param]
    return rn.spec.params_loc if param is not None else rn.spec.loc


def _build_nodes(ck: _Checker, nodes: dict[str, ResolvedNode]) -> None:
    for name, rn in nodes.items():
        if rn.node is None:
            continue
        try:
            state = rn.node.build(rn.in_specs, rn.out_specs)
        except ParamError as exc:
            ck.error(_param_loc(rn, exc.param), f"node {name!r} ({rn.cls.type_name}): {exc}")
            continue
        except (DataError, FlowtexError) as exc:
            ck.error(rn.spec.loc, f"node {name!r} ({rn.cls.type_name}): {exc}")
            continue
        except Exception as exc:
            if not is_plugin(rn.cls):
                raise  # flowtex's own bug: an internal error
            raise plugin_raised(rn.cls, name, "build", exc) from None
        rn.state = checked_state(rn.cls, name, state, rn.cls.build)
