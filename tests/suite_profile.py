"""Where the suite's time goes: a pytest plugin that logs each test's CPU and numba time (docs/testing.md).

Turned on by ``PYTEST_FLOWTEX_PROFILE=FOLDER`` (tests/conftest.py registers it then, and only then). Every
test (setup, call and teardown, so a module fixture counts in the first test that needs it) appends one JSON line
to ``FOLDER/<worker>.jsonl``:

``wall``        seconds of wall time
``cpu``         seconds of CPU time of this process (user + system)
``children``    seconds of CPU time of the subprocesses the test waited for (CLI runs, live sessions, JACK)
``numba``       seconds of wall time inside numba's compiler lock: compiles and loads from the disk cache
``compiles``    seconds of wall time of numba compiles that were not cache hits (outermost ``numba:compile``
                events; a C-callable wrapper's own compile is not one, the kernels it calls are)
``compiled``    the functions numba compiled (not loaded from its cache), nested ones included

``python benchmarks/suite_profile.py FOLDER`` sums them per file and per worker.
"""

from __future__ import annotations

import json
import os
import resource
import time
from pathlib import Path

import pytest
from numba.core import event

ENV = "PYTEST_FLOWTEX_PROFILE"


class _Nested(event.Listener):
    """Wall time spent in the outermost of nested numba events of one kind."""

    def __init__(self) -> None:
        self.depth = 0
        self.start = 0.0
        self.total = 0.0
        self.names: list[str] = []
        """Every function compiled (nested ones too), as ``module.qualname(signature)``."""

    def on_start(self, ev: event.Event) -> None:
        self.depth += 1
        if self.depth == 1:
            self.start = time.perf_counter()
        data = ev.data if isinstance(ev.data, dict) else {}
        func = getattr(data.get("dispatcher"), "py_func", None) or getattr(data.get("dispatcher"), "_pyfunc", None)
        if func is not None:
            self.names.append(f"{func.__module__}.{func.__qualname__}{tuple(str(a) for a in data.get('args', ()))}")

    def on_end(self, ev: event.Event) -> None:
        self.depth -= 1
        if self.depth == 0:
            self.total += time.perf_counter() - self.start


class SuiteProfile:
    """The plugin object: one JSON line per test into ``folder``."""

    def __init__(self, folder: Path) -> None:
        self.lock, self.compile = _Nested(), _Nested()
        event.register("numba:compiler_lock", self.lock)
        event.register("numba:compile", self.compile)
        self._time_cfunc_compiles()
        folder.mkdir(parents=True, exist_ok=True)
        self.out = (folder / f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')}.jsonl").open("a")

    def _time_cfunc_compiles(self) -> None:
        """Count a C callback's compile (a dispatch-tier wrapper, which fires no ``numba:compile``) as a compile."""
        from numba.core.ccallback import CFunc

        compile_, listener = CFunc.compile, self.compile

        def timed(cf: CFunc) -> None:
            hits, total, names = cf._cache_hits, listener.total, len(listener.names)
            listener.on_start(event.Event("numba:compile", event.EventStatus.START, {"dispatcher": cf, "args": cf._sig.args}))
            try:
                return compile_(cf)
            finally:
                listener.on_end(event.Event("numba:compile", event.EventStatus.END))
                if cf._cache_hits > hits:  # loaded from the disk cache: not a compile
                    listener.total = total
                    del listener.names[names:]

        CFunc.compile = timed

    @pytest.hookimpl(hookwrapper=True)
    def pytest_runtest_protocol(self, item, nextitem):  # type: ignore[no-untyped-def]
        me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        wall, lock, comp = time.perf_counter(), self.lock.total, self.compile.total
        self.compile.names.clear()
        yield
        me2, kids2 = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
        self.out.write(json.dumps({
            "test": item.nodeid, "file": item.nodeid.split("::")[0],
            "worker": os.environ.get("PYTEST_XDIST_WORKER", "main"),
            "wall": round(time.perf_counter() - wall, 4),
            "cpu": round(me2.ru_utime + me2.ru_stime - me.ru_utime - me.ru_stime, 4),
            "children": round(kids2.ru_utime + kids2.ru_stime - kids.ru_utime - kids.ru_stime, 4),
            "numba": round(self.lock.total - lock, 4), "compiles": round(self.compile.total - comp, 4),
            "compiled": self.compile.names}) + "\n")
        self.out.flush()


def register(config: pytest.Config) -> None:
    """Register the plugin when ``$PYTEST_FLOWTEX_PROFILE`` names a folder."""
    folder = os.environ.get(ENV)
    if folder:
        config.pluginmanager.register(SuiteProfile(Path(folder)), "flowtex-suite-profile")
