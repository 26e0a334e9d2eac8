"""``flowtex plugin check TARGET``: every common mistake of a node type, found before it reaches a device.

TARGET is a plugin ``.py`` file (every node type it defines is checked) or the
name of a node type flowtex can load (entry points, ``$FLOWTEX_PLUGINS``). Per
node type, in order (a failed step stops that type's later steps):

1. declarations and kernel signature (:func:`flowtex.nodecheck.check_node_class`);
2. the kernel compiles for the argument types the graph passes
   (:func:`flowtex.nodecheck.check_kernel_compiles`; ports are 2-D whatever their shape);
3. no allocation in the compiled kernel: numba's generated LLVM IR is searched
   for calls into its runtime's allocator (:data:`flowtex.kernelprobe.ALLOCATORS`), in a child
   process compiling into an empty numba cache (numba shows no IR for cached code);
4. runtime checks in a child process compiled with bounds checking
   (:mod:`flowtex.kernelprobe`): out-of-bounds reads and writes, state kept
   between calls, every output element written, finite outputs.

Parameters of kind float, int or floats without a min or max are listed as notes.
Each problem is one line ``FILE:LINE: node 'TYPE': ...``.
"""

from __future__ import annotations

import inspect
import json
import os
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from .config import BACKGROUND_ENV
from .errors import FlowtexError
from .node_api import Node, suggest
from .nodecheck import attr_line, check_kernel_compiles, check_node_class, node_where

PROBE_TIMEOUT_S = 600.0
"""Longest the bounds-checked child process may take (it compiles the kernel once, then runs a few thousand ticks)."""


@dataclass
class Report:
    """What ``plugin check`` found: problems (exit 1) and notes."""

    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    checked: list[str] = field(default_factory=list)
    """Node types checked."""


def node_types(target: str) -> dict[str, type[Node]]:
    """The node types ``target`` (a plugin file, or a node type name) defines."""
    from .registry import load_plugin_file, load_registry

    path = Path(target)
    if path.suffix == ".py" or path.is_file():
        if not path.is_file():
            raise FlowtexError(f"{target}: no such plugin file")
        module = load_plugin_file(path)
        found = {obj.type_name: obj for obj in vars(module).values()
                 if inspect.isclass(obj) and issubclass(obj, Node) and obj.type_name and obj.__module__ == module.__name__}
        if not found:
            raise FlowtexError(f"{target}: defines no node type (a Node subclass with a type_name)")
        return found
    registry = load_registry()
    cls = registry.get(target)
    if cls is None:
        raise FlowtexError(f"{target}: neither a plugin .py file nor a known node type{suggest(target, registry.names())}")
    return {target: cls}


def _unbounded(cls: type[Node]) -> list[tuple[str, str]]:
    """(parameter, "min", "max" or "min or max") of every numeric parameter missing a bound."""
    found = []
    for name, p in cls.params.items():
        missing = [b for b in ("min", "max") if getattr(p, b) is None]
        if p.kind in ("float", "int", "floats") and missing:
            found.append((name, " or ".join(missing)))
    return found


def _child(target: str, cls: type[Node], mode: str, env: dict[str, str]) -> tuple[list[dict], str | None]:
    """Run ``python -m flowtex.kernelprobe MODE TARGET TYPE``; its JSON lines, or None and why it failed."""
    root = str(Path(__file__).resolve().parents[1])  # the folder holding this flowtex package
    env = {**os.environ, **env, "PYTHONPATH": os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])]),
           BACKGROUND_ENV: "0"}
    try:
        done = subprocess.run([sys.executable, "-m", "flowtex.kernelprobe", mode, str(target), cls.type_name], env=env,
                              capture_output=True, text=True, timeout=PROBE_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return [], f"the {mode} check did not finish in {PROBE_TIMEOUT_S:g} s (does the kernel loop forever?)"
    if done.returncode != 0:
        how = f"signal {signal.Signals(-done.returncode).name}" if done.returncode < 0 else f"exit code {done.returncode}"
        last = (done.stderr.strip().splitlines() or [""])[-1]
        return [], f"running the kernel crashed the checking process ({how}{': ' + last if last else ''})"
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")], None


def allocations(target: str, cls: type[Node]) -> tuple[list[str], str | None]:
    """Allocator calls in the kernel's compiled code, found in a child process compiling into an empty numba cache.

    numba cannot show the LLVM IR of code it loaded from its disk cache (and a plugin kernel is usually cached), so the
    child compiles the kernel and every function it calls afresh.
    """
    with tempfile.TemporaryDirectory(prefix="flowtex-alloc-") as tmp:
        items, failed = _child(target, cls, "allocations", {"NUMBA_CACHE_DIR": tmp})
    return sorted({str(name) for item in items for name in item.get("allocations", [])}), failed


def runtime_problems(target: str, cls: type[Node]) -> list[tuple[int, str]]:
    """(line, message) from :mod:`flowtex.kernelprobe` run in a child process with numba's bounds checking on.

    The child compiles into its own numba cache folder (bounds-checked machine code must not
    replace the normal one); a crash or a timeout there is reported, not suffered here.
    """
    from .cache import cache_dir

    items, failed = _child(target, cls, "runtime", {"NUMBA_BOUNDSCHECK": "1", "NUMBA_CACHE_DIR": str(cache_dir() / "boundscheck")})
    if failed:
        return [(0, failed + "; look for reads or writes outside the ports, p, s and si")]
    return [(int(item["line"]), str(item["message"])) for item in items]


def check_type(target: str, cls: type[Node], report: Report) -> None:
    """Append every problem and note of one node type to ``report``."""
    report.checked.append(cls.type_name)
    try:
        check_node_class(cls)
    except FlowtexError as exc:
        report.problems.append(str(exc))
        return
    for name, missing in _unbounded(cls):
        report.notes.append(f"{node_where(cls, line=attr_line(cls, 'params'))}: note: parameter {name!r} has no {missing}; "
                            "any such value reaches the kernel (declare bounds, e.g. Param('float', min=0.0, max=1.0))")
    try:
        check_kernel_compiles(cls)
    except FlowtexError as exc:
        report.problems.append(str(exc))
        return
    kernel = cls.get_kernel()
    func = getattr(kernel, "py_func", kernel)
    calls, failed = allocations(target, cls)
    if failed:
        report.problems.append(f"{node_where(cls, func)}: {failed}")
    if calls:
        report.problems.append(f"{node_where(cls, func)}: kernel {func.__name__} allocates memory on every call (numba "
                               f"generated {', '.join(calls)}): np.empty/zeros, array expressions such as x[t, :] * 2 and "
                               "copied slices allocate; size work arrays in build() and keep them in s")
    for line, message in runtime_problems(target, cls):
        where = node_where(cls, func, line or None)
        (report.notes if message.startswith("note: ") else report.problems).append(f"{where}: {message}")


def check_target(target: str) -> Report:
    """Check every node type ``target`` defines (see the module docstring)."""
    report = Report()
    for cls in node_types(target).values():
        check_type(target, cls, report)
    return report
