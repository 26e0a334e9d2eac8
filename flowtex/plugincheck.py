"""``flowtex plugin check TARGET``: every common mistake of a node type, found before it reaches a device.

TARGET is a plugin ``.py`` file (every node type it defines is checked) or the
name of a node type flowtex can load (entry points, ``$FLOWTEX_PLUGINS``). Per
node type, in order (a failed step stops that type's later steps):

1. declarations and kernel signature (:func:`flowtex.nodecheck.check_node_class`);
2. the kernel compiles for the argument types the graph passes
   (:func:`flowtex.nodecheck.check_kernel_compiles`; ports are 2-D whatever their shape);
3. no allocation in the compiled kernel: numba's generated LLVM IR is searched
   for calls into its runtime's allocator (:data:`ALLOCATORS`);
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
import re
import signal
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from .errors import FlowtexError
from .node_api import Node, suggest
from .nodecheck import attr_line, check_kernel_compiles, check_node_class, node_where

ALLOCATORS = re.compile(r"call [^@\n]*@(NRT_MemInfo_alloc\w*|NRT_MemInfo_new\w*|NRT_Allocate\w*|NRT_MemInfo_varsize_alloc\w*)")
"""numba runtime functions that allocate heap memory (np.empty, array expressions, slices copied, lists ...)."""
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


def allocations(cls: type[Node]) -> list[str]:
    """Allocator calls in the kernel's compiled code (its Python wrapper excluded), after :func:`check_kernel_compiles`."""
    kernel = cls.get_kernel()
    found: set[str] = set()
    for sig in kernel.signatures:
        ir = kernel.inspect_llvm(sig)
        for block in re.split(r"\n(?=define )", ir):
            head = block.split("(", 1)[0]
            if block.startswith("define") and "@cpython." not in head and "@cfunc." not in head:
                found.update(ALLOCATORS.findall(block))
    return sorted(found)


def _unbounded(cls: type[Node]) -> list[tuple[str, str]]:
    """(parameter, "min", "max" or "min or max") of every numeric parameter missing a bound."""
    found = []
    for name, p in cls.params.items():
        missing = [b for b in ("min", "max") if getattr(p, b) is None]
        if p.kind in ("float", "int", "floats") and missing:
            found.append((name, " or ".join(missing)))
    return found


def runtime_problems(target: str, cls: type[Node]) -> list[tuple[int, str]]:
    """(line, message) from :mod:`flowtex.kernelprobe` run in a child process with numba's bounds checking on.

    The child compiles into its own numba cache folder (bounds-checked machine code must not
    replace the normal one); a crash or a timeout there is reported, not suffered here.
    """
    from . import __file__ as package_init
    from .cache import cache_dir

    root = str(Path(package_init).resolve().parents[1])
    env = {**os.environ, "NUMBA_BOUNDSCHECK": "1", "NUMBA_CACHE_DIR": str(cache_dir() / "boundscheck"),
           "PYTHONPATH": os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])]), "FLOWTEX_BACKGROUND": "0"}
    try:
        done = subprocess.run([sys.executable, "-m", "flowtex.kernelprobe", str(target), cls.type_name], env=env,
                              capture_output=True, text=True, timeout=PROBE_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return [(0, f"the runtime checks did not finish in {PROBE_TIMEOUT_S:g} s (does the kernel loop forever?)")]
    if done.returncode != 0:
        how = f"signal {signal.Signals(-done.returncode).name}" if done.returncode < 0 else f"exit code {done.returncode}"
        last = (done.stderr.strip().splitlines() or [""])[-1]
        return [(0, f"running the kernel crashed the checking process ({how}{': ' + last if last else ''}); "
                    "look for reads or writes outside the ports, p, s and si")]
    found = []
    for line in done.stdout.splitlines():
        if line.startswith("{"):
            item = json.loads(line)
            found.append((int(item["line"]), str(item["message"])))
    return found


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
    calls = allocations(cls)
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
