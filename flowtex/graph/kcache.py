"""Sealed numba cache entries: verified before they are loaded, compiled once under a lock.

numba's ``cache=True`` trusts whatever it finds on disk: a truncated or
corrupted ``.nbc``/``.nbi`` file either raises deep inside unpickling or,
worse, loads damaged machine code. flowtex therefore *seals* every entry it
compiles: after a successful compile it writes ``<stem>.seal``, a JSON list of
the sha256 of each of the entry's numba files. Before the next load, the
files are hashed again; an entry whose files do not match its seal (or that
has files but no seal, e.g. after a crash) is deleted and compiled afresh.

Two processes compiling the same entry at the same time take turns on an
exclusive lock on ``<stem>.lock`` (``flock`` on POSIX, ``msvcrt.locking`` on
Windows, chosen when a lock is first taken, not at import): the second one
waits, then loads the entry the first one sealed. One good entry is left,
never two half-written ones.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

from ..cache import write_cache_file
from ..interrupts import interrupts_deferred

T = TypeVar("T")


@contextlib.contextmanager
def locked(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on the file ``path`` (created if missing) for the ``with`` block."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        _lock(fd)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _lock(fd: int) -> None:
    """Block until this process holds the exclusive lock on the open file ``fd`` (released when ``fd`` is closed)."""
    try:
        import fcntl
    except ImportError:  # Windows: lock the file's first byte; LK_LOCK retries for 10 s, so retry until it is ours
        import msvcrt

        while True:
            try:
                msvcrt.locking(fd, msvcrt.LK_LOCK, 1)  # type: ignore[attr-defined]
                return
            except OSError:
                continue
    fcntl.flock(fd, fcntl.LOCK_EX)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def seal_of(files: list[Path]) -> dict[str, str]:
    """File name -> sha256 of its bytes, for the files that exist."""
    return {p.name: _digest(p) for p in sorted(files) if p.exists()}


def entry_ok(seal_path: Path, files: list[Path]) -> bool:
    """True when ``files`` are exactly the ones sealed in ``seal_path``, byte for byte."""
    try:
        sealed = json.loads(seal_path.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(sealed, dict) and sealed == seal_of(files) and bool(sealed)


def sealed_compile(stem: Path, cache_files: Callable[[], list[Path]], compile_: Callable[[], T]) -> tuple[T, bool]:
    """Run ``compile_`` (which loads the entry from numba's cache or compiles and saves it) safely.

    ``stem`` names the entry (``stem.seal``, ``stem.lock``); ``cache_files()``
    lists the entry's numba files as they are now on disk. Returns
    ``(compile_(), rebuilt)`` where ``rebuilt`` says a damaged or unsealed entry
    was deleted first. A Ctrl-C meanwhile is raised once the entry is sealed
    (:func:`flowtex.interrupts.interrupts_deferred`: numba compiles a C-callable
    wrapper without the events that defer it elsewhere).
    """
    seal_path = stem.with_suffix(".seal")
    stem.parent.mkdir(parents=True, exist_ok=True)
    with interrupts_deferred(), locked(stem.with_suffix(".lock")):
        files = cache_files()
        rebuilt = False
        if files and not entry_ok(seal_path, files):
            for p in files:
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
            rebuilt = True
        result = compile_()
        now = seal_of(cache_files())
        if now:
            write_cache_file(seal_path, json.dumps(now).encode())
    return result, rebuilt
