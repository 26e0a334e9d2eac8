"""Shared test helpers: write graph files into tmp_path."""

from __future__ import annotations

import gc
import os
import subprocess
import textwrap
from pathlib import Path

import pytest
from hypothesis import settings

REPO = Path(__file__).resolve().parents[1]
pytest_plugins = ["pytester"]  # runs pytest inside a test (tests/test_golden_portability.py: what a golden failure prints)

if os.environ.get("NUMBA_CACHE_DIR"):
    # A caller's NUMBA_CACHE_DIR turns flowtex's filing of compiled code off (flowtex.cache), and the suite tests that
    # filing (test_cache_shared_by_copies, test_plugin_cache_copies, test_kernel_cache_damage): keep the caller's
    # choice of where caches may be written, as flowtex's own cache folder, and let flowtex file numba's code there.
    numba_dir = os.environ.pop("NUMBA_CACHE_DIR")
    if not os.environ.get("FLOWTEX_CACHE_DIR"):
        os.environ["FLOWTEX_CACHE_DIR"] = str(Path(numba_dir) / "flowtex")
for _blas_threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    # One BLAS thread per process in the run: pytest-xdist's workers (started after this file is read, so they inherit
    # it) and the processes the tests start. The workers already share the cores; a BLAS with a thread per core in
    # each of them oversubscribes the cores, and OpenBLAS's idle threads spin (docs/testing.md has the runs). Every
    # comparison of results is within this run's one setting.
    os.environ.setdefault(_blas_threads, "1")
os.environ.setdefault("FLOWTEX_BACKGROUND", "0")  # no background fused compiles (docs/engine.md) competing with the tests
# The suite runs on the dispatch tier: a structure costs no numba compile once its node types are cached, and both tiers
# give bit-identical outputs (tests/test_engine_tiers.py). The files below keep the fused tier: tier equivalence and goldens.
_SUITE_TIER_MARK = "PYTEST_FLOWTEX_SUITE_TIER"
"""Set beside FLOWTEX_COMPILE when this conftest chose the tier: pytest-xdist's workers inherit the controller's
environment, so in a worker FLOWTEX_COMPILE is already set and only this mark says the suite (not the caller) set it."""
if "FLOWTEX_COMPILE" not in os.environ:
    os.environ["FLOWTEX_COMPILE"] = "dispatch"
    os.environ[_SUITE_TIER_MARK] = "1"
SUITE_SETS_TIER = os.environ.get(_SUITE_TIER_MARK) == "1"

FUSED_TIER_FILES = frozenset({
    # tier equivalence and goldens
    "test_engine_tiers.py", "test_examples.py", "test_texture_examples.py", "test_golden_portability.py",
    # live sessions built through the Python API: live always runs the fused tick (flowtex live forces it), and only the
    # fused tier carries an exception raised inside a kernel out to the runtime (the dispatch tier's wrappers are C
    # callbacks): test_live.py's "exception inside the graph" session fails on the dispatch tier
    "test_live.py", "test_livesafe_dbc.py", "test_livesafe_guard.py", "test_livesafe_replay.py",
    "test_livesafe_session.py", "test_replay.py", "test_fused.py", "test_scene_live.py",
})
"""Test files that run on the fused tier (what library callers get by default), whatever the suite's default."""


settings.register_profile("flowtex", deadline=None)
"""Hypothesis's per-example deadline (200 ms) is off: an example's first call may compile a kernel (seconds, more on a
loaded machine), and speed is measured in benchmarks/, never in a test. Each test's ``max_examples`` is its own."""
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "flowtex"))

SLOW_FIRST = (
    "test_examples.py", "test_engine_tiers.py", "test_audio_jack.py", "test_live.py", "test_plugin_check.py",
    "test_plugin_declarations.py", "test_engine_cache.py", "test_plugin_new.py", "test_cli_hostile_options.py",
    "test_golden_portability.py", "test_fused.py", "test_friction_noise.py", "test_replay_stream.py", "test_livesafe_hostile.py",
    "test_hatt_parity.py", "test_scene_live.py", "test_texture_examples.py", "test_hostile_bounds.py", "test_fit_batch.py",
    "test_arma_resample.py", "test_kernel_faults.py", "test_resample_corpus.py", "test_crossval.py",
)
"""The test files that take longest (CPU and real time of a fresh-clone run, docs/testing.md), slowest first.

They are collected first so that pytest-xdist (``--dist loadfile``) starts them first: the many quick files then fill
the gaps at the end, and no slow file starts last on one worker while the other one waits (largest job first)."""


def pytest_configure(config: pytest.Config) -> None:
    if os.environ.get("PYTEST_FLOWTEX_PROFILE"):  # where the suite's time goes (tests/suite_profile.py, docs/testing.md)
        from suite_profile import register

        register(config)
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False  # xdist would order files by their number of tests; keep SLOW_FIRST's
    _GC_THRESHOLDS.append(gc.get_threshold())
    gc.set_threshold(COLLECTION_GC_THRESHOLD, *gc.get_threshold()[1:])


COLLECTION_GC_THRESHOLD = 50_000
"""Allocations between the cyclic garbage collector's young-generation passes while the test files are collected
(Python's default is 700). Collecting imports every test module and rewrites its asserts: millions of short-lived AST
nodes, which at the default set off full passes over every object numpy, scipy and numba hold: a large share of each
worker's collection CPU (docs/testing.md). Objects are still collected, only in larger batches."""
_GC_THRESHOLDS: list[tuple[int, int, int]] = []
"""The collector's thresholds before collection, restored once it is done."""


def pytest_collection_finish(session: pytest.Session) -> None:
    """Back to the default collector once collected, with what collection left frozen: the modules, functions and
    parameters that live until the run ends are then no longer traversed by each full pass during the tests (objects
    made by the tests are collected as before)."""
    gc.collect()
    gc.freeze()
    if _GC_THRESHOLDS:
        gc.set_threshold(*_GC_THRESHOLDS.pop())


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto``: one worker more than the CPUs this process may run on (``PYTEST_XDIST_AUTO_NUM_WORKERS`` still rules).

    Part of the suite waits on the clock rather than computing: live sessions tick at 1 kHz in real time and the JACK
    sessions play audio in real time, while their worker's core idles. A worker more than there are cores computes in
    those waits; a second extra one only adds collection and contention (docs/testing.md has the runs)."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS"):
        return None  # pytest-xdist's own hook reads it
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return cores + 1


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The files of :data:`SLOW_FIRST` first, in its order; the others after them, in collection order."""
    rank = {name: k for k, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # a stable sort: tests keep their order in a file


@pytest.fixture(autouse=True)
def _compile_tier(request, monkeypatch):
    """The fused tier for the files of :data:`FUSED_TIER_FILES`; the suite's default (dispatch) elsewhere.

    A tier set in the environment before the run (``FLOWTEX_COMPILE=fused pytest``) applies to every file."""
    if SUITE_SETS_TIER and request.path.name in FUSED_TIER_FILES:
        monkeypatch.setenv("FLOWTEX_COMPILE", "fused")


@pytest.fixture
def write_graph(tmp_path):
    """Write YAML text (dedented) to tmp_path/NAME and return its path."""

    def _write(text: str, name: str = "g.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text).lstrip("\n"))
        return path

    return _write


@pytest.fixture
def flowtex_cli(capsys):
    """Run ``flowtex ARGS...`` in this process (:func:`flowtex.cli.main`); its exit code, stdout and stderr, as
    :func:`subprocess.run` gives them. For tests about what a verb does: a fresh interpreter costs CPU (imports,
    kernels loaded from the cache; docs/testing.md) that the test does not look at. Tests about the process itself (signals,
    the interpreter's exit code, a fresh cache, installs) start a real one."""
    from flowtex.cli import main

    def run(*args: object) -> subprocess.CompletedProcess:
        capsys.readouterr()
        code = main([str(a) for a in args])
        out = capsys.readouterr()
        return subprocess.CompletedProcess(["flowtex", *map(str, args)], code, out.out, out.err)

    return run


@pytest.fixture
def nrt_allocations():
    """``count(fn, *args)``: the heap allocations numba's runtime made during ``fn(*args)``.

    numba counts them only while its runtime statistics are on: switched on for the test (numba's
    ``memsys_enable_stats``, what ``NUMBA_NRT_STATS=1`` does at start-up) and off again after it, in this process
    (a child started with the variable costs a second of imports). A call from Python boxes its array arguments: a
    count above 0 shows the counter is on."""
    from numba.core.runtime import _nrt_python as nrt
    from numba.core.runtime import rtsys

    def count(fn, *args) -> int:
        before = rtsys.get_allocation_stats().alloc
        fn(*args)
        return rtsys.get_allocation_stats().alloc - before

    was_on = nrt.memsys_stats_enabled()
    nrt.memsys_enable_stats()
    try:
        yield count
    finally:
        if not was_on:
            nrt.memsys_disable_stats()


HATT_ENV = "FLOWTEX_HATT_DIR"
"""Folder holding HaTT's published ``Models_*.xml`` files (research licence: never committed)."""


def hatt_xml_files() -> list[Path]:
    """HaTT's published model sets, from ``$FLOWTEX_HATT_DIR``; empty when the variable is unset or the folder holds none."""
    folder = os.environ.get(HATT_ENV)
    if not folder or not Path(folder).is_dir():
        return []
    return sorted(Path(folder).glob("Models_*.xml"))


@pytest.fixture(scope="session")
def hatt_files() -> list[Path]:
    """The HaTT XML model sets; skips the test when they are not on this machine (set FLOWTEX_HATT_DIR)."""
    files = hatt_xml_files()
    if not files:
        pytest.skip(f"HaTT's published model sets are not here (set {HATT_ENV} to the folder holding Models_*.xml)")
    return files
