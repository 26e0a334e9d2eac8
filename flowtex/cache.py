"""Where compiled code is cached, and when it is stale.

numba's ``cache=True`` checks only the modification time of the file that
defines a function, not of the functions it calls: edit a kernel in
``flowtex/dsp`` and a cached node kernel in ``flowtex/nodes`` that calls it
would keep the old machine code. flowtex therefore keys numba's cache folder
by a fingerprint of its whole source tree (every ``.py`` file's path, size and
modification time): any edit to flowtex gives a fresh folder, and unchanged
sources load instantly. Older folders are pruned (the newest few, and any used in the last hour, are kept). Setting ``NUMBA_CACHE_DIR``
yourself turns this off.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from pathlib import Path

from .dsp.fastmath import CONTRACT

CACHE_ENV = "FLOWTEX_CACHE_DIR"
KEEP_OLD = 3
IN_USE_S = 3600.0
"""A folder used this recently is never pruned: another checkout of flowtex (another source tree) may be compiling into it."""


def cache_dir() -> Path:
    """Root of flowtex's on-disk cache (``$FLOWTEX_CACHE_DIR`` or ``~/.cache/flowtex``)."""
    root = os.environ.get(CACHE_ENV)
    if root:
        return Path(root)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "flowtex"


def source_fingerprint() -> str:
    """Hash of the path, size and modification time of every flowtex source file, and of the FMA-contraction setting."""
    package = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        st = path.stat()
        h.update(f"{path.relative_to(package)}:{st.st_size}:{st.st_mtime_ns};".encode())
    h.update(f"contract={CONTRACT};".encode())  # flowtex.dsp.fastmath's setting changes the machine code
    return h.hexdigest()[:16]


def configure_numba_cache() -> str:
    """Point numba's cache at a folder for this source tree; returns the fingerprint.

    Must run before any module with ``@njit(cache=True)`` is imported.
    """
    fingerprint = source_fingerprint()
    if os.environ.get("NUMBA_CACHE_DIR"):
        return fingerprint
    import numba

    root = cache_dir() / "numba"
    folder = root / fingerprint
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return fingerprint  # read-only home: numba falls back to its own default
    numba.config.CACHE_DIR = str(folder)
    _prune(root, folder)
    return fingerprint


def _prune(root: Path, current: Path) -> None:
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
