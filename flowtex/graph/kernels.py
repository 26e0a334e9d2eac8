"""Tiny jitted helpers the generated graph code calls.

``view``, ``fslice`` and ``islice`` are ordinary compiled functions, which
LLVM inlines when it optimizes the module that calls them; numba's own
``inline="always"`` would instead type and lower their bodies again at every
call site, and a generated module has one per port and per node (some 100 in a
15-node graph), which made a fused compile about a third slower for the same
machine code (docs/engine.md, "What compiles when"). The rest, called at a few
sites each, are inlined by numba.

Port, parameter and state views are made with ``numba.carray`` from the
arena's data pointer rather than by slicing: a sliced view carries the
arena's reference count, which numba increments and decrements atomically at
every kernel call; a ``carray`` view carries none. Over a 10-node graph
stepped one tick at a time this is the difference between ~0.75 µs and
~0.3 µs per tick. The arena outlives every view: the Graph object owns it.
"""

from __future__ import annotations

import numpy as np
from numba import carray, njit, types
from numba.extending import intrinsic

from ..cache import configure_numba_cache
from .arena import FAULT  # (its imports decorate no numba function: the cache folder below is still chosen in time)

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)

ITEM = 8  # bytes per float64 / int64 arena element



def _pointer_to(item: types.Type):
    """A numba intrinsic turning an integer address into a ``CPointer(item)`` (for ``carray``)."""

    def pointer(typingctx, address):
        sig = types.CPointer(item)(address)

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.CPointer(item)))

        return sig, codegen

    pointer.__name__ = pointer.__qualname__ = f"{item}_pointer"
    return intrinsic(pointer)


_float_ptr = _pointer_to(types.float64)
_int_ptr = _pointer_to(types.int64)
_byte_ptr = _pointer_to(types.uint8)


@njit(inline="always", cache=True)
def bytes_at(address: int, n: int) -> np.ndarray:
    """The ``n`` bytes at ``address`` as a uint8 array (no reference counting: the caller keeps the memory alive)."""
    return carray(_byte_ptr(address), n)


@njit(cache=True)
def view(base: int, offset: int, width: int, rows: int) -> np.ndarray:
    """``rows x width`` view of the float arena (data address ``base``) starting at ``offset``."""
    return carray(_float_ptr(base + offset * ITEM), (rows, width))


@njit(cache=True)
def fslice(base: int, start: int, stop: int) -> np.ndarray:
    """``f[start:stop]`` of the float arena at data address ``base``, without reference counting."""
    return carray(_float_ptr(base + start * ITEM), stop - start)


@njit(cache=True)
def islice(base: int, start: int, stop: int) -> np.ndarray:
    """``i[start:stop]`` of the int arena at data address ``base``, without reference counting."""
    return carray(_int_ptr(base + start * ITEM), stop - start)


@njit(inline="always", cache=True)
def copy_row(base: int, dst: int, src: int, width: int) -> None:
    """Copy ``width`` values between arena offsets (hold logic of multi-rate nodes).

    Offsets are relative to the float arena's data address ``base``; during
    ``run`` a port's offset may point into the caller's input or output array.
    """
    d = carray(_float_ptr(base + dst * ITEM), width)
    s = carray(_float_ptr(base + src * ITEM), width)
    for q in range(width):
        d[q] = s[q]


@njit(inline="always", cache=True)
def at(base: int, k: int) -> int:
    """Item ``k`` of the int arena at data address ``base`` (the dispatch tier's table reads)."""
    return carray(_int_ptr(base + k * ITEM), 1)[0]


@njit(inline="always", cache=True)
def record_fault(ib: int, d: int, r: int, n: int) -> None:
    """Note in the int arena (data address ``ib``) that the kernel of descriptor ``d`` raised on rows ``r .. r+n-1``."""
    slots = carray(_int_ptr(ib + FAULT * ITEM), 3)
    slots[0] = d
    slots[1] = r
    slots[2] = n


@intrinsic
def call_pointer(typingctx, fn, a, b, c, d, e):
    """Call the C function at address ``fn`` as ``void(int64 a, int64 b, int64 c, int64 d, int64 e)``.

    The dispatch tier's driver calls each node's compiled wrapper (a numba ``cfunc``)
    through its address, read from the int arena at run time.
    """
    sig = types.void(types.int64, types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        from llvmlite import ir

        i64 = ir.IntType(64)
        fnty = ir.FunctionType(ir.VoidType(), [i64] * 5)
        values = list(args)  # the signature is all int64: numba casts the arguments before the call
        builder.call(builder.inttoptr(values[0], fnty.as_pointer()), values[1:])
        return context.get_dummy_value()

    return sig, codegen
