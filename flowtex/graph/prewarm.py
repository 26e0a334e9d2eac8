"""Compile a cold graph's missing kernel wrappers on two cores instead of one.

When a graph needs several wrappers that are not in the cache yet (a first
run after install), :func:`start_helper` starts one helper process that
compiles the dispatch driver, then the wrappers in *reverse* order, while the
calling process compiles them in order. Each entry is compiled under its lock
(:mod:`flowtex.graph.kcache`): whichever process comes second to an entry
waits for it and loads it. The two meet in the middle, so a cold first run
takes about half the compile time on a 2-core machine. Only kernels of
flowtex's own modules are handed over (a plugin's module is not importable
by name); ``FLOWTEX_BACKGROUND=0`` also turns the helper off.
"""

from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys
from collections.abc import Callable

from .background import BACKGROUND_ENV, enabled
from .wrappers import is_cached, load_wrapper

MIN_MISSING = 2


def start_helper(needed: list[tuple[Callable, int, int]]) -> subprocess.Popen | None:
    """Start the helper for the uncached wrappers in ``needed`` (kernel, inputs, outputs), or None."""
    missing = [(k, a, b) for k, a, b in dict.fromkeys(needed) if not is_cached(k, a, b)]
    handed = [(k.py_func.__module__, k.py_func.__qualname__, a, b) for k, a, b in missing
              if getattr(k, "py_func", k).__module__.startswith("flowtex.")]
    if len(handed) < MIN_MISSING or (os.cpu_count() or 1) < 2 or not enabled():
        return None
    return subprocess.Popen([sys.executable, "-m", __name__, json.dumps(handed[::-1])], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, BACKGROUND_ENV: "0"})


def main(request: str) -> int:
    from . import tiers

    tiers.dispatch_run()  # first: the caller needs the driver last
    for module, name, n_in, n_out in json.loads(request):
        load_wrapper(getattr(importlib.import_module(module), name), n_in, n_out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
