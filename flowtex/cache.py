"""Where compiled code is cached, and when it is stale.

numba's ``cache=True`` checks only the modification time of the file that
defines a function, not of the functions it calls: edit a kernel in
``flowtex/dsp`` and a cached node kernel in ``flowtex/nodes`` that calls it
would keep the old machine code. flowtex therefore keys numba's cache folder
by a fingerprint of its whole source tree (every ``.py`` file's path, size and
modification time): any edit to flowtex gives a fresh folder, and unchanged
sources load instantly. Setting ``NUMBA_CACHE_DIR`` yourself turns this off.

numba binds a function's cache folder when the function is decorated, so
:func:`configure_numba_cache` runs just before the first module holding
kernels is imported (the packages and modules with ``@njit(cache=True)`` call
it first), never at ``import flowtex``. Older folders are pruned by
:func:`prune_numba_cache`, which the compile service calls once, at the first
compile of a process (the newest few, and any used in the last hour, are kept).
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import time
from pathlib import Path

from .config import CACHE_ENV, cache_dir, contract_enabled

__all__ = ["CACHE_ENV", "cache_dir", "configure_numba_cache", "prune_numba_cache", "source_fingerprint"]

KEEP_OLD = 3
IN_USE_S = 3600.0
"""A folder used this recently is never pruned: another checkout of flowtex (another source tree) may be compiling into it."""


@functools.lru_cache(maxsize=1)
def source_fingerprint() -> str:
    """Hash of the path, size and modification time of every flowtex source file, and of the FMA-contraction setting.

    Computed once per process (the tree a process runs is the one it imported).
    """
    package = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        st = path.stat()
        h.update(f"{path.relative_to(package)}:{st.st_size}:{st.st_mtime_ns};".encode())
    h.update(f"contract={contract_enabled()};".encode())  # flowtex.dsp.fastmath's setting changes the machine code
    return h.hexdigest()[:16]


_CONFIGURED: list[Path] = []
"""The numba cache folder this process chose (empty until configured, or when the user's NUMBA_CACHE_DIR rules)."""
_DONE: list[bool] = []


def configure_numba_cache() -> str:
    """Point numba's cache at a folder for this source tree (once per process); returns the fingerprint.

    Runs before any flowtex module with ``@njit(cache=True)`` decorates its kernels.
    """
    fingerprint = source_fingerprint()
    if _DONE:
        return fingerprint
    _DONE.append(True)
    if os.environ.get("NUMBA_CACHE_DIR"):
        return fingerprint
    import numba

    folder = cache_dir() / "numba" / fingerprint
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return fingerprint  # read-only home: numba falls back to its own default
    numba.config.CACHE_DIR = str(folder)
    _CONFIGURED.append(folder)
    return fingerprint


def prune_numba_cache() -> None:
    """Delete numba cache folders of older source trees (kept: the newest few, and any used in the last hour)."""
    if not _CONFIGURED:
        return
    current = _CONFIGURED[0]
    root = current.parent
    try:
        others = sorted((p for p in root.iterdir() if p.is_dir() and p != current), key=lambda p: p.stat().st_mtime)
    except OSError:
        return
    now = time.time()
    for old in others[:-KEEP_OLD] if len(others) > KEEP_OLD else []:
        try:
            if now - max([old.stat().st_mtime] + [c.stat().st_mtime for c in old.iterdir()]) < IN_USE_S:
                continue
        except OSError:
            continue
        shutil.rmtree(old, ignore_errors=True)
