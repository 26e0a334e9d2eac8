"""The compile service: tier choice, background and prewarm jobs, environment switches, platform guards.

Tiers (docs/engine.md):

``fused`` (tier 1)
    one ``block``/``run``/``step`` generated for the graph's structure and
    compiled by numba with every kernel inlined (:mod:`flowtex.graph.fused`):
    the fastest tick, but each new structure costs a full compile (seconds).
``dispatch`` (tier 0)
    one generic driver, compiled once per machine, calls each node's cached
    wrapper through its address (:mod:`flowtex.graph.dispatch`): a structural
    edit compiles nothing new when its node types were seen before.
``auto``
    ``fused`` when this structure's fused code is already in the cache,
    otherwise ``dispatch`` (and, from :func:`flowtex.load_graph`, a background
    compile of the fused code for next time).

Jobs, each a ``python -m flowtex.compile.worker`` process (:mod:`.worker`):

background
    when ``auto`` runs a graph on the dispatch tier, compiles its fused tier at
    the lowest CPU priority (``nice 19``) so the next run of the same structure
    takes it. The newest request wins: each background job writes its pid to
    ``<cache>/background.pid`` and stops the previous one first, so at most one
    runs per cache and it is always for the latest edit.
prewarm
    when a graph needs several kernel wrappers not in the cache yet (a first run
    after install), one helper compiles the dispatch driver, then the wrappers
    in *reverse* order, while this process compiles them in order; each entry
    is compiled under its lock (:mod:`flowtex.graph.kcache`), so whichever
    process comes second to an entry loads it. A cold first run takes about
    half the compile time on a 2-core machine.

``FLOWTEX_BACKGROUND=0`` turns both jobs off (the test suite does, to keep
its CPU to itself).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..cache import cache_dir, prune_numba_cache
from ..config import BACKGROUND_ENV, COMPILE_ENV, background_enabled, compile_tier, worker_env
from ..errors import FlowtexError
from ..graph.arena import Layout
from ..graph.kcache import locked
from ..graph.notice import compile_notice
from ..graph.resolved import ResolvedGraph

TIERS = ("fused", "dispatch", "auto")
WORKER = "flowtex.compile.worker"
"""Module of the one subprocess entry point (``python -m flowtex.compile.worker JOB REQUEST``)."""
MIN_MISSING = 2
"""Uncached wrappers below this number are compiled in this process alone (a helper costs a process start)."""
PID_FILE = "background.pid"


def check_tier(tier: str) -> str:
    """``tier`` if it is one of :data:`TIERS`, else a :class:`FlowtexError` naming the choices."""
    if tier not in TIERS:
        raise FlowtexError(f"unknown compile tier {tier!r}; use one of {', '.join(TIERS)} (--compile / {COMPILE_ENV})")
    return tier


def default_tier() -> str:
    """The tier of a caller that names none: ``$FLOWTEX_COMPILE``, else ``fused``."""
    return check_tier(compile_tier())


_FIRST_COMPILE: list[bool] = []


def compile_tick(resolved: ResolvedGraph, layout: Layout, plan: Any, tier: str, step_in: list[str],
                 step_out: list[str]) -> Any:
    """Compile (or load from the disk cache) the tick of ``resolved`` on ``tier`` (``fused``, ``dispatch`` or ``auto``).

    ``plan`` is the graph's :class:`~flowtex.graph.fused.FusedPlan`; returns the backend's
    :class:`~flowtex.graph.fused.Compiled`. Says so on stderr when compiling takes long. The dispatch tier is ready
    on return; the fused tier compiles each entry point (``run``, ``block``, ``step``) on its first use.
    """
    from ..graph.dispatch import compile_dispatch, needed_wrappers
    from ..nodecheck import check_plugin_kernels

    if not _FIRST_COMPILE:
        _FIRST_COMPILE.append(True)
        prune_numba_cache()  # once per process, at its first compile (never at import)
    use = "fused" if tier == "fused" or (tier == "auto" and plan.cached("run")) else "dispatch"
    types = sorted({rn.cls.type_name for rn in resolved.nodes.values()})
    what = f"graph {resolved.spec.name!r} ({len(resolved.nodes)} nodes: {', '.join(types)})"
    with compile_notice(what if use == "fused" else f"node kernels of {what}", str(cache_dir())):
        check_plugin_kernels(rn.cls for rn in resolved.nodes.values())  # a typing error is the plugin's, at its line
        if use == "fused":  # each entry point compiles on its first use (an offline run: run alone), announced alike
            return plan.compile(layout.i, lambda: compile_notice(what, str(cache_dir())))
        helper = start_prewarm(needed_wrappers(resolved))  # a cold cache: compile on two cores

        def helper_done() -> None:
            if helper is not None:
                helper.wait()  # it finishes the driver, or an entry this process is waiting for anyway

        return compile_dispatch(resolved, layout, step_in, step_out, helper_done)


def _worker(job: str, request: str) -> list[str]:
    """Command line of a worker process doing ``job`` (``background`` or ``prewarm``) for the JSON ``request``."""
    return [sys.executable, "-m", WORKER, job, request]


def start_prewarm(needed: list[tuple[Callable, int, int]]) -> subprocess.Popen | None:
    """Start the prewarm helper for the uncached wrappers in ``needed`` (kernel, inputs, outputs), or None."""
    from ..graph.wrappers import is_cached

    missing = [(k, a, b) for k, a, b in dict.fromkeys(needed) if not is_cached(k, a, b)]
    handed = [(k.py_func.__module__, k.py_func.__qualname__, a, b) for k, a, b in missing
              if getattr(k, "py_func", k).__module__.startswith("flowtex.")]  # a plugin's module is not importable by name
    if len(handed) < MIN_MISSING or (os.cpu_count() or 1) < 2 or not background_enabled():
        return None
    return subprocess.Popen(_worker("prewarm", json.dumps(handed[::-1])), stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=worker_env(**{BACKGROUND_ENV: "0"}))


def compile_in_background(path: str | Path, overrides: Mapping[str, Any], plugins: tuple[str | Path, ...],
                          block_rows: int, auto_plugins: bool = True) -> subprocess.Popen | None:
    """Start the background compile of the fused tier of the graph file ``path`` (None when turned off)."""
    if not background_enabled():
        return None
    try:
        text = Path(path).read_text(encoding="utf-8")  # now: the file may be gone (or edited again) when the compile starts
        request = json.dumps({"path": str(Path(path).resolve()), "text": text, "overrides": dict(overrides),
                              "plugins": [str(Path(p).resolve()) for p in plugins], "block_rows": block_rows,
                              "auto_plugins": auto_plugins})
    except (TypeError, OSError, UnicodeDecodeError):
        return None  # an override that is not JSON (a Python object), or an unreadable file: nothing to hand over
    return subprocess.Popen(_worker("background", request), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True,
                            env=worker_env(**{COMPILE_ENV: "fused", BACKGROUND_ENV: "0"}))


# --- platform guards -------------------------------------------------------------------------------------------

def _is_background(pid: int) -> bool:
    """True when process ``pid`` is a background compile job of this service.

    Read from ``/proc/PID/cmdline`` (Linux): a pid in the pid file may have been reused by another program. Where
    there is no ``/proc`` the answer is False, so nothing is ever stopped there: an older job then finishes its
    (harmless, superseded) compile.
    """
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False
    return WORKER.encode() in cmdline and b"\0background\0" in cmdline


def background_running(folder: Path | None = None) -> bool:
    """True while a background compile job of the cache ``folder`` (default: this process's cache) runs.

    Always False where ``/proc`` is missing (see :func:`_is_background`).
    """
    pid_file = (folder if folder is not None else cache_dir()) / PID_FILE
    try:
        return _is_background(int(pid_file.read_text()))
    except (OSError, ValueError):
        return False


def take_over(pid_file: Path) -> None:
    """Stop the previous background compile (if it is still running) and record this process as the current one."""
    with locked(pid_file.with_suffix(".lock")):
        with contextlib.suppress(OSError, ValueError):
            old = int(pid_file.read_text())
            if old != os.getpid() and _is_background(old):
                os.kill(old, signal.SIGTERM)
        pid_file.write_text(str(os.getpid()))


def lower_priority() -> None:
    """Run this process at the lowest CPU priority where the platform has ``nice`` (POSIX)."""
    if hasattr(os, "nice"):
        os.nice(19)

