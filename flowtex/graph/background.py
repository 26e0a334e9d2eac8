"""Compile a graph's fused tier in a low-priority background process, for next time.

When ``auto`` runs a graph on the dispatch tier (its fused code is not cached
yet), :func:`compile_in_background` starts ``python -m flowtex.graph.background``
at the lowest CPU priority (``nice 19``): the foreground run keeps the CPU, and
the fused code lands in the cache, so the next run of the same structure
takes the fused tier.

Several edits in a row: the newest request wins. Each background process
writes its pid to ``<cache>/background.pid`` and stops the previous one
(only a process whose command line is this module) before compiling, so at
most one background compile runs per cache and it is always for the latest
edit. ``FLOWTEX_BACKGROUND=0`` turns background compiles off (the test suite
does, to keep its CPU to itself).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..cache import cache_dir
from .kcache import locked

BACKGROUND_ENV = "FLOWTEX_BACKGROUND"
MODULE = "flowtex.graph.background"


def enabled() -> bool:
    return os.environ.get(BACKGROUND_ENV, "1").strip().lower() not in ("0", "false", "no", "off")


def compile_in_background(path: str | Path, overrides: Mapping[str, Any], plugins: tuple[str | Path, ...],
                          block_rows: int, auto_plugins: bool = True) -> subprocess.Popen | None:
    """Start the background compile of the fused tier of the graph file ``path`` (None when turned off)."""
    if not enabled():
        return None
    try:
        text = Path(path).read_text(encoding="utf-8")  # now: the file may be gone (or edited again) when the compile starts
        request = json.dumps({"path": str(Path(path).resolve()), "text": text, "overrides": dict(overrides),
                              "plugins": [str(Path(p).resolve()) for p in plugins], "block_rows": block_rows,
                              "auto_plugins": auto_plugins})
    except (TypeError, OSError, UnicodeDecodeError):
        return None  # an override that is not JSON (a Python object), or an unreadable file: nothing to hand over
    return subprocess.Popen([sys.executable, "-m", MODULE, request], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                            env={**os.environ, "FLOWTEX_COMPILE": "fused", BACKGROUND_ENV: "0"})


def _is_background(pid: int) -> bool:
    try:
        return MODULE.encode() in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def take_over(pid_file: Path) -> None:
    """Stop the previous background compile (if it is still running) and record this process as the current one."""
    with locked(pid_file.with_suffix(".lock")):
        with contextlib.suppress(OSError, ValueError):
            old = int(pid_file.read_text())
            if old != os.getpid() and _is_background(old):
                os.kill(old, signal.SIGTERM)
        pid_file.write_text(str(os.getpid()))


def main(request: str) -> int:
    os.nice(19)
    args = json.loads(request)
    folder = cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    take_over(folder / "background.pid")
    from .compiled import Graph, graph_registry
    from .resolve import resolve_graph
    from .spec import parse_spec

    path = Path(args["path"])  # the text as it was; relative paths in it resolve against its folder, as in the run
    spec = parse_spec(args["text"], path, args["overrides"])
    registry = graph_registry(path, tuple(args["plugins"]), args["auto_plugins"], spec.plugins)
    Graph(resolve_graph(spec, registry), args["block_rows"], "fused")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
