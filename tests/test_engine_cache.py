"""The dispatch tier's kernel cache: damaged entries are rebuilt, concurrent compiles leave one good entry, keys."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numba
import pytest

from flowtex.cache import source_fingerprint
from flowtex.graph import wrappers
from flowtex.graph.kcache import entry_ok
from flowtex.nodes.arith import Add, Gain

GRAPHS = {  # node type -> (graph wiring, expected y for a = 0..4, b = 1)
    "gain": ("  n: {type: gain, params: {k: 2}}\nedges:\n  - a -> n.x\n", [0.0, 2.0, 4.0, 6.0, 8.0]),
    "add": ("  n: {type: add}\nedges:\n  - a -> n.a\n  - b -> n.b\n", [1.0, 2.0, 3.0, 4.0, 5.0]),
    "multiply": ("  n: {type: multiply}\nedges:\n  - a -> n.a\n  - b -> n.b\n", [0.0, 1.0, 2.0, 3.0, 4.0]),
}

SCRIPT = """
import json, sys
import numpy as np
from flowtex.graph import wrappers
from flowtex.graph.compiled import load_graph
for path in sys.argv[1:]:
    before, rebuilt = set(wrappers._LOADED), len(wrappers.REBUILT)
    graph = load_graph(path, tier="dispatch")
    y = graph.run({k: v for k, v in {"a": np.arange(5.0), "b": np.ones(5)}.items() if k in graph.inputs})["y"]
    (digest,) = set(wrappers._LOADED) - before  # the graph's one node type: one wrapper
    cf = wrappers._LOADED[digest]
    print(json.dumps({"digest": digest, "rebuilt": len(wrappers.REBUILT) - rebuilt, "hits": cf.cache_hits, "y": y.tolist()}))
"""
"""Runs each graph file named on its command line on the dispatch tier in one process; per graph one JSON line: its
wrapper's cache key, how many wrappers were rebuilt (a damaged entry), cache hits of its wrapper, and ``y``."""


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """One cache for this module with no wrapper entry (each test uses its own node type's wrapper), seeded with
    numba's entries of flowtex's own kernels and driver from the suite's cache, so that its processes compile only
    what is tested here, the wrappers. (The seed is a copy: damaging an entry here touches no other test's cache.)"""
    root = tmp_path_factory.mktemp("kcache")
    env = {**os.environ, "FLOWTEX_CACHE_DIR": str(root / "cache"), "FLOWTEX_BACKGROUND": "0"}
    env.pop("NUMBA_CACHE_DIR", None)
    ours = Path(numba.config.CACHE_DIR) / "flowtex"  # flowtex.cache files flowtex's kernels there (by source fingerprint)
    if ours.is_dir():  # other processes may be writing there: a file that vanishes mid-copy only costs its compile
        with contextlib.suppress(shutil.Error, OSError):
            shutil.copytree(ours, root / "cache" / "numba" / source_fingerprint() / "flowtex", ignore_dangling_symlinks=True)
    return root, env


def _start(cache, *nodes: str) -> subprocess.Popen:
    root, env = cache
    paths = []
    for node in nodes:
        paths.append(root / f"{node}.yaml")
        paths[-1].write_text("flowtex: 1\nname: tiny\nrate: 1000\ninputs:\n  a: {}\n  b: {}\nnodes:\n" + GRAPHS[node][0]
                             + "outputs:\n  y: n.y\n")
    return subprocess.Popen([sys.executable, "-c", SCRIPT, *map(str, paths)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _run(cache, *nodes: str) -> dict:
    """Runs ``nodes``' graphs in one new process; the result of each (one process: imports and numba's start-up once)."""
    results = _finish(_start(cache, *nodes), *nodes)
    return results[0] if len(nodes) == 1 else dict(zip(nodes, results, strict=True))


def _finish(proc: subprocess.Popen, *nodes: str) -> list[dict]:
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    results = [json.loads(line) for line in out.strip().splitlines()[-len(nodes):]]
    for node, result in zip(nodes, results, strict=True):
        assert result.pop("y") == GRAPHS[node][1]
    return results


@pytest.fixture(scope="module")
def first_runs(cache):
    """The damaged-entry test's first runs, in one process: each compiles its node type's wrapper into the empty cache."""
    return _run(cache, "gain", "multiply")


def _entry(cache, digest: str) -> tuple[Path, list[Path]]:
    """Seal and numba files of the wrapper entry ``digest``."""
    root = cache[0] / "cache"
    return root / "kernels" / f"w_{digest}.seal", sorted(p for p in (root / "numba").rglob(f"w_{digest}.*")
                                                         if p.suffix in (".nbi", ".nbc"))


def test_a_corrupt_entry_is_detected_and_rebuilt(cache, first_runs):
    damage = {"gain": "flip", "multiply": "truncate"}  # one entry each; both graphs then run in one process
    for node, how in damage.items():
        first = first_runs[node]
        assert first["rebuilt"] == 0 and first["hits"] == 0  # (an intact entry loads: the test below)
        seal, files = _entry(cache, first["digest"])
        data = next(p for p in files if p.suffix == ".nbc")
        raw = bytearray(data.read_bytes())
        if how == "flip":
            raw[len(raw) // 2] ^= 0xFF  # a byte of machine code or of its pickle: unpickling may even succeed
            data.write_bytes(bytes(raw))
        else:
            data.write_bytes(bytes(raw[: len(raw) // 3]))
    again = _run(cache, *damage)  # and still computes the right numbers (checked in _finish)
    for node in damage:
        assert again[node]["rebuilt"] == 1 and again[node]["hits"] == 0, node  # never trusted: compiled afresh
        assert entry_ok(*_entry(cache, first_runs[node]["digest"])), node  # and sealed again


def test_two_processes_compiling_the_same_kernel_leave_one_good_entry(cache):
    procs = [_start(cache, "add"), _start(cache, "add")]
    results = [_finish(p, "add")[0] for p in procs]
    assert all(r["rebuilt"] == 0 for r in results)
    assert sorted(r["hits"] for r in results) == [0, 1]  # the second waited for the first, then loaded its entry
    seal, files = _entry(cache, results[0]["digest"])
    assert [p.suffix for p in files] == [".nbc", ".nbi"], files  # one data file, one index: no duplicate
    assert entry_ok(seal, files)
    assert _run(cache, "add") == {"digest": results[0]["digest"], "rebuilt": 0, "hits": 1}


def test_the_cache_key_covers_kernel_source_numba_cpu_and_fastmath(monkeypatch):
    gain, add = Gain.get_kernel(), Add.get_kernel()
    src = wrappers.wrapper_source("k", 1, 1)
    base = wrappers.wrapper_digest(src, gain)
    assert wrappers.wrapper_digest(src, add) != base  # another kernel (source and name)
    assert wrappers.wrapper_digest(wrappers.wrapper_source("k", 2, 1), gain) != base  # another wrapper
    key = wrappers.machine_key()
    assert "cpu=" in key and "features=" in key and "numba=" in key and "contract=" in key
    for part, other in (("numba=", "numba=0.0.0;"), ("cpu=", "cpu=other;"), ("contract=", "contract=other")):
        changed = ";".join(other if item.startswith(part) else item for item in key.split(";"))
        monkeypatch.setattr(wrappers, "machine_key", lambda changed=changed: changed)
        assert wrappers.wrapper_digest(src, gain) != base, part
