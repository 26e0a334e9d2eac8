"""Shapes and units along the edges, in execution order: each node is constructed and asked for its outputs.

A port's shape or unit may refer to another input's (``=x``); a delay fed back from later in
the order is resolved by assuming its spec and correcting it in a few passes
(:func:`resolve_ports`). Problems go to the shared :class:`~flowtex.graph.resolved.GraphChecker`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import DataError, FlowtexError, ParamError
from ..limits import port_values_problem
from ..node_api import BuildContext, Port, PortSpec, expected_shape, simplify_unit
from ..node_params import load_files
from ..nodecheck import checked_outputs, is_plugin, plugin_raised, scheduled_every
from .resolved import GraphChecker, ResolvedNode, param_loc
from .spec import EdgeSpec


def _loaded_params(rn: ResolvedNode) -> tuple[dict[str, Any], dict[str, Path]]:
    """The node's parameters with its files read into objects (flowtex.node_params.load_files: the graph/io
    boundary), read once per node; ParamError (naming the parameter) for a file that cannot be read."""
    if rn.loaded is None:
        rn.loaded = load_files(rn.cls, rn.params)
    return rn.loaded


def _port_check(port: Port, name: str, got: PortSpec, specs: dict[str, PortSpec]) -> str | None:
    shape = expected_shape(port, specs)
    if shape is not None and shape != got.shape:
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


def resolve_ports(ck: GraphChecker, nodes: dict[str, ResolvedNode], inputs: dict[str, PortSpec],
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
    unit = port.unit
    if unit.startswith("="):
        ref = specs.get(unit[1:])
        unit = ref.unit if ref is not None else "*"
    return expected_shape(port, specs), unit


def _resolve_pass(ck: GraphChecker, nodes: dict[str, ResolvedNode], inputs: dict[str, PortSpec],
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
            resolved = rn.node.resolve(specs)
        except ParamError as exc:
            failed.add(name)
            ck.error(param_loc(rn, exc.param), f"node {name!r} ({rn.cls.type_name}): {exc}")
        except (DataError, FlowtexError) as exc:
            failed.add(name)
            ck.error(rn.spec.loc, f"node {name!r} ({rn.cls.type_name}): {exc}")
        except Exception as exc:
            if not is_plugin(rn.cls):
                raise  # flowtex's own bug: an internal error
            raise plugin_raised(rn.cls, name, method, exc) from None
        else:
            rn.out_specs = checked_outputs(rn.cls, name, resolved)  # a wrong result: the plugin's error at its resolve()
            if _too_wide(ck, rn, rn.out_specs, "output"):
                rn.out_specs = {}
                failed.add(name)
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


def _too_wide(ck: GraphChecker, rn: ResolvedNode, specs: dict[str, PortSpec], kind: str) -> bool:
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


def _own_schedule(ck: GraphChecker, rn: ResolvedNode, input_every: dict[str, int]) -> bool:
    """Apply a node's own schedule (:meth:`Node.own_every`) to ``rn.spec.every``; False after an error."""
    try:
        own = scheduled_every(rn.cls, rn.spec.name, rn.params, ck.spec.rate, input_every)
    except ParamError as exc:
        ck.error(param_loc(rn, exc.param), f"node {rn.spec.name!r} ({rn.cls.type_name}): {exc}")
        return False
    if own is None:
        return True
    if rn.spec.every not in (1, own):
        ck.error(rn.spec.loc, f"node {rn.spec.name!r} ({rn.cls.type_name}): its parameters make it run every {own} ticks, "
                              f"but the graph says every: {rn.spec.every}; drop every:")
        return False
    rn.spec.every = own
    return True
