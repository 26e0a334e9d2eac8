"""Check a node type's kernel against the node contract, and blame the node's own file.

A plugin kernel that lacks ``si``, is not compiled with numba, or does not
type-check for its ports would otherwise fail deep inside the generated graph
code, as what looks like flowtex's own bug. These checks run when a node type
is registered (:func:`check_node_class`: kernel present, numba-compiled,
arguments ``(p, s, si, inputs..., outputs...)``) and when a graph using it is
built (:func:`check_kernel_compiles`: the kernel compiled alone for the
argument types the graph passes), and report ``file:line: node 'name': ...``
with the fix.

Node types are taken as classes (``type``), not imported from :mod:`flowtex.node_api`: ``Node.processor`` checks a
plugin's kernel with this module, and the node API imports its processor.
"""

from __future__ import annotations

import inspect
import os
import re
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from .errors import FlowtexError, ParamError
from .limits import MAX_EVERY, MAX_NODE_PORTS, MAX_PORT_VALUES, excerpt
from .node_decl import NodeState, Param, Port, PortSpec, outputs_problem

CONTRACT = "kernel(p, s, si, inputs..., outputs...)"
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_NUMBA_FILE_LINE = re.compile(r'File "([^"]+)", line (\d+)')


def _kernel_attr(cls: type, attr: str) -> Callable | None:
    try:
        return cls.get_kernel(attr)
    except AttributeError:
        return None


def _python_function(kernel: Callable) -> Callable:
    return getattr(kernel, "py_func", kernel)


def shown_path(path: str | Path) -> str:
    """A path as the user would type it: relative to the working directory when inside it."""
    try:
        rel = os.path.relpath(path)
    except ValueError:
        return str(path)
    return rel if not rel.startswith("..") else str(path)


def _def_line(func: Callable) -> int:
    """Line of the ``def`` statement (not of its decorators)."""
    try:
        lines, start = inspect.getsourcelines(func)
    except (OSError, TypeError):
        return getattr(getattr(func, "__code__", None), "co_firstlineno", 0)
    for k, text in enumerate(lines):
        if text.lstrip().startswith("def "):
            return start + k
    return start


def is_plugin(cls: type) -> bool:
    """True for node types defined outside flowtex (plugin files and installed packages): their mistakes are theirs."""
    return not cls.__module__.startswith("flowtex.")


def error_line(exc: BaseException, path: str | Path) -> int:
    """Line of the last traceback frame of ``exc`` inside the file ``path`` (0 if none; a SyntaxError's own line)."""
    if isinstance(exc, SyntaxError) and exc.lineno:
        return exc.lineno
    target = Path(path).resolve()
    tb = exc.__traceback__
    line = 0
    while tb is not None:
        if Path(tb.tb_frame.f_code.co_filename).resolve() == target:
            line = tb.tb_lineno
        tb = tb.tb_next
    return line


def attr_line(cls: type, attr: str) -> int | None:
    """Line of ``attr = ...`` in the class body (where a declaration mistake is), or None."""
    try:
        lines, start = inspect.getsourcelines(cls)
    except (OSError, TypeError):
        return None
    pattern = re.compile(rf"^\s*{re.escape(attr)}\s*(:[^=]*)?=")
    return next((start + k for k, text in enumerate(lines) if pattern.match(text)), None)


def type_name_location(cls: type) -> str | None:
    """``FILE:LINE`` of the class's ``type_name = ...`` (where a name clash is fixed), or None without its source."""
    try:
        path = inspect.getsourcefile(cls)
    except TypeError:
        path = None
    line = attr_line(cls, "type_name") if path else None
    return f"{shown_path(path)}:{line}" if path and line else None


def node_where(cls: type, func: Callable | None = None, line: int | None = None) -> str:
    target: object = func if func is not None else cls
    try:
        path = inspect.getsourcefile(target)  # type: ignore[arg-type]
    except TypeError:
        path = None
    if path is None:
        return f"{cls.__module__}: node {cls.type_name!r}"
    if line is not None:
        pass
    elif func is not None:
        line = _def_line(func)
    else:
        try:
            line = inspect.getsourcelines(cls)[1]
        except (OSError, TypeError):
            line = 0
    return f"{shown_path(path)}:{line}: node {cls.type_name!r}"


def kernel_location(cls: type, line: int | None = None, attr: str = "kernel") -> str:
    """``FILE:LINE`` of a node type's kernel (its ``def`` line unless ``line`` is given), or its module's name."""
    func = _python_function(_kernel_attr(cls, attr) or cls)
    try:
        path = inspect.getsourcefile(func)
    except TypeError:
        path = None
    if path is None:
        return cls.__module__
    return f"{shown_path(path)}:{line if line is not None else _def_line(func)}"


def _is_numba_dispatcher(kernel: Callable) -> bool:
    from numba.core.dispatcher import Dispatcher

    return isinstance(kernel, Dispatcher)


def expected_arguments(cls: type) -> list[str]:
    """Argument names the contract expects: ``p, s, si``, then input then output port names."""
    return ["p", "s", "si", *cls.inputs, *cls.outputs]


def _shape_problem(port: Port, inputs: dict, output: bool) -> str | None:
    """What is wrong with a declared shape, or None."""
    shape = port.shape
    if shape is None:
        return "shape None (any shape) is for inputs only; declare the output's shape, e.g. () or '=x'" if output else None
    if isinstance(shape, str):
        if not shape.startswith("=") or not shape[1:]:
            return f"shape {shape!r} is not a shape; use a tuple such as () or (3,), None (any; inputs only) or '=x' (as input x)"
        if shape[1:] not in inputs:
            return f"shape {shape!r} names no input; inputs are: {', '.join(inputs) or 'none'}"
        return None
    if not isinstance(shape, tuple) or not all(isinstance(n, int) and not isinstance(n, bool) for n in shape):
        return f"shape {excerpt(shape)} is not a shape; use a tuple of positive integers such as () or (3,)"
    if any(n < 1 for n in shape):
        return f"shape {shape!r} has a size below 1; every size is a positive integer"
    values = 1
    for n in shape:
        values *= n
    if values > MAX_PORT_VALUES:
        return f"shape {shape!r} holds {values:,} values per tick, more than the limit of {MAX_PORT_VALUES:,}"
    return None


def _unit_problem(port: Port, inputs: dict, output: bool) -> str | None:
    unit = port.unit
    if not isinstance(unit, str):
        return f"unit {excerpt(unit)} is not a string; use e.g. 'N', '' (dimensionless), '*' (any; inputs only) or '=x'"
    if unit == "*" and output:
        return "unit '*' (any unit) is for inputs only; declare the output's unit, e.g. '' or '=x'"
    if unit.startswith("=") and unit[1:] not in inputs:
        return f"unit {unit!r} names no input; inputs are: {', '.join(inputs) or 'none'}"
    return None


def check_declarations(cls: type) -> None:
    """Raise :class:`FlowtexError` at the declaring line for a port or parameter declaration flowtex cannot use."""
    for attr, kind in (("params", Param), ("inputs", Port), ("outputs", Port)):
        table = getattr(cls, attr)
        def where(attr: str = attr) -> str:  # found only for a message: reading the source costs ms per node
            return node_where(cls, line=attr_line(cls, attr))

        if not isinstance(table, dict):
            raise FlowtexError(f"{where()}: {attr} is {excerpt(table)}, not a dict of name: {kind.__name__}(...)")
        for name, decl in table.items():
            if not isinstance(name, str) or not name.isidentifier():
                raise FlowtexError(f"{where()}: {attr[:-1]} name {excerpt(name)} is not a Python identifier")
            if not isinstance(decl, kind):
                raise FlowtexError(f"{where()}: {attr[:-1]} {name!r} is {excerpt(decl)}, not a {kind.__name__}(...)")
            if kind is Port:
                output = attr == "outputs"
                problem = _shape_problem(decl, cls.inputs, output) or _unit_problem(decl, cls.inputs, output)
                if problem:
                    raise FlowtexError(f"{where()}: {attr[:-1]} {name!r}: {problem}")
                if output and decl.optional:
                    raise FlowtexError(f"{where()}: output {name!r}: optional is for inputs only")
    ports = len(cls.inputs) + len(cls.outputs)
    if ports > MAX_NODE_PORTS:
        raise FlowtexError(f"{node_where(cls, line=attr_line(cls, 'inputs'))}: {len(cls.inputs)} inputs and {len(cls.outputs)} "
                           f"outputs are {ports} ports, more than the limit of {MAX_NODE_PORTS}; take a vector input "
                           "(Port((n,))) instead of many scalar ones")


def check_node_class(cls: type) -> None:
    """Raise :class:`FlowtexError` (``file:line: node 'name': ...`` and the fix) if the declarations or kernel break the contract."""
    check_declarations(cls)
    owner = next((k for k in cls.__mro__ if "seed_state" in k.__dict__), None)
    if cls.uses_seed and (owner is None or (owner.__module__, owner.__qualname__) == ("flowtex.node_api", "Node")):
        raise FlowtexError(f"{node_where(cls, line=attr_line(cls, 'uses_seed'))}: uses_seed = True but the node defines no "
                           "seed_state(self, state, istate, seed); write one that fills its random state in place from the "
                           "np.random.SeedSequence seed (the graph's seed and the node's name), or drop uses_seed")
    attrs = ["kernel"] + (["emit_kernel", "absorb_kernel"] if cls.breaks_cycles else [])
    for attr in attrs:
        kernel = _kernel_attr(cls, attr)
        if kernel is None:
            raise FlowtexError(f"{node_where(cls)}: defines no {attr}; set {attr} = a numba @njit function "
                               f"with arguments {CONTRACT}")
        func = _python_function(kernel)
        if not callable(func) or not hasattr(func, "__code__"):
            raise FlowtexError(f"{node_where(cls)}: {attr} is {kernel!r}, not a function; set {attr} = a numba @njit function")
        if not _is_numba_dispatcher(kernel):
            raise FlowtexError(f"{node_where(cls, func)}: {attr} {func.__name__} is a plain Python function; decorate it "
                               "with @njit(cache=True) (from numba import njit): kernels run inside the compiled graph")
        if attr != "kernel":
            continue
        params = list(inspect.signature(func).parameters.values())
        if any(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params):
            continue
        want = expected_arguments(cls)
        if len(params) != len(want):
            have = ", ".join(p.name for p in params)
            ins = ", ".join(cls.inputs) or "none"
            outs = ", ".join(cls.outputs) or "none"
            raise FlowtexError(
                f"{node_where(cls, func)}: kernel {func.__name__}({have}) takes {len(params)} arguments but the node's ports need "
                f"{len(want)}: {func.__name__}({', '.join(want)}) -- p (params), s (float state), si (int state), "
                f"then the inputs ({ins}) and the outputs ({outs}) in declaration order")


def check_kernel_compiles(cls: type) -> None:
    """Compile the node's kernel alone for the argument types graph code passes; blame the node's file on failure.

    ``p`` and ``s`` are ``float64[::1]``, ``si`` is ``int64[::1]``, every port a
    C-contiguous ``float64[:, ::1]``. Costs nothing extra: the graph reuses this compilation.
    """
    from numba import float64, int64
    from numba.core.errors import NumbaError

    kernel = cls.get_kernel()
    sig = (float64[::1], float64[::1], int64[::1]) + (float64[:, ::1],) * (len(cls.inputs) + len(cls.outputs))
    try:
        kernel.compile(sig)
    except NumbaError as exc:
        raise FlowtexError(_compile_message(cls, kernel, str(exc))) from None


def check_plugin_kernels(classes: Iterable[type]) -> None:
    """:func:`check_kernel_compiles` for each plugin node type among ``classes`` (flowtex's own are compiled by its tests)."""
    for cls in {cls for cls in classes if is_plugin(cls)}:
        check_kernel_compiles(cls)


def checked_state(cls: type, node_name: str, state: object, build: Callable) -> NodeState:
    """``state`` if :meth:`Node.build` returned a usable :class:`NodeState`, else the plugin's error at its ``build`` line."""
    if isinstance(state, NodeState):
        for field in ("params", "state", "istate"):
            try:
                arr = np.asarray(getattr(state, field), dtype=np.int64 if field == "istate" else np.float64)
            except (TypeError, ValueError, OverflowError):
                arr = None
            if arr is None:  # any shape is packed flat (row-major) into the arena
                raise FlowtexError(f"{node_where(cls, build)}: build() of graph node {node_name!r} returned NodeState({field}="
                                   f"{excerpt(getattr(state, field))}); {field} must be an array of numbers")
        return state
    raise FlowtexError(f"{node_where(cls, build)}: build() of graph node {node_name!r} returned {excerpt(state)}, not a "
                       "NodeState; end build() with return NodeState(params=..., state=..., istate=...)")


def checked_outputs(cls: type, node_name: str, specs: object) -> dict[str, PortSpec]:
    """``specs`` if :meth:`Node.resolve` returned a usable spec for each declared output
    (:func:`flowtex.node_decl.outputs_problem`), else the plugin's error at its ``resolve`` line."""
    problem = outputs_problem(list(cls.outputs), specs)
    if problem:
        raise FlowtexError(f"{node_where(cls, cls.resolve)}: resolve() of graph node {node_name!r} {problem}; return "
                           f"{{name: PortSpec(shape, unit)}} for each declared output: {', '.join(cls.outputs) or 'none'}")
    return specs  # type: ignore[return-value]


def checked_every(cls: type, node_name: str, every: object) -> int | None:
    """``every`` if :meth:`Node.own_every` returned None or a whole number of ticks in 1..MAX_EVERY, else the plugin's
    error at its ``own_every`` line (0 would divide by zero in the generated schedule)."""
    if every is None or (isinstance(every, (int, np.integer)) and not isinstance(every, bool) and 1 <= every <= MAX_EVERY):
        return None if every is None else int(every)
    raise FlowtexError(f"{node_where(cls, cls.own_every)}: own_every() for graph node {node_name!r} returned "
                       f"{excerpt(every)}; return None (the graph's every: decides) or a whole number of ticks from 1 to "
                       f"{MAX_EVERY:,}")


def scheduled_every(cls: type, node_name: str, params: dict, rate: float, input_every: dict[str, int]) -> int | None:
    """The node's own schedule (:meth:`Node.own_every` for ``params`` at base ``rate`` Hz), checked by
    :func:`checked_every`: None when the graph's ``every:`` decides. A :class:`ParamError` is the caller's to place (it
    names a parameter); anything else a plugin's ``own_every`` raises becomes its error at its line."""
    try:
        own = cls.own_every(params, rate, input_every)
    except ParamError:
        raise
    except Exception as exc:
        if not is_plugin(cls):
            raise  # flowtex's own bug: an internal error
        raise plugin_raised(cls, node_name, "own_every", exc) from None
    return checked_every(cls, node_name, own)


def checked_latency(cls: type, node_name: str, latency: object) -> int:
    """``latency`` if :meth:`Node.latency_samples` returned a whole number of ticks >= 0, else the plugin's error at
    its ``latency_samples`` line."""
    if isinstance(latency, (int, np.integer)) and not isinstance(latency, bool) and latency >= 0:
        return int(latency)
    raise FlowtexError(f"{node_where(cls, cls.latency_samples)}: latency_samples() of graph node {node_name!r} returned "
                       f"{excerpt(latency)}; return the delay from input to output as a whole number of ticks >= 0")


def plugin_raised(cls: type, node_name: str, method: str, exc: Exception) -> FlowtexError:
    """The plugin's error for an exception its ``method`` (``__init__``, ``resolve``, ``build``) raised, at the raising line."""
    func = getattr(cls, method)
    try:
        path = inspect.getsourcefile(func) or ""
    except TypeError:
        path = ""
    line = error_line(exc, path) if path else 0
    where = node_where(cls, func, line or None)
    return FlowtexError(f"{where}: {method}() of graph node {node_name!r} raised {type(exc).__name__}: {exc}")


def _compile_message(cls: type, kernel: Callable, text: str) -> str:
    func = _python_function(kernel)
    text = _ANSI.sub("", text)
    where = node_where(cls, func)
    source = inspect.getsourcefile(func)
    for path, line in _NUMBA_FILE_LINE.findall(text):
        if source and Path(path).name == Path(source).name:
            where = f"{shown_path(source)}:{line}: node {cls.type_name!r}"
            break
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    useful = [ln for ln in lines if not ln.startswith(("Failed in", "During:", "File ", "<source"))] or lines or [""]
    detail = useful[0] + (" " + useful[1] if useful[0].endswith(":") and len(useful) > 1 else "")
    return (f"{where}: kernel {func.__name__} does not compile for its ports ({detail}); arguments are p, s: float64[::1], "
            "si: int64[::1], each port float64[:, ::1] of shape (ticks, width)")
