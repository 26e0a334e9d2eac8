"""The node contract: declared ports and parameters, build-time Python, a numba kernel.

A node type is a subclass of :class:`Node` with a ``type_name``. It declares

* ``params``: ``{name: Param}`` -- typed, bounded, documented; validated before
  the node is constructed, so ``__init__`` sees clean values in ``self.p``;
* ``inputs`` / ``outputs``: ``{name: Port}`` -- shape and unit of each port;
* ``kernel``: a numba ``@njit`` function called once per block of ticks.

Kernel calling convention (the same offline and live)::

    kernel(p, s, si, in_1, ..., in_k, out_1, ..., out_m)

``p`` (float64[:]) holds the node's parameter values, ``s`` (float64[:]) its
float state and ``si`` (int64[:]) its integer state, all as returned by
:meth:`Node.build`. Each port is a C-contiguous float64 array of shape
``(n, width)``: row ``t`` is tick ``t`` of the block, ``width`` is the product
of the port's shape (1 for a scalar). ``n`` is 1 when the graph is stepped
live and up to the block size offline; a kernel must give the same numbers
either way. Kernels must not allocate.

Build-time Python (``__init__``, :meth:`Node.resolve`, :meth:`Node.build`)
runs once per graph build: load files, design filters, size the state.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .cache import configure_numba_cache
from .dsp.layout import Field, Layout, Memory  # noqa: F401  (re-exported: plugins declare their memory with it)
from .node_decl import (  # noqa: F401  (re-exported: the node API is one import for plugins)
    PARAM_KINDS,
    REQUIRED,
    BuildContext,
    NodeState,
    Param,
    Port,
    PortSpec,
    check,
    expected_shape,
    resolve_declared,
    simplify_unit,
    suggest,
    unit_product,
)

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)


class Node:
    """Base class of every node type. See the module docstring for the contract."""

    type_name: ClassVar[str] = ""
    params: ClassVar[dict[str, Param]] = {}
    inputs: ClassVar[dict[str, Port]] = {}
    outputs: ClassVar[dict[str, Port]] = {}
    version: ClassVar[str] = "1"
    kernel: ClassVar[Callable[..., None]]
    uses_seed: ClassVar[bool] = False
    """True for nodes with random state; they implement :meth:`seed_state`."""
    breaks_cycles: ClassVar[bool] = False
    """True for pure delays: output at tick t depends only on inputs before t.

    Such nodes also provide ``emit_kernel(p, s, si, out)`` and
    ``absorb_kernel(p, s, si, inp)`` used when the graph has a feedback loop.
    """

    memory: ClassVar[Memory | None] = None
    """The node's parameters and state declared once (:class:`~flowtex.dsp.layout.Memory`): ``build`` packs with
    :meth:`pack_state`, kernels index with constants taken from the same declaration. ``None``: a node written to the
    positional API (its ``build`` fills ``NodeState`` arrays itself)."""

    latency_doc: ClassVar[str] = ""
    """How the node's latency follows from its parameters (shown by ``flowtex nodes``); see :meth:`latency_samples`."""

    def __init__(self, name: str, params: dict[str, Any], context: BuildContext):
        self.name = name
        self.p = params
        self.context = context

    @classmethod
    def summary(cls) -> str:
        """First line of the class docstring."""
        doc = (cls.__doc__ or "").strip()
        return doc.splitlines()[0] if doc else ""

    @classmethod
    def get_kernel(cls, attr: str = "kernel") -> Callable[..., None]:
        for klass in cls.__mro__:
            if attr in klass.__dict__:
                value = klass.__dict__[attr]
                return value.__func__ if isinstance(value, staticmethod) else value
        raise AttributeError(f"node type {cls.type_name!r} defines no {attr}")

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        """Shapes and units of the outputs, given those of the connected inputs.

        The default follows the declared ``Port`` shapes and units (with
        ``"=name"`` references). Override when an output depends on a
        parameter (for example on the order of a loaded model). Raise
        :class:`ParamError` for an input the node cannot accept.
        """
        return {name: resolve_declared(port, inputs) for name, port in self.outputs.items()}

    @classmethod
    def own_every(cls, params: dict[str, Any], rate: float, input_every: dict[str, int]) -> int | None:
        """Ticks between runs for a node whose parameters and inputs fix its schedule (e.g. ``resample``), else None.

        ``params`` are validated; ``rate`` is the graph's base rate in Hz;
        ``input_every`` is as in :attr:`BuildContext.input_every`. The
        graph then runs the node every that many ticks (a different ``every:``
        in the graph file is an error). Raise :class:`ParamError` for a rate
        that does not divide the base rate.
        """
        return None

    @classmethod
    def check_params(cls, params: dict[str, Any]) -> None:
        """Check validated ``params`` against each other before any file they name is read (raise :class:`ParamError`).

        For rules the declarations cannot state, such as two parameters that exclude each other, so that such a
        mistake is reported as itself rather than as a problem with a file. The default checks nothing.
        """

    def latency_samples(self) -> int:
        """Fixed delay from input to output, in ticks of this node (0: none, the default).

        Nodes that work on frames or FIR filters override it; ``flowtex graph``
        states it in samples and milliseconds. Called after construction, with
        ``self.p`` and ``self.context`` set.
        """
        return 0

    def input_default(self, name: str, spec: PortSpec) -> np.ndarray:
        """Value an unconnected optional input reads (shape ``spec.width``)."""
        return np.full(spec.width, self.inputs[name].default, dtype=np.float64)

    def build(self, inputs: dict[str, PortSpec], outputs: dict[str, PortSpec]) -> NodeState:
        """Allocate parameter and state arrays for the kernel (default: the declared :attr:`memory` with no sizes)."""
        return self.pack_state() if self.memory is not None else NodeState()

    def pack_state(self, sizes: dict[str, int] | None = None, *, params: dict[str, Any] | np.ndarray | None = None,
                   state: dict[str, Any] | np.ndarray | None = None, istate: dict[str, Any] | np.ndarray | None = None
                   ) -> NodeState:
        """The :class:`NodeState` this type's :attr:`memory` declares for build-time ``sizes``, fields set from the values
        (or an array a helper packed with the same layout, its length checked; :meth:`Memory.pack`).

        The sizes are kept in ``self.memory_sizes`` so that checks can compare the packed arrays with the declaration.
        """
        if self.memory is None:
            raise TypeError(f"node type {self.type_name!r} declares no memory; set the class attribute memory = Memory(...)")
        self.memory_sizes = dict(sizes or {})
        p, s, si = self.memory.pack(self.memory_sizes, params, state, istate)
        return NodeState(params=p, state=s, istate=si)

    def seed_state(self, state: np.ndarray, istate: np.ndarray, seed: np.random.SeedSequence) -> None:
        """Re-seed random state in place (only for ``uses_seed`` nodes)."""
        raise NotImplementedError

    @classmethod
    def processor(cls, rate: float = 1000.0, seed: int = 0, name: str | None = None, base_dir: str | Path = ".",
                  nonfinite: str = "error", every: int = 1, input_every: Mapping[str, int] | None = None,
                  params: Mapping[str, Any] | None = None, **keyword_params: Any) -> Any:
        """This node's build and kernel on plain arrays, state kept between calls (flowtex.node_processor).

        ``rate`` (Hz) and ``seed`` are the graph's; ``name`` the node's name in a graph (it seeds random
        nodes, so a processor named like a graph's node reproduces it); ``nonfinite`` what a call does with NaN/inf
        inputs (as ``Graph.run``'s: ``error``, ``hold``, ``zero`` or ``pass``); ``every`` the node's rate divider (a
        graph's ``every:``) and ``input_every`` each input's producer's (input name -> ticks, default 1).
        The node's parameters, as in a graph file: ``params={...}`` (any name, ``rate`` or ``seed`` too) and/or
        keywords (any name but the settings above).
        """
        from .node_processor import Processor, given_params

        return Processor(cls, given_params(cls, params, keyword_params), rate=rate, seed=seed, name=name,
                         base_dir=base_dir, nonfinite=nonfinite, every=every, input_every=input_every)


