"""The Python side of ``Graph.step()``: a step function generated for one graph's inputs and outputs.

Part of the compiled ``Graph`` (flowtex/graph/compiled.py, the compile layer), kept apart so that file stays
under ~400 lines; ``graph`` below is that ``Graph``, typed ``Any`` because importing it here would be a circle.

Straight-line code (no loops or comprehensions over port names) keeps the Python side of a tick to a few hundred
nanoseconds; the compiled ``step`` entry point it calls compiles on first use (:func:`flowtex.graph.fused.lazy_entry`).
Wrong inputs get one-line errors naming the input.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

import numpy as np

from ..errors import FlowtexError
from ..limits import excerpt
from .arena import FAULT
from .fused import lazy_entry


def make_py_step(graph: Any) -> Callable[[Mapping[str, Any] | None], dict[str, Any]]:
    """``graph.step``'s function, generated for ``graph``'s scalar and vector inputs and outputs (module docstring)."""
    lines = ["def py_step(values=None):", "    if values is None:", "        values = EMPTY", "    hits = 0"]
    for k, name in enumerate(graph._step_in):
        lines.append(f"    x{k} = values.get({name!r}, MISSING)")
        lines.append(f"    if x{k} is MISSING:")
        lines.append(f"        x{k} = f[{graph._in_scalar_off[name]}]")
        lines.append("    else:")
        lines.append("        hits += 1")
    vector_in = [n for n in graph.resolved.input_specs if n not in graph._scalar_in]
    for name in vector_in:
        lines.append(f"    if {name!r} in values:")
        lines.append("        try:")
        lines.append(f"            v = np.ravel(values[{name!r}])")
        lines.append("        except (ValueError, TypeError):")
        lines.append(f"            bad_vector({name!r}, values[{name!r}])")
        lines.append(f"        if v.size != {graph.resolved.input_specs[name].width} or v.dtype.kind not in 'biuf':")
        lines.append(f"            bad_vector({name!r}, values[{name!r}])  # a number would fill every component, complex lose a part")
        lines.append(f"        IN_VIEWS[{name!r}][:] = v")
        lines.append("        hits += 1")
    lines.append("    if hits != len(values):")
    lines.append("        unknown_input(values)")
    args = "".join(f", x{k}" for k in range(len(graph._step_in)))
    lines.append("    try:")
    lines.append(f"        r = STEP(f, i{args})")
    lines.append("    except TypeError:")
    lines.append("        bad_scalar(values)")
    lines.append("    except Exception as exc:")
    lines.append("        kernel_raised(exc)")
    if graph.tier == "dispatch":
        lines.append(f"    if i[{FAULT}] != 0:")
        lines.append("        check_fault()")
    items = [f"{name!r}: r[{k}]" for k, name in enumerate(graph._step_out)]
    items += [f"{name!r}: OUT_VIEWS[{name!r}].reshape({graph.resolved.output_specs[name].shape!r}).copy()"
              for name in graph._vector_out]
    lines.append("    return {" + ", ".join(items) + "}")
    namespace: dict[str, Any] = {"EMPTY": {}, "MISSING": object(), "f": graph.f, "i": graph.i, "np": np,
                                 "bad_scalar": partial(_bad_scalar, graph), "bad_vector": partial(_bad_vector, graph),
                                 "IN_VIEWS": graph._in_views, "OUT_VIEWS": graph._out_views, "KNOWN": frozenset(graph._in_views),
                                 "unknown_input": partial(_unknown_input, graph), "kernel_raised": graph._kernel_raised,
                                 "check_fault": graph._check_fault}
    namespace["STEP"] = lazy_entry(lambda: graph._code.get("step"), lambda fn: namespace.__setitem__("STEP", fn))
    exec("\n".join(lines), namespace)  # generated from port names validated as identifiers
    return namespace["py_step"]


def _bad_scalar(graph: Any, values: Mapping[str, Any]) -> None:
    for name in graph._step_in:
        if name in values:
            try:
                float(values[name])
            except (TypeError, ValueError):
                raise FlowtexError(f"input {name!r} is a scalar; step() got {excerpt(values[name])}; pass one number, "
                                   f"e.g. {{{name!r}: 1.0}}") from None
    raise FlowtexError("step(): scalar inputs must be numbers")


def _bad_vector(graph: Any, name: str, value: Any) -> None:
    shape = graph.resolved.input_specs[name].shape
    try:
        arr = np.asarray(value)
        got = f"shape {arr.shape}" + ("" if arr.dtype.kind in "biuf" else f" of {arr.dtype} values, not real numbers")
    except (ValueError, TypeError):
        got = excerpt(value)
    raise FlowtexError(f"input {name!r} has shape {shape} ({graph.resolved.input_specs[name].width} numbers); "
                       f"step() got {got}")


def _unknown_input(graph: Any, values: Mapping[str, Any]) -> None:
    for name in values:
        if name not in graph._in_views:
            raise FlowtexError(f"graph {graph.name!r} has no input {name!r}; inputs: {', '.join(graph._in_views) or 'none'}")
