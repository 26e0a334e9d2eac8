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

Steps 3 and 4 each run in one child process for all the node types of TARGET.
Parameters of kind float, int or floats without a min or max are listed as notes.
Each problem is one line ``FILE:LINE: node 'TYPE': ...``.
"""

from __future__ import annotations

import inspect
import json
import os
import queue
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from .config import BACKGROUND_ENV
from .errors import FlowtexError
from .node_api import Node, suggest
from .nodecheck import attr_line, check_kernel_compiles, check_node_class, node_where, type_name_location

PROBE_TIMEOUT_S = 600.0
"""Longest a child process may take over one node type (it compiles the kernel once, then runs a few thousand ticks)."""


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
        found: dict[str, type[Node]] = {}
        for obj in vars(module).values():
            if inspect.isclass(obj) and issubclass(obj, Node) and obj.type_name and obj.__module__ == module.__name__:
                first = found.setdefault(obj.type_name, obj)
                if first is not obj:  # a graph loading this file would refuse it at the second class
                    raise FlowtexError(f"{type_name_location(obj) or target}: node type {obj.type_name!r} is already defined by "
                                       f"class {first.__name__} of this file; give each class its own type_name")
        if not found:
            raise FlowtexError(f"{target}: defines no node type (a Node subclass with a type_name)")
        return found
    registry = load_registry()
    cls = registry.get(target)
    if cls is None:
        raise FlowtexError(f"{target}: neither a plugin .py file nor a known node type{suggest(target, registry.names())}")
    return {target: cls}


def _taken_by(cls: type[Node]) -> str | None:
    """Where flowtex's own node types and the installed ones already define ``cls``'s type name (None: free)."""
    from .registry import load_registry

    try:
        registry = load_registry()
        other = registry.get(cls.type_name)
    except FlowtexError:  # another installed plugin is broken: not this one's problem
        return None
    if other is None or other is cls or (inspect.getsourcefile(other) == inspect.getsourcefile(cls)
                                         and other.__qualname__ == cls.__qualname__):
        return None
    return registry.origins.get(cls.type_name, other.__module__)


def _processor_settings(cls: type[Node]) -> list[str]:
    """Parameters named like a keyword of :meth:`Node.processor` (rate, seed, ...): only ``params={...}`` sets them."""
    own = [n for n, p in inspect.signature(Node.processor).parameters.items() if p.kind is p.POSITIONAL_OR_KEYWORD]
    return [name for name in cls.params if name in own]


def _processor_call_keywords(cls: type[Node]) -> list[str]:
    """Inputs named like a keyword of a processor's call (``ticks``): a processor cannot be given them."""
    from .node_processor import Processor

    own = [n for n, p in inspect.signature(Processor.__call__).parameters.items() if p.kind is p.KEYWORD_ONLY]
    return [name for name in cls.inputs if name in own]


def _unbounded(cls: type[Node]) -> list[tuple[str, str]]:
    """(parameter, "min", "max" or "min or max") of every numeric parameter missing a bound."""
    found = []
    for name, p in cls.params.items():
        missing = [b for b in ("min", "max") if getattr(p, b) is None]
        if p.kind in ("float", "int", "floats") and missing:
            found.append((name, " or ".join(missing)))
    return found


def _children(target: str, classes: list[type[Node]], mode: str, env: dict[str, str]) -> dict[str, tuple[list[dict], str | None]]:
    """Run ``python -m flowtex.kernelprobe MODE TARGET TYPE...`` for ``classes``; per type name its JSON items, and None
    or why its check failed.

    One process checks every type (a process costs about a second of imports and numba start-up before it checks
    anything). A type that crashes the process or runs longer than :data:`PROBE_TIMEOUT_S` is reported as such, and the
    types after it are checked in a new process.
    """
    root = str(Path(__file__).resolve().parents[1])  # the folder holding this flowtex package
    env = {**os.environ, **env, "PYTHONPATH": os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])]),
           BACKGROUND_ENV: "0"}
    results: dict[str, tuple[list[dict], str | None]] = {}
    pending = [cls.type_name for cls in classes]
    while pending:
        items, done, current, failed = _child(mode, target, pending, env)
        for name in pending:
            if name in done:
                results[name] = (items.get(name, []), None)
        if failed is None:
            break
        stopped = current or next(name for name in pending if name not in done)  # died before its first line
        results[stopped] = (items.get(stopped, []), failed)
        pending = pending[pending.index(stopped) + 1:]
    return results


def _child(mode: str, target: str, names: list[str], env: dict[str, str]) -> tuple[dict[str, list[dict]], set[str], str | None, str | None]:
    """One kernelprobe process over ``names``: (items per type, types done, the type it was checking when it stopped,
    None or why it stopped early)."""
    items: dict[str, list[dict]] = {}
    done: set[str] = set()
    current = None
    lines: queue.Queue[str | None] = queue.Queue()
    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen([sys.executable, "-m", "flowtex.kernelprobe", mode, str(target), *names], env=env,
                                stdout=subprocess.PIPE, stderr=err, text=True, stdin=subprocess.DEVNULL)
        reader = threading.Thread(target=lambda: [*map(lines.put, proc.stdout), lines.put(None)], daemon=True)
        reader.start()
        deadline = time.monotonic() + PROBE_TIMEOUT_S  # per type: from the start, then from each type's start line
        failed = None
        while (line := _next_line(lines, deadline)) is not None:
            if line == "":  # no line before the deadline
                proc.kill()
                failed = f"the {mode} check did not finish in {PROBE_TIMEOUT_S:g} s (does the kernel loop forever?)"
                break
            if not line.startswith("{"):
                continue
            item = json.loads(line)
            if "start" in item:
                current, deadline = item["start"], time.monotonic() + PROBE_TIMEOUT_S
            elif "done" in item:
                done.add(item["done"])
                current = None
            else:
                items.setdefault(item.pop("type"), []).append(item)
        proc.wait()
        reader.join()
        proc.stdout.close()
        if failed is None and proc.returncode != 0:
            how = f"signal {signal.Signals(-proc.returncode).name}" if proc.returncode < 0 else f"exit code {proc.returncode}"
            err.seek(0)
            last = (err.read().strip().splitlines() or [""])[-1]
            failed = f"running the kernel crashed the checking process ({how}{': ' + last if last else ''})"
    if failed is None and len(done) < len(names):
        failed = "the checking process ended before checking it"
    return items, done, current, failed


def _next_line(lines: queue.Queue[str | None], deadline: float) -> str | None:
    """The next line (None at the end of the output), or "" when none came before ``deadline``."""
    try:
        return lines.get(timeout=max(0.0, deadline - time.monotonic()))
    except queue.Empty:
        return ""


def allocations(target: str, classes: list[type[Node]]) -> dict[str, tuple[list[str], str | None]]:
    """Per type name: allocator calls in the kernel's compiled code, found in a child process compiling into an empty
    numba cache, and None or why the check failed.

    numba cannot show the LLVM IR of code it loaded from its disk cache (and a plugin kernel is usually cached), so the
    child compiles the kernel and every function it calls afresh.
    """
    with tempfile.TemporaryDirectory(prefix="flowtex-alloc-") as tmp:
        found = _children(target, classes, "allocations", {"NUMBA_CACHE_DIR": tmp})
    return {name: (sorted({str(call) for item in items for call in item.get("allocations", [])}), failed)
            for name, (items, failed) in found.items()}


def runtime_problems(target: str, classes: list[type[Node]]) -> dict[str, list[tuple[int, str]]]:
    """Per type name: (line, message) from :mod:`flowtex.kernelprobe` run in a child process with numba's bounds
    checking on.

    The child compiles into its own numba cache folder (bounds-checked machine code must not
    replace the normal one), one per flowtex source tree as the normal cache is (:func:`flowtex.cache.source_fingerprint`:
    numba's own cache, which the child uses there, does not see an edit to a function a kernel calls in another file);
    a crash or a timeout there is reported, not suffered here.
    """
    from .cache import cache_dir, prune_other_trees, source_fingerprint

    folder = cache_dir() / "boundscheck" / source_fingerprint()
    prune_other_trees(folder)
    found = _children(target, classes, "runtime", {"NUMBA_BOUNDSCHECK": "1", "NUMBA_CACHE_DIR": str(folder)})
    out = {}
    for name, (items, failed) in found.items():
        out[name] = [(-1 if item.get("located") else int(item["line"]), str(item["message"])) for item in items]
        if failed:
            out[name].append((0, failed + "; look for reads or writes outside the ports, p, s and si"))
    return out


def check_in_process(cls: type[Node], report: Report) -> bool:
    """Steps 1 and 2 (declarations, the kernel compiles) and the notes on parameters; whether the child steps follow."""
    report.checked.append(cls.type_name)
    try:
        check_node_class(cls)
    except FlowtexError as exc:
        report.problems.append(str(exc))
        return False
    clash = _taken_by(cls)
    if clash:
        report.problems.append(f"{type_name_location(cls) or node_where(cls)}: node type {cls.type_name!r} is already defined "
                               f"by {clash}; a graph would refuse to load this plugin: rename it (e.g. 'my_{cls.type_name}')")
    for name in _processor_settings(cls):
        report.notes.append(f"{node_where(cls, line=attr_line(cls, 'params'))}: note: parameter {name!r} is named like "
                            f"Node.processor()'s own keyword {name!r}: a processor sets it only as params={{{name!r}: ...}}")
    for name in _processor_call_keywords(cls):
        report.notes.append(f"{node_where(cls, line=attr_line(cls, 'inputs'))}: note: input {name!r} is named like a "
                            f"processor call's own keyword {name!r}: Node.processor() cannot feed it; rename it to use "
                            "the node on arrays")
    for name, missing in _unbounded(cls):
        report.notes.append(f"{node_where(cls, line=attr_line(cls, 'params'))}: note: parameter {name!r} has no {missing}; "
                            "any such value reaches the kernel (declare bounds, e.g. Param('float', min=0.0, max=1.0))")
    try:
        check_kernel_compiles(cls)
    except FlowtexError as exc:
        report.problems.append(str(exc))
        return False
    return True


def check_in_children(target: str, classes: list[type[Node]]) -> dict[str, Report]:
    """Steps 3 and 4 for ``classes`` (each passed :func:`check_in_process`): per type name, its problems and notes."""
    calls = allocations(target, classes)
    runtime = runtime_problems(target, classes)
    reports = {}
    for cls in classes:
        report = reports[cls.type_name] = Report()
        kernel = cls.get_kernel()
        func = getattr(kernel, "py_func", kernel)
        found, failed = calls[cls.type_name]
        if failed:
            report.problems.append(f"{node_where(cls, func)}: {failed}")
        if found:
            report.problems.append(f"{node_where(cls, func)}: kernel {func.__name__} allocates memory on every call (numba "
                                   f"generated {', '.join(found)}): np.empty/zeros, array expressions such as x[t, :] * 2 "
                                   "and copied slices allocate; size work arrays in build() and keep them in s")
        for line, message in runtime[cls.type_name]:  # line -1: the message names its file and line itself
            where = node_where(cls, func, line or None)
            (report.notes if message.startswith("note: ") else report.problems).append(
                message if line == -1 else f"{where}: {message}")
    return reports


def check_target(target: str) -> Report:
    """Check every node type ``target`` defines (see the module docstring): steps 1 and 2 here, type by type, then
    step 3 for every type that passed them in one child process, and step 4 in another."""
    classes = list(node_types(target).values())
    parts = {cls.type_name: Report() for cls in classes}
    passed = [cls for cls in classes if check_in_process(cls, parts[cls.type_name])]
    for name, found in check_in_children(target, passed).items():
        parts[name].problems += found.problems
        parts[name].notes += found.notes
    report = Report()
    for part in parts.values():  # in the order the types are defined, each type's problems in the order of the steps
        report.problems += part.problems
        report.notes += part.notes
        report.checked += part.checked
    return report
