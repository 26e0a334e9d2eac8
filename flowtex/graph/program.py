"""What the runtime needs from a compiled graph: the tick-program protocol, declared once.

The live loop, the replay, the CAN codecs and the fused live tick (``flowtex/runtime``)
drive a graph tick by tick through its arenas rather than through ``run()``. This
module names that seam, so the runtime is typed against it instead of probing
attributes. :class:`~flowtex.graph.compiled.Graph` is the implementation
(tests/runtime/test_seams.py checks it provides every member); the protocol lives
in the graph layer so the runtime, above it, can name it without importing the
compile service.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..node_decl import PortSpec
from .spec import GraphSpec


@runtime_checkable
class TickProgram(Protocol):
    """A compiled graph as the runtime drives it: one float64 and one int64 arena, stepped in place.

    Every graph input and output is a contiguous float64 slice of :attr:`f`; a tick
    reads the input slices, runs the generated ``block`` on the arenas and leaves the
    output slices holding that tick's values. Nothing here allocates per tick.
    """

    spec: GraphSpec
    """The checked graph file (``spec.path``: the YAML it came from)."""
    seed: int
    """The noise seed the last :meth:`reset` used."""
    f: np.ndarray
    """The float64 arena: port buffers, parameters and float state (C-contiguous, 1-D, never reallocated)."""
    i: np.ndarray
    """The int64 arena: tick counter, fault word, schedule tables and integer state (C-contiguous, 1-D)."""

    @property
    def name(self) -> str: ...

    @property
    def rate(self) -> float:
        """Base tick rate in Hz."""
        ...

    @property
    def inputs(self) -> dict[str, PortSpec]: ...

    @property
    def outputs(self) -> dict[str, PortSpec]: ...

    @property
    def block_function(self) -> Any:
        """The compiled ``block(f, i, n)`` numba function (``n`` ticks on the arenas), for code that fuses a tick into its own call."""
        ...

    def block_source(self) -> tuple[list[str], dict[str, Any]] | None:
        """``block``'s body (lines over ``f``, ``i`` and ``n``) and the kernels its lines name, for code that holds a
        tick in its own compiled function; None when it can only call :attr:`block_function`."""
        ...

    def with_block_rows(self, rows: int) -> TickProgram:
        """The same program (code, parameters, seed; fresh state) with port buffers of ``rows`` rows; ``self`` if it has them."""
        ...

    def input_view(self, name: str) -> np.ndarray:
        """Writable float64 view (a slice of :attr:`f`) of graph input ``name``'s current value."""
        ...

    def output_view(self, name: str) -> np.ndarray:
        """Float64 view (a slice of :attr:`f`) of graph output ``name``'s latest value."""
        ...

    def step_block(self, n: int = 1) -> None:
        """Advance ``n`` ticks on whatever the input views hold; raises the kernel's fault as a FlowtexError."""
        ...

    def reset(self, seed: int | None = None) -> None:
        """Restore the initial state and re-seed random nodes (``seed`` None: the current one)."""
        ...

    def warm(self) -> None:
        """One tick on scratch copies of the arenas: the code comes back into the CPU caches, nothing observable changes."""
        ...

    def scratch_arenas(self) -> tuple[np.ndarray, np.ndarray]:
        """Float and int arenas shaped like :attr:`f` and :attr:`i`, for effect-free warm-up ticks."""
        ...

