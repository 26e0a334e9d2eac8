"""A compile cache copied or moved elsewhere loads the code flowtex generated (flowtex.cache.GENERATED): the fused
tier's graph modules and the live tick are filed by their content digest, not by the cache's path, and stamped with
their file's contents, so an edited file never loads the old machine code."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numba
import pytest

import flowtex.runtime.fused as fused_tick
from flowtex.cache import GENERATED_FOLDER, cache_dir, source_fingerprint
from flowtex.graph.compiled import load_graph
from flowtex.graph.dispatch import dispatch_run
from flowtex.graph.jit import import_source, load_generated
from flowtex.graph.kcache import locked
from flowtex.graph.wrappers import load_wrapper
from flowtex.nodes.arith import Gain
from flowtex.runtime.canio import load_io, tick_out
from tests.cli.gain_graph import GAIN_GRAPH, MAP_GRAPH

REPO = Path(__file__).resolve().parents[1]
DBC, MAP = REPO / "graphs" / "devices" / "example.dbc", REPO / "graphs" / "devices" / "example_map.yaml"

CHILD = """
import json, sys
import numpy as np
from numba.core import event

compiled = []

class Compiles(event.Listener):
    def on_start(self, ev):
        d = ev.data if isinstance(ev.data, dict) else {}
        f = getattr(d.get("dispatcher"), "py_func", None)
        compiled.append(f"{f.__module__}.{f.__qualname__}" if f is not None else "?")

    def on_end(self, ev):
        pass

event.register("numba:compile", Compiles())
import flowtex
from flowtex.graph.compiled import load_graph
from flowtex.nodes.arith import Gain
from flowtex.runtime.canio import load_io, tick_out
from flowtex.runtime.fused import fuse_tick
from flowtex.graph import wrappers

gain, mapped, dbc, canmap = sys.argv[1:]
y = load_graph(gain, tier="fused").run({"x": np.arange(4.0)})["y"].tolist()
g = load_graph(mapped, tier="fused", block_rows=1)
io = load_io(g, dbc, canmap)
assert fuse_tick(g, io, tick_out, io.new_watchdog(1).last) is not None
y_dispatch = load_graph(gain, tier="dispatch").run({"x": np.arange(4.0)})["y"].tolist()
(wrapper,) = wrappers._LOADED.values()
print(json.dumps({"flowtex": flowtex.__file__, "y": y, "y_dispatch": y_dispatch, "compiled": compiled,
                  "wrapper_loaded": wrapper.cache_hits}))
"""
"""Runs the gain graph on the fused tier, builds the live tick of the mapped graph and runs the gain graph on the
dispatch tier; prints every numba compile (``numba:compile`` fires for compiles only, not for loads from the disk
cache; a C-callable wrapper's compile fires none: its cache hits are printed)."""


def _compile_here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Path, list[Any]]:
    """Compile (or load) what the child runs in this process, into the suite's cache; the graph files and the compiled
    functions of the generated modules (the gain graph's ``run``, the mapped graph's live tick, the dispatch tier's
    ``run`` and the gain kernel's wrapper)."""
    gain, mapped = tmp_path / "gain.yaml", tmp_path / "mapped.yaml"
    gain.write_text(GAIN_GRAPH)
    mapped.write_text(MAP_GRAPH)
    graph = load_graph(gain, tier="fused")
    assert graph.run({"x": [1.0]})["y"].tolist() == [2.0]
    plan = graph.fused_plan
    functions = [load_generated(plan.source, plan.kernels, plan.versions).run]
    loaded = fused_tick.load_generated

    def noting(*args, **kw):  # the live tick's module
        module = loaded(*args, **kw)
        functions.append(module.live_tick)
        return module

    monkeypatch.setattr(fused_tick, "load_generated", noting)
    g = load_graph(mapped, tier="fused", block_rows=1)
    io = load_io(g, DBC, MAP)
    assert fused_tick.fuse_tick(g, io, tick_out, io.new_watchdog(1).last) is not None
    assert len(functions) == 2
    assert load_graph(gain, tier="dispatch").run({"x": [1.0]})["y"].tolist() == [2.0]
    functions += [dispatch_run(), load_wrapper(Gain.get_kernel(), len(Gain.inputs), len(Gain.outputs))]
    return gain, mapped, functions


def _copy_cache(dest: Path, functions: list[Any]) -> None:
    """What the child needs of the suite's cache, copied to ``dest`` as ``cp -r`` copies (new modification times), each
    file at the same place within the cache: numba's entries of flowtex's kernels, and the generated modules' sources,
    seals and numba entries (wherever numba filed them)."""
    numba_here = Path(numba.config.CACHE_DIR)
    numba_there = dest / "numba" / source_fingerprint()
    shutil.copytree(numba_here / "flowtex", numba_there / "flowtex", copy_function=shutil.copy,
                    ignore=shutil.ignore_patterns("*.tmp.*", ".*.tmp"))  # files another worker is writing: not entries
    for fn in functions:
        py_func = getattr(fn, "py_func", None) or fn._pyfunc  # a dispatcher's, or a C-callable wrapper's
        source = Path(py_func.__code__.co_filename)  # <cache>/codegen/g_<digest>.py, <cache>/kernels/w_<digest>.py
        stem, folder = source.stem, dest / source.parent.relative_to(cache_dir())
        folder.mkdir(exist_ok=True)
        with locked(source.with_suffix(".lock")):  # no other worker writes the entry meanwhile
            for path in source.parent.glob(f"{stem}.*"):
                if path.suffix in (".py", ".seal"):
                    shutil.copy(path, folder / path.name)
            entries = Path(fn._cache._cache_path)
            there = numba_there / entries.relative_to(numba_here)
            there.mkdir(parents=True, exist_ok=True)
            copied = [shutil.copy(p, there / p.name) for p in entries.glob(f"{stem}.*")]
            assert copied, f"no numba entry of {stem} in {entries}"


def _child(cache: Path, gain: Path, mapped: Path) -> dict:
    env = {**os.environ, "FLOWTEX_CACHE_DIR": str(cache), "FLOWTEX_BACKGROUND": "0", "PYTHONPATH": str(REPO)}
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, "-c", CHILD, str(gain), str(mapped), str(DBC), str(MAP)], env=env,
                          cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_copied_then_moved_cache_loads_fused_graph_live_tick_and_dispatch_tier_without_compiling(tmp_path, monkeypatch):
    gain, mapped, functions = _compile_here(tmp_path, monkeypatch)
    copy = tmp_path / "copy"
    _copy_cache(copy, functions)
    result = _child(copy, gain, mapped)
    assert Path(result["flowtex"]).is_relative_to(REPO)
    assert result["y"] == [0.0, 2.0, 4.0, 6.0]
    assert result["compiled"] == []  # before: numba filed them by the cache's path (and older numba by file times)
    assert result["y_dispatch"] == [0.0, 2.0, 4.0, 6.0] and result["wrapper_loaded"] == 1
    moved = tmp_path / "elsewhere" / "moved"
    moved.parent.mkdir()
    os.rename(copy, moved)  # what `mv` does: the same files, times kept, at another path
    result = _child(moved, gain, mapped)
    assert result["y"] == result["y_dispatch"] == [0.0, 2.0, 4.0, 6.0]
    assert result["compiled"] == [] and result["wrapper_loaded"] == 1


TINY = "from numba import njit\n\n\n@njit(cache=True)\ndef f(x):\n    return x + {}\n"
"""A generated module's smallest form: editing the constant leaves ``f``'s bytecode (numba's key) unchanged."""


def _tiny(path: Path, constant: str, name: str):
    """Import ``TINY`` with ``constant`` from ``path`` as a generated module; its ``f``."""
    return import_source(path, TINY.format(constant), {}, f"flowtex_test_generated_{name}").f


def test_generated_entries_are_filed_by_name_and_stamped_by_contents(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "numba"))
    first = tmp_path / "a" / "codegen" / "g_tiny.py"
    f = _tiny(first, "1.0", "first")
    assert f(1.0) == 2.0
    assert Path(f._cache._cache_path) == tmp_path / "numba" / GENERATED_FOLDER
    assert sum(f.stats.cache_misses.values()) == 1
    # the same file in another folder, written later (a copied cache): loaded, not compiled
    same = _tiny(tmp_path / "b" / "codegen" / "g_tiny.py", "1.0", "copy")
    assert same(1.0) == 2.0
    assert sum(same.stats.cache_hits.values()) == 1 and sum(same.stats.cache_misses.values()) == 0
    # the file edited in place, same name, same bytecode: compiled afresh, never the old machine code
    edited = _tiny(first, "2.0", "edited")
    assert edited(1.0) == 3.0
    assert sum(edited.stats.cache_hits.values()) == 0 and sum(edited.stats.cache_misses.values()) == 1
    again = _tiny(tmp_path / "c" / "g_tiny.py", "2.0", "edited_again")  # and the edited entry is the one kept now
    assert again(1.0) == 3.0 and sum(again.stats.cache_hits.values()) == 1


def test_numbas_locator_setting_still_rules(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "numba"))
    monkeypatch.setattr(numba.config, "CACHE_LOCATOR_CLASSES", "UserProvidedCacheLocator")
    f = _tiny(tmp_path / "codegen" / "g_tiny.py", "1.0", "numbas_locator")
    assert f(1.0) == 2.0
    folder = Path(f._cache._cache_path)  # numba's own: named after the source's folder and a hash of its path
    assert folder.parent == tmp_path / "numba" and folder.name.startswith("codegen_")
