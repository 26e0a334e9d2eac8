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


RUNTIME_ENV: dict[str, str | None] = {"NUMBA_BOUNDSCHECK": "1", "NUMBA_CACHE_DIR": None}
"""What the runtime checks' child changes in its environment (None: unset; see :func:`runtime_problems`)."""


def child_env(env: dict[str, str | None]) -> dict[str, str]:
    """The environment of a checking child: this process's, with ``env`` (a value None: the variable unset), this
    flowtex package first on ``PYTHONPATH`` and no background compiles."""
    root = str(Path(__file__).resolve().parents[1])  # the folder holding this flowtex package
    given = {**os.environ, **env, "PYTHONPATH": os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])]),
             BACKGROUND_ENV: "0"}
    return {name: value for name, value in given.items() if value is not None}


def _children(target: str, classes: list[type[Node]], mode: str,
              env: dict[str, str | None]) -> dict[str, tuple[list[dict], str | None]]:
    """Run ``python -m flowtex.kernelprobe MODE TARGET TYPE...`` for ``classes`` in :func:`child_env` of ``env``; per
    type name its JSON items, and None or why its check failed.

    One process checks every type (a process costs about a second of imports and numba start-up before it checks
    anything). A type that crashes the process or runs longer than :data:`PROBE_TIMEOUT_S` is reported as such, and the
    types after it are checked in a new process.
    """
    results: dict[str, tuple[list[dict], str | None]] = {}
    pending = [cls.type_name for cls in classes]
    while pending:
        items, done, current, failed = _child(mode, target, pending, child_env(env))
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
    child compiles the kernel and every function it calls afresh. What it found is kept beside the compiled code, keyed
    as that code is (:func:`allocation_key`), so the same kernel is not compiled afresh again to say the same.
    """
    keys = {cls.type_name: allocation_key(cls) for cls in classes}
    known = {name: (calls, None) for name, key in keys.items() if (calls := _kept_allocations(key)) is not None}
    fresh = [cls for cls in classes if cls.type_name not in known]
    if fresh:
        with tempfile.TemporaryDirectory(prefix="flowtex-alloc-") as tmp:
            found = _children(target, fresh, "allocations", {"NUMBA_CACHE_DIR": tmp})
        for name, (items, failed) in found.items():
            calls = sorted({str(call) for item in items for call in item.get("allocations", [])})
            known[name] = (calls, failed)
            if failed is None:
                _keep_allocations(keys[name], calls)
    return {cls.type_name: known[cls.type_name] for cls in classes}


def allocation_key(cls: type[Node]) -> Path | None:
    """Where the allocation check of ``cls``'s kernel is kept: a file named by a digest of everything its compiled code
    depends on, as the compile cache keys it (flowtex's source tree, the plugin's code id: any edit to the plugin's
    folder or package, numba and llvmlite's versions, the ``NUMBA_*`` settings), plus the type and kernel names.
    None (never kept) for a kernel from neither flowtex nor a plugin folder or registered plugin package: nothing
    tells when its code changes."""
    import hashlib

    import llvmlite
    import numba

    from .cache import folder_in_package, numba_cache_folder, source_fingerprint
    from .plugincode import plugin_code_of

    kernel = cls.get_kernel()
    func = getattr(kernel, "py_func", kernel)
    code = plugin_code_of(func)
    if code is None and folder_in_package(getattr(getattr(func, "__code__", None), "co_filename", "")) is None:
        return None
    settings = sorted((k, v) for k, v in os.environ.items() if k.startswith("NUMBA_") and k != "NUMBA_CACHE_DIR")
    what = [source_fingerprint(), numba.__version__, llvmlite.__version__, tuple(code) if code else None, settings,
            cls.type_name, getattr(func, "__module__", ""), getattr(func, "__qualname__", "")]
    digest = hashlib.sha256(repr(what).encode()).hexdigest()[:32]
    return numba_cache_folder() / "allocation-checks" / f"{digest}.json"


def _kept_allocations(path: Path | None) -> list[str] | None:
    """The allocator calls kept at ``path``; None when there is no such record or it is unreadable (checked afresh)."""
    if path is None:
        return None
    try:
        calls = json.loads(path.read_text(encoding="utf-8"))["allocations"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError):  # RecursionError: a damaged file nested deep
        return None
    return calls if isinstance(calls, list) and all(isinstance(c, str) for c in calls) else None


def _keep_allocations(path: Path | None, calls: list[str]) -> None:
    """Keep a finished allocation check at ``path`` (atomically; a cache that cannot be written is only slower)."""
    from .cache import write_cache_file

    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_cache_file(path, json.dumps({"allocations": calls}).encode())
    except OSError:
        pass


def runtime_problems(target: str, classes: list[type[Node]]) -> dict[str, list[tuple[int, str]]]:
    """Per type name: (line, message) from :mod:`flowtex.kernelprobe` run in a child process with numba's bounds
    checking on.

    The child compiles into the bounds-checked cache folders (:func:`flowtex.cache.numba_cache_folder`: bounds-checked
    machine code must not replace the normal one), filed and keyed as the normal cache is: by flowtex's source tree and
    by the plugin's code id, so an edit to a helper file gives new code and a copy of the plugin folder elsewhere loads
    what the first compiled (a caller's ``NUMBA_CACHE_DIR`` is not passed on: it would turn that filing off and receive
    bounds-checked code). A crash or a timeout there is reported, not suffered here.
    """
    from .cache import numba_cache_folder, prune_cache_tree

    prune_cache_tree(numba_cache_folder(boundscheck=True))  # also checks, here, that the cache folder can be written
    found = _children(target, classes, "runtime", RUNTIME_ENV)
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
