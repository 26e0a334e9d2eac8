"""Two copies of the same flowtex sources share compiled kernels (flowtex.cache): a fresh clone, a reinstall, a CI
run or a branch switched away and back loads what the first copy compiled, and an edited copy does not."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numba

from flowtex.cache import PACKAGE, source_fingerprint
from flowtex.dsp.triangulation import clamp_query

CHILD = """
import sys
from flowtex.dsp.triangulation import clamp_query
assert clamp_query(5.0, 3.0, 0.5, 0.1, 0.01) == 2.5
import flowtex
print(flowtex.__file__, sum(clamp_query.stats.cache_hits.values()), sum(clamp_query.stats.cache_misses.values()))
"""
"""Calls one small cached kernel of the copy and prints where flowtex came from and numba's cache hits and misses."""


def _copy_package(dest: Path) -> Path:
    """A copy of the flowtex package at another path, every file with a new modification time (as a clone has)."""
    shutil.copytree(PACKAGE, dest / "flowtex", ignore=shutil.ignore_patterns("__pycache__"))
    for path in (dest / "flowtex").rglob("*.py"):
        os.utime(path, (1.0e9, 1.0e9))
    return dest


def _run_copy(root: Path) -> tuple[str, int, int]:
    env = {**os.environ, "PYTHONPATH": str(root)}
    env.pop("NUMBA_CACHE_DIR", None)
    done = subprocess.run([sys.executable, "-c", CHILD], env=env, cwd=root, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    where, hits, misses = done.stdout.split()
    return where, int(hits), int(misses)


def test_the_fingerprint_follows_contents_not_paths_or_times(tmp_path):
    copy = _copy_package(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(copy)}
    code = "import flowtex, flowtex.cache as c; print(flowtex.__file__, c.source_fingerprint())"
    where, fingerprint = subprocess.run([sys.executable, "-c", code], env=env, cwd=copy, capture_output=True, text=True,
                                        check=True, timeout=120).stdout.split()
    assert Path(where).is_relative_to(copy)
    assert fingerprint == source_fingerprint()
    (copy / "flowtex" / "dsp" / "triangulation.py").write_text((PACKAGE / "dsp" / "triangulation.py").read_text() + "\n# edited\n")
    edited = subprocess.run([sys.executable, "-c", code], env=env, cwd=copy, capture_output=True, text=True, check=True,
                            timeout=120).stdout.split()[1]
    assert edited != fingerprint


def test_a_copy_elsewhere_loads_the_kernels_the_first_copy_compiled(tmp_path):
    assert clamp_query(5.0, 3.0, 0.5, 0.1, 0.01) == 2.5  # this copy compiles it (or loads it) into the shared cache
    assert numba.config.CACHE_DIR and Path(numba.config.CACHE_DIR).name == source_fingerprint()
    assert Path(clamp_query._cache._cache_path) == Path(numba.config.CACHE_DIR) / "flowtex" / "dsp"
    where, hits, misses = _run_copy(_copy_package(tmp_path))
    assert Path(where).is_relative_to(tmp_path)  # the copy ran, not this checkout
    assert (hits, misses) == (1, 0)


def test_an_unreadable_source_file_gives_a_fingerprint_not_an_error(monkeypatch):
    victim = PACKAGE / "dsp" / "powerlaw.py"
    read = Path.read_bytes

    def refusing(self: Path) -> bytes:
        if self == victim:
            raise PermissionError(13, "Permission denied", str(self))
        return read(self)

    monkeypatch.setattr(Path, "read_bytes", refusing)
    fingerprint = source_fingerprint.__wrapped__()  # computed afresh, not the process's cached answer
    assert len(fingerprint) == 16 and fingerprint != source_fingerprint()
