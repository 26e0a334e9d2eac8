"""Tier 0 (dispatch): one generic compiled driver for every graph, calling cached per-kernel wrappers.

The fused tier (:mod:`flowtex.graph.codegen`) generates and compiles one
``block`` function per graph *structure*: any structural edit costs a full
numba compile. Here ``block(f, i, n)`` is one fixed function, compiled once
per machine; what differs between graphs is data: a *dispatch table* appended
to the int arena, whose position is in header slot ``DISPATCH``::

    i[tab]     number of nodes
    i[tab + 1] 1 if the graph has a feedback loop (tick-by-tick execution)
    then per node, STRIDE items:
      wrapper address (kernel), emit wrapper address, absorb wrapper address,
      descriptor position, position of the node's ``every``,
      holds position, number of holds, 1 if the node breaks cycles (delay)

A node's descriptor lists positions in ``i`` (parameter, state and int-state
bounds, then each input's and output's offset and width); a hold is
(hold offset position, output offset position, output width position). The
driver follows exactly the call sequence the fused ``block`` has (same
kernels, same views, same order, same hold copies), so both tiers give the
same numbers bit for bit; each kernel call costs one indirect call (~2-5 ns).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np
from numba import njit

from .arena import DISPATCH, FAULT, TICK, Layout, NodeSlots, PortSlot
from .kernels import call_pointer, copy_row
from .prewarm import start_helper
from .resolve import ResolvedGraph, ResolvedNode
from .wrappers import load_wrapper, wrapper_path

STRIDE = 9


@njit(inline="always", cache=True)
def _guarded(i, e, fn, d, fb, ib, t, r, every):  # pragma: no cover - compiled
    """Run the node on row ``r`` if tick ``t`` is one of its ticks and refresh its holds, else repeat its holds."""
    holds, nh = i[e + 5], i[e + 6]
    if t % every == 0:
        call_pointer(fn, fb, ib, d, r, 1)
        for h in range(nh):
            q = holds + 3 * h
            w = i[i[q + 2]]
            copy_row(fb, i[i[q]], i[i[q + 1]] + r * w, w)
    else:
        for h in range(nh):
            q = holds + 3 * h
            w = i[i[q + 2]]
            copy_row(fb, i[i[q + 1]] + r * w, i[i[q]], w)


@njit(cache=True, nogil=True)
def block(f, i, n):  # pragma: no cover - compiled
    """Advance the graph whose dispatch table is in ``i`` by ``n`` ticks (``1 <= n <=`` block rows)."""
    t0 = i[TICK]
    fb = np.int64(f.ctypes.data)
    ib = np.int64(i.ctypes.data)
    tab = i[DISPATCH]
    count = i[tab]
    if i[tab + 1] == 0:  # acyclic: node by node over the whole block
        for k in range(count):
            e = tab + 2 + STRIDE * k
            every = i[i[e + 4]]
            if every == 1:
                call_pointer(i[e], fb, ib, i[e + 3], 0, n)
            else:
                for r in range(n):
                    _guarded(i, e, i[e], i[e + 3], fb, ib, t0 + r, r, every)
            if i[FAULT] != 0:  # the kernel raised: stop here (Graph reports the node)
                return
    else:  # a feedback loop: tick by tick, delays emit first and absorb last
        for r in range(n):
            for k in range(count):
                e = tab + 2 + STRIDE * k
                split = i[e + 7]
                fn = i[e + 1] if split else i[e]
                d = i[e + 8] if split else i[e + 3]
                every = i[i[e + 4]]
                if every == 1:
                    call_pointer(fn, fb, ib, d, r, 1)
                else:
                    _guarded(i, e, fn, d, fb, ib, t0 + r, r, every)
                if i[FAULT] != 0:
                    return
            for k in range(count):
                e = tab + 2 + STRIDE * k
                if i[e + 7]:
                    call_pointer(i[e + 2], fb, ib, i[e + 3], r, 1)
            if i[FAULT] != 0:
                return
    i[TICK] = t0 + n


def wrappers_of(rn: ResolvedNode, cyclic: bool) -> list[tuple[Callable, int, int]]:
    """(kernel, inputs, outputs) of each wrapper node ``rn`` needs: its kernel, and for a delay in a loop emit and absorb.

    Emit writes the outputs (it gets its own descriptor); absorb reads the inputs (the full descriptor, inputs first).
    """
    n_in, n_out = len(rn.cls.inputs), len(rn.cls.outputs)
    used = [(rn.cls.get_kernel(), n_in, n_out)]
    if cyclic and rn.cls.breaks_cycles:
        used += [(rn.cls.get_kernel("emit_kernel"), 0, n_out), (rn.cls.get_kernel("absorb_kernel"), n_in, 0)]
    return used


def dispatch_table(rg: ResolvedGraph, layout: Layout) -> tuple[np.ndarray, list[str]]:
    """The int arena with the dispatch table appended (and ``DISPATCH`` set), and one line per node naming its wrappers.

    Loads (or compiles, once per kernel and machine) every wrapper the graph needs.
    """
    base = layout.i.size
    count = len(rg.nodes)
    entries: list[int] = []
    extra: list[int] = []
    lines = []
    start_extra = base + 2 + STRIDE * count

    def descriptor(ns: NodeSlots, ports: list[PortSlot]) -> int:
        pos = start_extra + len(extra)
        extra.extend([ns.p[0], ns.p[1], ns.s[0], ns.s[1], ns.si[0], ns.si[1]])
        for s in ports:
            extra.extend([s.offset_index, s.width_index])
        return pos

    used = {name: wrappers_of(rn, rg.cyclic) for name, rn in rg.nodes.items()}
    helper = start_helper([u for us in used.values() for u in us])  # a cold cache: compile on two cores
    for name, rn in rg.nodes.items():
        ns = layout.nodes[name]
        split = rg.cyclic and rn.cls.breaks_cycles
        ins = [ns.inputs[p] for p in rn.cls.inputs]
        outs = [ns.outputs[p] for p in rn.cls.outputs]
        fns = [load_wrapper(*u).address for u in used[name]] + [0, 0]
        desc = descriptor(ns, ins + outs)
        emit_desc = descriptor(ns, outs) if split else 0
        holds = start_extra + len(extra)
        for port, hold in ns.holds.items():
            out = ns.outputs[port]
            extra.extend([hold.offset_index, out.offset_index, out.width_index])
        entries += [fns[0], fns[1], fns[2], desc, ns.every, holds, len(ns.holds), int(split), emit_desc]
        lines.append(f"{name} ({rn.cls.type_name}): " + ", ".join(wrapper_path(*u).name for u in used[name]))
    if helper is not None:
        helper.wait()  # it finishes the driver, or an entry this process is waiting for anyway
    table = np.array([count, int(rg.cyclic)] + entries + extra, dtype=np.int64)
    ints = np.concatenate([layout.i, table])
    ints[DISPATCH] = base
    return ints, lines


def driver_source() -> str:
    """The driver's source (``flowtex graph --show-code`` prints it for the dispatch tier)."""
    return inspect.getsource(_guarded) + "\n\n" + inspect.getsource(block)
