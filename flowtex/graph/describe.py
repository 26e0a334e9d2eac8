"""Human-readable views of graphs and node types (``flowtex graph``, ``flowtex nodes``)."""

from __future__ import annotations

from ..node_api import Node
from ..nodecheck import checked_latency
from ..registry import Registry
from .compiled import Graph


def describe_graph(graph: Graph) -> str:
    """Execution order, buffers and dropped nodes of a compiled graph."""
    rg = graph.resolved
    lay = graph.layout
    lines = [f"graph {graph.name!r}: {graph.rate:g} Hz, seed {graph.seed}, "
             f"{'tick-by-tick (feedback loop)' if rg.cyclic else 'block'} execution, block of {lay.block_rows} ticks"]
    lines.append("inputs:")
    for name, spec in rg.input_specs.items():
        lines.append(f"  {name}: {spec.describe()}  -> buffer f[{lay.graph_inputs[name].offset}]")
    lines.append("execution order:")
    for k, (name, rn) in enumerate(rg.nodes.items(), start=1):
        every = f" every {rn.spec.every} ticks ({graph.rate / rn.spec.every:g} Hz)" if rn.spec.every > 1 else ""
        latency = checked_latency(rn.cls, name, rn.node.latency_samples()) if rn.node is not None else 0
        if latency:
            node_rate = graph.rate / rn.spec.every
            every += f", latency {latency} samples ({1000.0 * latency / node_rate:g} ms)"
        lines.append(f"  {k}. {name} ({rn.cls.type_name}){every}")
        for port, src in rn.sources.items():
            origin = "default" if src is None else (src.port if src.node is None else f"{src.node}.{src.port}")
            lines.append(f"       in  {port:<14} {rn.in_specs[port].describe():<22} <- {origin}")
        for port, spec in rn.out_specs.items():
            slot = lay.nodes[name].outputs[port]
            lines.append(f"       out {port:<14} {spec.describe():<22} buffer f[{slot.offset}:{slot.offset + slot.width * lay.block_rows}]")
    lines.append("outputs:")
    for name, out in graph.spec.outputs.items():
        src = out.src.port if out.src.node is None else f"{out.src.node}.{out.src.port}"
        lines.append(f"  {name}: {rg.output_specs[name].describe()} <- {src}")
    if rg.dropped:
        lines.append("dropped (no output depends on them): " + ", ".join(rg.dropped))
    else:
        lines.append("dropped: none")
    lines.append(f"arena: {lay.f.size} float64 values ({lay.f.nbytes / 1024:.1f} KiB), {lay.i.size} int64 values")
    return "\n".join(lines)


def dot_string(text: str) -> str:
    """``text`` inside a DOT double-quoted string: backslashes, quotes and line breaks escaped. A graph name is free
    text; written as it was, ``name: 'x" ]; a [label="1'`` ended the string and wrote DOT of its own."""
    return text.replace("\\", "\\\\").replace('"', '\\"').replace("\r", "\\r").replace("\n", "\\n")


def graph_dot(graph: Graph) -> str:
    """Graphviz source of the graph (dropped nodes dashed)."""
    rg = graph.resolved
    lines = [f'digraph "{dot_string(graph.name)}" {{', "  rankdir=LR;", '  node [shape=box, fontname="Helvetica"];']
    for name in rg.input_specs:
        lines.append(f'  "in:{name}" [label="{name}", shape=ellipse];')
    for name, ns in graph.spec.nodes.items():
        style = ', style=dashed, color=gray' if name in rg.dropped else ""
        lines.append(f'  "{name}" [label="{name}\\n({ns.type})"{style}];')
    for name in graph.spec.outputs:
        lines.append(f'  "out:{name}" [label="{name}", shape=ellipse];')
    for edge in graph.spec.edges:
        src = f"in:{edge.src.port}" if edge.src.node is None else edge.src.node
        label = edge.src.port if edge.src.node is not None else ""
        lines.append(f'  "{src}" -> "{edge.dst.node}" [label="{label}->{edge.dst.port}"];')
    for name, out in graph.spec.outputs.items():
        src = f"in:{out.src.port}" if out.src.node is None else out.src.node
        lines.append(f'  "{src}" -> "out:{name}" [label="{out.src.port}"];')
    lines.append("}")
    return "\n".join(lines)


def describe_node_type(cls: type[Node], origin: str) -> str:
    """Ports, parameters and doc of one node type."""
    lines = [f"{cls.type_name} — {cls.summary()}", f"  from {origin}"]
    if cls.latency_doc:
        lines.append(f"  latency: {cls.latency_doc}")
    for title, ports in (("inputs", cls.inputs), ("outputs", cls.outputs)):
        if ports:
            lines.append(f"  {title}:")
            for name, port in ports.items():
                lines.append(f"    {name:<16} {port.describe():<34} {port.doc}")
    if cls.params:
        lines.append("  params:")
        for name, p in cls.params.items():
            default = "required" if p.required else f"default {p.default!r}"
            unit = f" [{p.unit}]" if p.unit else ""
            lines.append(f"    {name:<16} {p.describe_type()}{unit}, {default}: {p.doc}")
    return "\n".join(lines)


def describe_registry(registry: Registry) -> str:
    return "\n\n".join(describe_node_type(registry.types[n], registry.origins[n]) for n in registry.names())
