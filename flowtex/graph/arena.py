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

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..dsp.layout import Field
from ..dsp.layout import Layout as Declared
from ..errors import FlowtexError
from ..limits import MAX_BUFFER_VALUES
from .resolved import ResolvedGraph

INT_HEADER = Declared("int", [
    Field("tick", 1, "ticks run since reset"),
    Field("block_rows", 1, "rows of every port buffer"),
    Field("n_in", 1, "graph inputs"),
    Field("n_out", 1, "graph outputs"),
    Field("in_table", 1, "position of the input table (n_in SIGNAL entries)"),
    Field("out_table", 1, "position of the output table (n_out SIGNAL entries)"),
    Field("in_width", 1, "values per tick of all graph inputs"),
    Field("out_width", 1, "values per tick of all graph outputs"),
    Field("dispatch", 1, "position of the dispatch tier's table (flowtex.graph.dispatch); 0 for the fused tier"),
    Field("fault", 3, "dispatch tier: descriptor position of a node whose kernel raised (0: none), its first row, its rows"),
])
"""The int arena's header, declared once: its slots below, the generated ``run`` and the dispatch driver read it."""

SIGNAL = Declared("int", [
    Field("offset_index", 1, "position in i of the port's offset"),
    Field("width", 1, "values per tick"),
    Field("column", 1, "first column in run()'s X or Y"),
    Field("own_offset", 1, "the port's own arena offset (restored after run)"),
    Field("redirect", 1, "1 if run() points the port into the caller's array"),
])
"""One entry of the input and output tables (``TABLE_STRIDE`` ints per graph input or output)."""

TICK = INT_HEADER.const("tick")
BLOCK_ROWS = INT_HEADER.const("block_rows")
N_IN = INT_HEADER.const("n_in")
N_OUT = INT_HEADER.const("n_out")
IN_TABLE = INT_HEADER.const("in_table")
OUT_TABLE = INT_HEADER.const("out_table")
IN_WIDTH = INT_HEADER.const("in_width")
OUT_WIDTH = INT_HEADER.const("out_width")
DISPATCH = INT_HEADER.const("dispatch")
"""Position of the dispatch tier's table (:mod:`flowtex.graph.dispatch`); 0 for the fused tier."""
FAULT = INT_HEADER.const("fault")
"""Dispatch tier: the descriptor position of a node whose kernel raised (0: none); the driver and ``run`` stop on it.

``FAULT + 1`` holds the first row and ``FAULT + 2`` the number of rows of that call (:mod:`flowtex.graph.wrappers`)."""
HEADER = INT_HEADER.size()
TABLE_STRIDE = SIGNAL.size()
E_OFFSET_INDEX = SIGNAL.const("offset_index")
E_WIDTH = SIGNAL.const("width")
E_COLUMN = SIGNAL.const("column")
E_OWN_OFFSET = SIGNAL.const("own_offset")
E_REDIRECT = SIGNAL.const("redirect")

DISPATCH_HEAD = Declared("int", [Field("count", 1, "nodes"), Field("cyclic", 1, "1 if the graph has a feedback loop")])
"""Start of the dispatch tier's table; ``count`` DISPATCH_ENTRY entries follow, then descriptors and holds."""

DISPATCH_ENTRY = Declared("int", [
    Field("kernel", 1, "address of the kernel's wrapper"),
    Field("emit", 1, "address of the emit wrapper (delays in a loop), else 0"),
    Field("absorb", 1, "address of the absorb wrapper (delays in a loop), else 0"),
    Field("desc", 1, "position of the node's DESCRIPTOR"),
    Field("every", 1, "position in i of the node's every"),
    Field("holds", 1, "position of the node's HOLD entries"),
    Field("n_holds", 1, "number of HOLD entries"),
    Field("split", 1, "1 if the node runs as emit + absorb (a delay in a loop)"),
    Field("emit_desc", 1, "position of the emit wrapper's DESCRIPTOR, else 0"),
])
"""One node's entry of the dispatch table."""

DESCRIPTOR = Declared("int", [
    Field("p", 2, "positions in i of the parameter bounds (start, stop in f)"),
    Field("s", 2, "positions in i of the float state bounds"),
    Field("si", 2, "positions in i of the int state bounds"),
    Field("ports", "2 * n_ports", "per input then output: positions in i of its offset and width"),
], sizes=("n_ports",))
"""What a node's dispatch-tier wrapper reads (:mod:`flowtex.graph.wrappers`)."""

HOLD = Declared("int", [
    Field("hold", 1, "position in i of the hold slot's offset"),
    Field("out", 1, "position in i of the output port's offset"),
    Field("width", 1, "position in i of the output port's width"),
])
"""A multi-rate node's hold of one output (dispatch tier)."""


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
    f_pieces: tuple[tuple[int, np.ndarray], ...] = ()
    """The float arena's initial values that are not zero-filled buffers: (offset, values), in offset order;
    ``f`` as placed is zeros with these written in (:meth:`initial_floats`)."""

    def initial_floats(self, out: np.ndarray) -> None:
        """Write the float arena as placed into ``out`` (a graph's reset): zeros, then :attr:`f_pieces`."""
        out[:] = 0.0
        _write_pieces(out, self.f_pieces)


def _write_pieces(out: np.ndarray, pieces: Sequence[tuple[int, np.ndarray]]) -> None:
    """Write each (offset, values) piece of a float arena into ``out``."""
    for off, values in pieces:
        out[off:off + values.size] = values


class _Builder:
    """Collects the float arena's pieces (offset order) and the int table; :meth:`floats` allocates the arena once.

    A port buffer without a fill is zeros: it is only counted, never allocated here, so the arena is one zeroed
    allocation with the filled pieces written into it (a wide graph's buffers are neither built twice nor copied).
    """

    def __init__(self, block_rows: int):
        self.rows = block_rows
        self.f_chunks: list[tuple[int, np.ndarray]] = []
        self.f_size = 0
        self.ints: list[int] = [0] * HEADER

    def f_alloc(self, values: np.ndarray | None, size: int = 0) -> int:
        """Offset of ``values`` (or of ``size`` zeros when ``values`` is None) in the float arena."""
        off = self.f_size
        if values is None:
            self.f_size += size
            return off
        values = np.array(values, dtype=np.float64).ravel()  # a copy: the arena's initial values, kept for resets
        self.f_chunks.append((off, values))
        self.f_size += values.size
        return off

    def floats(self) -> np.ndarray:
        f = np.zeros(self.f_size)  # zero pages are not touched until written
        _write_pieces(f, self.f_chunks)
        return f

    def i_slot(self, value: int = 0) -> int:
        self.ints.append(int(value))
        return len(self.ints) - 1

    def port(self, width: int, fill: np.ndarray | None = None) -> PortSlot:
        if fill is None:
            off = self.f_alloc(None, self.rows * width)
        else:
            data = np.zeros((self.rows, width))
            data[:] = fill
            off = self.f_alloc(data)
        return PortSlot(off, width, self.i_slot(width), self.i_slot(off))

    def hold(self, width: int) -> PortSlot:
        off = self.f_alloc(None, width)
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


def _signal_entry(slot: PortSlot, column: int, redirect: bool) -> list[int]:
    """The input/output table entry of one graph signal (:data:`SIGNAL`)."""
    return SIGNAL.pack({"offset_index": slot.offset_index, "width": slot.width, "column": column,
                        "own_offset": slot.offset, "redirect": int(redirect)}).tolist()


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
        b.ints += _signal_entry(slot, col, True)
        in_columns[name] = (col, slot.width)
        col += slot.width
    col = 0
    out_table = len(b.ints)
    redirected = {id(s) for s in graph_inputs.values()}
    for name, slot in graph_outputs.items():
        # The first output of a port not read from the inputs is written in place (zero copy).
        in_place = id(slot) not in redirected
        redirected.add(id(slot))
        b.ints += _signal_entry(slot, col, in_place)
        out_columns[name] = (col, slot.width)
        col += slot.width

    for slots, istate in int_state:
        start = len(b.ints)
        b.ints += istate.tolist()
        b.ints[slots.si[0]] = start
        b.ints[slots.si[1]] = start + istate.size

    ints = np.array(b.ints, dtype=np.int64)
    ints[:HEADER] = INT_HEADER.pack({"block_rows": block_rows, "n_in": len(graph_inputs), "n_out": len(graph_outputs),
                                     "in_table": in_table, "out_table": out_table,
                                     "in_width": sum(s.width for s in graph_inputs.values()),
                                     "out_width": sum(s.width for s in graph_outputs.values())})
    f = b.floats()
    return Layout(f, ints, block_rows, graph_inputs, graph_outputs, node_slots, in_columns, out_columns,
                  tuple(b.f_chunks))
