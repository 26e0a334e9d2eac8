"""A node kernel that raised while the graph ran: one error naming the node, on either tier.

The fused tier's compiled ``run``/``block`` propagate a kernel's exception to
Python with the kernel's file and line in its traceback. The dispatch tier's
wrappers are C callbacks, which cannot propagate an exception: each wrapper
catches it and records the node's descriptor in the int arena's ``FAULT``
slots, and the driver stops (:mod:`flowtex.graph.wrappers`,
:mod:`flowtex.graph.dispatch`). Either way the caller gets a
:class:`KernelError` naming the node, not garbage output nor an "internal
error".
"""

from __future__ import annotations

import inspect
from types import TracebackType

import numpy as np

from ..cache import shares_compiled_code
from ..errors import FlowtexError
from ..nodecheck import kernel_location
from .arena import DISPATCH, DISPATCH_ENTRY, DISPATCH_HEAD, FAULT, TICK
from .resolved import ResolvedGraph, ResolvedNode


class KernelError(FlowtexError):
    """A node kernel raised while the graph ran; the run stopped (exit code 1, nothing written)."""


def _node_text(rg: ResolvedGraph, names: list[str]) -> str:
    cls = rg.nodes[names[0]].cls
    which = ", ".join(repr(n) for n in names)
    return f"node {which} ({cls.type_name})" if len(names) == 1 else f"nodes {which} ({cls.type_name}, one of them)"


def dispatch_fault(rg: ResolvedGraph, ints: np.ndarray) -> KernelError | None:
    """The error recorded in ``ints`` by the dispatch tier's wrappers (None when no kernel raised)."""
    d = int(ints[FAULT])
    if d == 0:
        return None
    row, rows = int(ints[FAULT + 1]), int(ints[FAULT + 2])
    tab = int(ints[DISPATCH]) + DISPATCH_HEAD.size()
    stride = DISPATCH_ENTRY.size()
    descs = (DISPATCH_ENTRY.const("desc"), DISPATCH_ENTRY.const("emit_desc"))
    name = next((n for k, n in enumerate(rg.nodes) if d in (ints[tab + stride * k + descs[0]], ints[tab + stride * k + descs[1]])),
                next(iter(rg.nodes)))
    rn = rg.nodes[name]
    first = int(ints[TICK]) + row
    ticks = f"tick {first}" if rows == 1 else f"ticks {first}..{first + rows - 1}"
    return KernelError(f"{kernel_location(rn.cls)}: {_node_text(rg, [name])}: kernel raised an exception in {ticks}; the run "
                       "stopped (the dispatch tier cannot show the exception's message: --compile fused shows it)")


def _kernel_frames(exc: BaseException) -> list[tuple[str, int]]:
    frames = []
    tb: TracebackType | None = exc.__traceback__
    while tb is not None:
        frames.append((tb.tb_frame.f_code.co_filename, tb.tb_lineno))
        tb = tb.tb_next
    return frames


def _defines(rn: ResolvedNode, path: str, line: int) -> bool:
    """True when ``path:line`` lies inside one of ``rn``'s kernels."""
    for attr in ("kernel", "emit_kernel", "absorb_kernel"):
        try:
            func = getattr(rn.cls.get_kernel(attr), "py_func", None)
        except AttributeError:
            continue
        if func is None:
            continue
        try:
            lines, start = inspect.getsourcelines(func)
            source = inspect.getsourcefile(func)
        except (OSError, TypeError):
            continue
        if source and shares_compiled_code(path, func) and start <= line < start + len(lines):
            return True
    return False


def raised_fault(rg: ResolvedGraph, exc: Exception, ints: np.ndarray) -> KernelError:
    """A :class:`KernelError` for an exception the fused tier's compiled code raised, naming the kernel's node and line."""
    what = f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__
    for path, line in reversed(_kernel_frames(exc)):
        names = [name for name, rn in rg.nodes.items() if _defines(rn, path, line)]
        if names:
            where = kernel_location(rg.nodes[names[0]].cls, line)
            return KernelError(f"{where}: {_node_text(rg, names)}: kernel raised {what} in the block of ticks from "
                               f"{int(ints[TICK])}; the run stopped")
    return KernelError(f"graph {rg.spec.name!r}: a node kernel raised {what} in the block of ticks from {int(ints[TICK])}; "
                       "the run stopped")
