"""Check a node type's kernel against the node contract, and blame the node's own file.

A plugin kernel that lacks ``si``, is not compiled with numba, or does not
type-check for its ports would otherwise fail deep inside the generated graph
code, as what looks like flowtex's own bug. These checks run when a node type
is registered (:func:`check_node_class`: kernel present, numba-compiled,
arguments ``(p, s, si, inputs..., outputs...)``) and when a graph using it is
built (:func:`check_kernel_compiles`: the kernel compiled alone for the
argument types the graph passes), and report ``file:line: node 'name': ...``
with the fix.
"""

from __future__ import annotations

import inspect
import os
import re
from collections.abc import Callable
from pathlib import Path

from .errors import FlowtexError
from .node_api import Node

CONTRACT = "kernel(p, s, si, inputs..., outputs...)"
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_NUMBA_FILE_LINE = re.compile(r'File "([^"]+)", line (\d+)')


def _kernel_attr(cls: type[Node], attr: str) -> Callable | None:
    try:
        return cls.get_kernel(attr)
    except AttributeError:
        return None


def _python_function(kernel: Callable) -> Callable:
    return getattr(kernel, "py_func", kernel)


def _shown(path: str | Path) -> str:
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


def _where(cls: type[Node], func: Callable | None = None) -> str:
    target: object = func if func is not None else cls
    try:
        path = inspect.getsourcefile(target)  # type: ignore[arg-type]
    except TypeError:
        path = None
    if path is None:
        return f"{cls.__module__}: node {cls.type_name!r}"
    if func is not None:
        line = _def_line(func)
    else:
        try:
            line = inspect.getsourcelines(cls)[1]
        except (OSError, TypeError):
            line = 0
    return f"{_shown(path)}:{line}: node {cls.type_name!r}"


def _is_numba_dispatcher(kernel: Callable) -> bool:
    from numba.core.dispatcher import Dispatcher

    return isinstance(kernel, Dispatcher)


def expected_arguments(cls: type[Node]) -> list[str]:
    """Argument names the contract expects: ``p, s, si``, then input then output port names."""
    return ["p", "s", "si", *cls.inputs, *cls.outputs]


def check_node_class(cls: type[Node]) -> None:
    """Raise :class:`FlowtexError` (``file:line: node 'name': ...`` and the fix) if the kernel breaks the contract."""
    attrs = ["kernel"] + (["emit_kernel", "absorb_kernel"] if cls.breaks_cycles else [])
    for attr in attrs:
        kernel = _kernel_attr(cls, attr)
        if kernel is None:
            raise FlowtexError(f"{_where(cls)}: defines no {attr}; set {attr} = a numba @njit function "
                               f"with arguments {CONTRACT}")
        func = _python_function(kernel)
        if not callable(func) or not hasattr(func, "__code__"):
            raise FlowtexError(f"{_where(cls)}: {attr} is {kernel!r}, not a function; set {attr} = a numba @njit function")
        if not _is_numba_dispatcher(kernel):
            raise FlowtexError(f"{_where(cls, func)}: {attr} {func.__name__} is a plain Python function; decorate it "
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
                f"{_where(cls, func)}: kernel {func.__name__}({have}) takes {len(params)} arguments but the node's ports need "
                f"{len(want)}: {func.__name__}({', '.join(want)}) -- p (params), s (float state), si (int state), "
                f"then the inputs ({ins}) and the outputs ({outs}) in declaration order")


def check_kernel_compiles(cls: type[Node]) -> None:
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


def _compile_message(cls: type[Node], kernel: Callable, text: str) -> str:
    func = _python_function(kernel)
    text = _ANSI.sub("", text)
    where = _where(cls, func)
    source = inspect.getsourcefile(func)
    for path, line in _NUMBA_FILE_LINE.findall(text):
        if source and Path(path).name == Path(source).name:
            where = f"{_shown(source)}:{line}: node {cls.type_name!r}"
            break
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    useful = [ln for ln in lines if not ln.startswith(("Failed in", "During:", "File ", "<source"))] or lines or [""]
    detail = useful[0] + (" " + useful[1] if useful[0].endswith(":") and len(useful) > 1 else "")
    return (f"{where}: kernel {func.__name__} does not compile for its ports ({detail}); arguments are p, s: float64[::1], "
            "si: int64[::1], each port float64[:, ::1] of shape (ticks, width)")
