"""Memory layout of a compiled graph: one float64 arena and one int64 arena.

Everything the compiled tick touches lives in two flat arrays, so the jitted
functions take very few arguments (calling numba with many arrays is slow):

float arena ``f``
    one buffer of ``block_rows x width`` values per graph input, per node
    output port and per unconnected optional input; a hold slot per output
    of multi-rate nodes; then each node's parameters and float state.
int arena ``i``
    a header, the input/output copy tables, one fixed-size table per node
    (offsets into ``f``), then each node's integer state.

The *positions* of table entries depend only on the graph's structure, so
the generated source can name them literally; the *values* (offsets, widths,
parameters) are data. Two graphs that differ only in parameter values or
model files therefore share generated code and its compiled cache.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import FlowtexError
from ..limits import MAX_BUFFER_VALUES
from .resolve import ResolvedGraph

# Header slots of the int arena.
TICK = 0
BLOCK_ROWS = 1
N_IN = 2
N_OUT = 3
IN_TABLE = 4
OUT_TABLE = 5
TABLE_STRIDE = 5
IN_WIDTH = 6
OUT_WIDTH = 7
DISPATCH = 8
"""Position of the dispatch tier's table (:mod:`flowtex.graph.dispatch`); 0 for the fused tier."""
FAULT = 9
"""Dispatch tier: the descriptor position of a node whose kernel raised (0: none); the driver and ``run`` stop on it.

``FAULT + 1`` holds the first row and ``FAULT + 2`` the number of rows of that call (:mod:`flowtex.graph.wrappers`)."""
HEADER = 12


@dataclass
class PortSlot:
    """Where one port's buffer is: ``f[offset : offset + rows * width]`` row-major."""

    offset: int
    width: int
    width_index: int
    """Position in ``i`` that holds ``width`` (so generated code reads it as data)."""
    offset_index: int
    """Position in ``i`` that holds ``offset``."""


@dataclass
class NodeSlots:
    """Positions in ``i`` of one node's table entries (literal in generated code)."""

    name: str
    p: tuple[int, int]
    s: tuple[int, int]
    si: tuple[int, int]
    every: int
    inputs: dict[str, PortSlot] = field(default_factory=dict)
    outputs: dict[str, PortSlot] = field(default_factory=dict)
    holds: dict[str, PortSlot] = field(default_factory=dict)


@dataclass
class Layout:
    f: np.ndarray
    i: np.ndarray
    block_rows: int
    graph_inputs: dict[str, PortSlot]
    graph_outputs: dict[str, PortSlot]
    nodes: dict[str, NodeSlots]
    in_columns: dict[str, tuple[int, int]]
    """Graph input name -> (first column, width). ``run`` takes all inputs as one
    1-D array: input k's ``total x width`` values, time-major, start at ``total * column``.

    The input and output tables in ``i`` hold, per signal, ``TABLE_STRIDE`` values:
    position in ``i`` of the port's offset, width, column, the port's own arena
    offset, and whether ``run`` redirects the port into the caller's array."""
    out_columns: dict[str, tuple[int, int]]


class _Builder:
    def __init__(self, block_rows: int):
        self.rows = block_rows
        self.f_chunks: list[np.ndarray] = []
        self.f_size = 0
        self.ints: list[int] = [0] * HEADER

    def f_alloc(self, values: np.ndarray) -> int:
        off = self.f_size
        values = np.ascontiguousarray(values, dtype=np.float64).ravel()
        self.f_chunks.append(values)
        self.f_size += values.size
        return off

    def i_slot(self, value: int = 0) -> int:
        self.ints.append(int(value))
        return len(self.ints) - 1

    def port(self, width: int, fill: np.ndarray | None = None) -> PortSlot:
        data = np.zeros((self.rows, width))
        if fill is not None:
            data[:] = fill
        off = self.f_alloc(data)
        return PortSlot(off, width, self.i_slot(width), self.i_slot(off))

    def hold(self, width: int) -> PortSlot:
        off = self.f_alloc(np.zeros(width))
        return PortSlot(off, width, self.i_slot(width), self.i_slot(off))


def _check_buffers(rg: ResolvedGraph, block_rows: int) -> None:
    """Refuse, before allocating, port buffers holding more than :data:`~flowtex.limits.MAX_BUFFER_VALUES` values."""
    per_row = sum(s.width for s in rg.input_specs.values())
    for rn in rg.nodes.values():
        per_row += sum(s.width for s in rn.out_specs.values()) + sum(
            rn.in_specs[p].width for p, src in rn.sources.items() if src is None)
    if per_row * block_rows > MAX_BUFFER_VALUES:
        raise FlowtexError(f"{rg.spec.path}: graph {rg.spec.name!r}: its port buffers would hold {per_row * block_rows:,} values "
                           f"({per_row:,} per tick x {block_rows} rows); flowtex allocates at most {MAX_BUFFER_VALUES:,} "
                           "(flowtex.limits.MAX_BUFFER_VALUES): make the ports narrower")


def plan_layout(rg: ResolvedGraph, block_rows: int) -> Layout:
    """Place every buffer, parameter and state array of ``rg``."""
    _check_buffers(rg, block_rows)
    b = _Builder(block_rows)
    graph_inputs = {name: b.port(spec.width) for name, spec in rg.input_specs.items()}
    out_ports: dict[tuple[str, str], PortSlot] = {}
    node_slots: dict[str, NodeSlots] = {}
    for name, rn in rg.nodes.items():
        slots = NodeSlots(name, (0, 0), (0, 0), (0, 0), rn.spec.every)
        for port, spec in rn.out_specs.items():
            out_ports[(name, port)] = slots.outputs[port] = b.port(spec.width)
            if rn.spec.every > 1:
                slots.holds[port] = b.hold(spec.width)
        node_slots[name] = slots
    for name, rn in rg.nodes.items():
        slots = node_slots[name]
        for port, src in rn.sources.items():
            if src is None:
                assert rn.node is not None
                fill = rn.node.input_default(port, rn.in_specs[port])
                slots.inputs[port] = b.port(rn.in_specs[port].width, fill)
            elif src.node is None:
                slots.inputs[port] = graph_inputs[src.port]
            else:
                slots.inputs[port] = out_ports[(src.node, src.port)]
    # Parameters and float state after all buffers; int state after all tables.
    int_state: list[tuple[NodeSlots, np.ndarray]] = []
    for name, rn in rg.nodes.items():
        slots = node_slots[name]
        assert rn.state is not None
        p = b.f_alloc(rn.state.params)
        s = b.f_alloc(rn.state.state)
        slots.p = (b.i_slot(p), b.i_slot(p + rn.state.params.size))
        slots.s = (b.i_slot(s), b.i_slot(s + rn.state.state.size))
        slots.si = (b.i_slot(), b.i_slot())
        slots.every = b.i_slot(rn.spec.every)
        int_state.append((slots, np.asarray(rn.state.istate, dtype=np.int64).ravel()))

    graph_outputs: dict[str, PortSlot] = {}
    for name, out in rg.spec.outputs.items():
        graph_outputs[name] = graph_inputs[out.src.port] if out.src.node is None else out_ports[(out.src.node, out.src.port)]

    in_columns, out_columns = {}, {}
    col = 0
    in_table = len(b.ints)
    for name, slot in graph_inputs.items():
        b.ints += [slot.offset_index, slot.width, col, slot.offset, 1]
        in_columns[name] = (col, slot.width)
        col += slot.width
    col = 0
    out_table = len(b.ints)
    redirected = {id(s) for s in graph_inputs.values()}
    for name, slot in graph_outputs.items():
        # The first output of a port not read from the inputs is written in place (zero copy).
        in_place = id(slot) not in redirected
        redirected.add(id(slot))
        b.ints += [slot.offset_index, slot.width, col, slot.offset, int(in_place)]
        out_columns[name] = (col, slot.width)
        col += slot.width

    for slots, istate in int_state:
        start = len(b.ints)
        b.ints += istate.tolist()
        b.ints[slots.si[0]] = start
        b.ints[slots.si[1]] = start + istate.size

    ints = np.array(b.ints, dtype=np.int64)
    ints[BLOCK_ROWS] = block_rows
    ints[N_IN] = len(graph_inputs)
    ints[N_OUT] = len(graph_outputs)
    ints[IN_TABLE] = in_table
    ints[OUT_TABLE] = out_table
    ints[IN_WIDTH] = sum(s.width for s in graph_inputs.values())
    ints[OUT_WIDTH] = sum(s.width for s in graph_outputs.values())
    f = np.concatenate(b.f_chunks) if b.f_chunks else np.zeros(0)
    return Layout(f, ints, block_rows, graph_inputs, graph_outputs, node_slots, in_columns, out_columns)
