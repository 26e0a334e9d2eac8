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

This backend compiles in the calling process and starts none; a helper process
that compiles missing wrappers on a second core is the compile service's
business (:mod:`flowtex.compile.service`), given :func:`needed_wrappers`.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from .arena import DESCRIPTOR, DISPATCH, DISPATCH_ENTRY, DISPATCH_HEAD, FAULT, HOLD, TICK, Layout, NodeSlots, PortSlot
from .codegen import run_source
from .fused import BLOCK_SIG, RUN_SIG, Compiled, entry
from .jit import load_generated
from .kernels import call_pointer, copy_row
from .resolved import ResolvedGraph, ResolvedNode
from .wrappers import REBUILT, load_wrapper, wrapper_path

STRIDE = DISPATCH_ENTRY.size()
"""Ints per node entry (:data:`~flowtex.graph.arena.DISPATCH_ENTRY`); the positions below come from the same declaration."""
HEAD = DISPATCH_HEAD.size()
T_COUNT = DISPATCH_HEAD.const("count")
T_CYCLIC = DISPATCH_HEAD.const("cyclic")
D_KERNEL = DISPATCH_ENTRY.const("kernel")
D_EMIT = DISPATCH_ENTRY.const("emit")
D_ABSORB = DISPATCH_ENTRY.const("absorb")
D_DESC = DISPATCH_ENTRY.const("desc")
D_EVERY = DISPATCH_ENTRY.const("every")
D_HOLDS = DISPATCH_ENTRY.const("holds")
D_NHOLDS = DISPATCH_ENTRY.const("n_holds")
D_SPLIT = DISPATCH_ENTRY.const("split")
D_EMIT_DESC = DISPATCH_ENTRY.const("emit_desc")
H_STRIDE = HOLD.size()
H_HOLD = HOLD.const("hold")
H_OUT = HOLD.const("out")
H_WIDTH = HOLD.const("width")


@njit(inline="always", cache=True)
def _guarded(i, e, fn, d, fb, ib, t, r, every):  # pragma: no cover - compiled
    """Run the node on row ``r`` if tick ``t`` is one of its ticks and refresh its holds, else repeat its holds."""
    holds, nh = i[e + D_HOLDS], i[e + D_NHOLDS]
    if t % every == 0:
        call_pointer(fn, fb, ib, d, r, 1)
        for h in range(nh):
            q = holds + H_STRIDE * h
            w = i[i[q + H_WIDTH]]
            copy_row(fb, i[i[q + H_HOLD]], i[i[q + H_OUT]] + r * w, w)
    else:
        for h in range(nh):
            q = holds + H_STRIDE * h
            w = i[i[q + H_WIDTH]]
            copy_row(fb, i[i[q + H_OUT]] + r * w, i[i[q + H_HOLD]], w)


@njit(cache=True, nogil=True)
def block(f, i, n):  # pragma: no cover - compiled
    """Advance the graph whose dispatch table is in ``i`` by ``n`` ticks (``1 <= n <=`` block rows)."""
    t0 = i[TICK]
    fb = np.int64(f.ctypes.data)
    ib = np.int64(i.ctypes.data)
    tab = i[DISPATCH]
    count = i[tab + T_COUNT]
    if i[tab + T_CYCLIC] == 0:  # acyclic: node by node over the whole block
        for k in range(count):
            e = tab + HEAD + STRIDE * k
            every = i[i[e + D_EVERY]]
            if every == 1:
                call_pointer(i[e + D_KERNEL], fb, ib, i[e + D_DESC], 0, n)
            else:
                for r in range(n):
                    _guarded(i, e, i[e + D_KERNEL], i[e + D_DESC], fb, ib, t0 + r, r, every)
            if i[FAULT] != 0:  # the kernel raised: stop here (Graph reports the node)
                return
    else:  # a feedback loop: tick by tick, delays emit first and absorb last
        for r in range(n):
            for k in range(count):
                e = tab + HEAD + STRIDE * k
                split = i[e + D_SPLIT]
                fn = i[e + D_EMIT] if split else i[e + D_KERNEL]
                d = i[e + D_EMIT_DESC] if split else i[e + D_DESC]
                every = i[i[e + D_EVERY]]
                if every == 1:
                    call_pointer(fn, fb, ib, d, r, 1)
                else:
                    _guarded(i, e, fn, d, fb, ib, t0 + r, r, every)
                if i[FAULT] != 0:
                    return
            for k in range(count):
                e = tab + HEAD + STRIDE * k
                if i[e + D_SPLIT]:
                    call_pointer(i[e + D_ABSORB], fb, ib, i[e + D_DESC], r, 1)
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


def needed_wrappers(rg: ResolvedGraph) -> list[tuple[Callable, int, int]]:
    """Every (kernel, inputs, outputs) wrapper the graph ``rg`` needs, in execution order."""
    return [u for rn in rg.nodes.values() for u in wrappers_of(rn, rg.cyclic)]


def dispatch_table(rg: ResolvedGraph, layout: Layout) -> tuple[np.ndarray, list[str]]:
    """The int arena with the dispatch table appended (and ``DISPATCH`` set), and one line per node naming its wrappers.

    Loads (or compiles, once per kernel and machine) every wrapper the graph needs.
    """
    base = layout.i.size
    count = len(rg.nodes)
    entries: list[int] = []
    extra: list[int] = []
    lines = []
    start_extra = base + HEAD + STRIDE * count

    def descriptor(ns: NodeSlots, ports: list[PortSlot]) -> int:
        pos = start_extra + len(extra)
        extra.extend(DESCRIPTOR.pack({"p": ns.p, "s": ns.s, "si": ns.si,
                                      "ports": [k for s in ports for k in (s.offset_index, s.width_index)]},
                                     n_ports=len(ports)).tolist())
        return pos

    used = {name: wrappers_of(rn, rg.cyclic) for name, rn in rg.nodes.items()}
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
            extra.extend(HOLD.pack({"hold": hold.offset_index, "out": out.offset_index, "width": out.width_index}).tolist())
        entries += DISPATCH_ENTRY.pack({"kernel": fns[0], "emit": fns[1], "absorb": fns[2], "desc": desc, "every": ns.every,
                                        "holds": holds, "n_holds": len(ns.holds), "split": int(split),
                                        "emit_desc": emit_desc}).tolist()
        lines.append(f"{name} ({rn.cls.type_name}): " + ", ".join(wrapper_path(*u).name for u in used[name]))
    table = np.array(DISPATCH_HEAD.pack({"count": count, "cyclic": int(rg.cyclic)}).tolist() + entries + extra, dtype=np.int64)
    ints = np.concatenate([layout.i, table])
    ints[DISPATCH] = base
    return ints, lines


@functools.cache
def driver_source() -> str:
    """The driver's source (``flowtex graph --show-code`` prints it for the dispatch tier), read once a process."""
    return inspect.getsource(_guarded) + "\n\n" + inspect.getsource(block)


_DISPATCH_RUN: Any = None


def dispatch_run() -> Any:
    """The dispatch tier's ``run``: the fused tier's run loop (one source) over the generic driver."""
    global _DISPATCH_RUN
    if _DISPATCH_RUN is None:
        source = "# Generated by flowtex: the run loop over the dispatch tier's generic driver.\n" \
                 "import numpy as np\nfrom numba import njit\nfrom flowtex.graph.kernels import view\n\n\n" + run_source()
        module = load_generated(source, {"block": block}, "dispatch-run")
        block.compile(BLOCK_SIG)
        module.run.compile(RUN_SIG)
        _DISPATCH_RUN = module.run
    return _DISPATCH_RUN


def dispatch_step(block_entry: Callable[..., Any], in_offsets: list[int], out_offsets: list[int]) -> Callable[..., tuple]:
    """A Python ``step(f, i, x0, ...)`` for the dispatch tier: write the scalars, one driver call, read the scalars.

    A non-number raises ``TypeError`` like the fused tier's compiled ``step``.
    """
    args = "".join(f", x{k}" for k in range(len(in_offsets)))
    lines = [f"def step(f, i{args}):"]
    if in_offsets:
        lines.append("    try:")
        lines += [f"        f[{off}] = float(x{k})" for k, off in enumerate(in_offsets)]
        lines += ["    except ValueError:", "        raise TypeError('step(): scalar inputs must be numbers') from None"]
    lines.append("    BLOCK(f, i, 1)")
    values = [f"f.item({off})" for off in out_offsets] or ["0.0"]
    lines.append(f"    return ({', '.join(values)},)")
    namespace: dict[str, Any] = {"BLOCK": block_entry}
    exec("\n".join(lines), namespace)  # generated from integer offsets only
    return namespace["step"]


def compile_dispatch(rg: ResolvedGraph, layout: Layout, step_in: list[str], step_out: list[str],
                     tables_done: Callable[[], None] | None = None) -> Compiled:
    """The dispatch tier for ``rg``: load (or compile, once per kernel) its wrappers and build the dispatch table.

    ``tables_done`` is called once the wrappers are loaded and before the driver is (the compile service waits
    there for a helper process compiling wrappers and the driver beside this one).
    """
    before = len(REBUILT)
    ints, lines = dispatch_table(rg, layout)
    if tables_done is not None:
        tables_done()
    run = dispatch_run()
    step = dispatch_step(entry(block), [layout.graph_inputs[n].offset for n in step_in],
                         [layout.graph_outputs[n].offset for n in step_out])
    source = (f"# Dispatch tier (tier 0) of graph {rg.spec.name!r}: the generic driver below runs the nodes in this order,\n"
              "# calling each node's cached wrapper (source in the named file of the kernel cache) through its address:\n"
              + "".join(f"#   {k}. {line}\n" for k, line in enumerate(lines, start=1)) + "\n" + driver_source())
    entries = {"block": block, "run": run, "step": step}
    return Compiled("dispatch", ints, source, entries.__getitem__, REBUILT[before:])
