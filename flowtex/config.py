"""Every ``FLOWTEX_*`` environment variable, read in one place (the lowest layer: nothing happens at import).

Each variable is read by one function here, when it is needed, so a test or a
parent process may set it at any time before the call. Other modules call
these functions and never read ``os.environ`` for a ``FLOWTEX_*`` name.

============================  =====================================================================
``FLOWTEX_CACHE_DIR``         root of the on-disk cache (default ``$XDG_CACHE_HOME/flowtex`` or
                              ``~/.cache/flowtex``): generated code, kernel wrappers, numba's files
``FLOWTEX_COMPILE``           default compile tier of :func:`flowtex.load_graph`: ``fused``
                              (unset), ``dispatch`` or ``auto`` (docs/engine.md)
``FLOWTEX_BACKGROUND``        ``0`` turns off background and prewarm compile processes
``FLOWTEX_CONTRACT``          ``0`` compiles kernels without FMA contraction
                              (:mod:`flowtex.dsp.fastmath`; read once, before kernels compile)
``FLOWTEX_PLUGINS``           extra plugin folders, ``os.pathsep``-separated
``FLOWTEX_DEBUG``             set: the CLI shows the traceback of an internal error
============================  =====================================================================
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import FlowtexError

CACHE_ENV = "FLOWTEX_CACHE_DIR"
COMPILE_ENV = "FLOWTEX_COMPILE"
BACKGROUND_ENV = "FLOWTEX_BACKGROUND"
CONTRACT_ENV = "FLOWTEX_CONTRACT"
PLUGIN_ENV = "FLOWTEX_PLUGINS"
DEBUG_ENV = "FLOWTEX_DEBUG"

OFF = ("0", "false", "no", "off")
"""Spellings that turn a switch off (case-insensitive, surrounding blanks ignored)."""


def _switch(name: str, default: bool = True) -> bool:
    value = os.environ.get(name)
    if value is None:
        return default
    return value.strip().lower() not in OFF


def cache_dir() -> Path:
    """Root of flowtex's on-disk cache (``$FLOWTEX_CACHE_DIR`` or ``~/.cache/flowtex``), created if missing.

    Raises :class:`~flowtex.errors.FlowtexError`, one line naming the variable, when no file can be created there.
    """
    root = os.environ.get(CACHE_ENV)
    if root:
        folder = Path(root)
        problem = _unusable(folder)
        if problem:
            raise FlowtexError(f"{CACHE_ENV}={root}: {problem}; point {CACHE_ENV} at a folder flowtex can write, or unset it "
                               "(the cache then lives in ~/.cache/flowtex)")
        return folder
    xdg = os.environ.get("XDG_CACHE_HOME")
    folder = (Path(xdg) if xdg else Path.home() / ".cache") / "flowtex"
    problem = _unusable(folder)
    if problem:
        raise FlowtexError(f"{folder}: the cache folder {problem}; set {CACHE_ENV} to a folder flowtex can write")
    return folder


def _unusable(folder: Path) -> str | None:
    """Why no cache can be kept in ``folder`` (a file, below a file, a dangling link, not creatable, read-only), or None.

    Checked by creating the folder (``mkdir -p``) and a file in it, as the cache will, not by asking ``os.access``.
    """
    if folder.is_symlink() and not folder.exists():
        return f"is a symbolic link to {os.readlink(folder)}, which does not exist"
    if folder.exists() and not folder.is_dir():
        return "is a file, not a folder"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot be created ({exc.strerror or exc}{' at ' + exc.filename if exc.filename else ''})"
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".probe.")
    except OSError as exc:
        return f"is not writable ({exc.strerror or exc})"
    os.close(fd)
    os.unlink(name)
    return None


def compile_tier() -> str:
    """``$FLOWTEX_COMPILE`` (unchecked; the compile service checks it), ``fused`` when unset or blank."""
    return os.environ.get(COMPILE_ENV, "fused").strip() or "fused"


def background_enabled() -> bool:
    """False when ``FLOWTEX_BACKGROUND`` turns background and prewarm compile processes off."""
    return _switch(BACKGROUND_ENV)


def contract_enabled() -> bool:
    """Whether kernels compile with FMA contraction (``FLOWTEX_CONTRACT``, default on)."""
    return _switch(CONTRACT_ENV)


def plugin_folders() -> list[Path]:
    """Folders named by ``$FLOWTEX_PLUGINS`` (``os.pathsep``-separated; empty items ignored), in order."""
    return [Path(item) for item in os.environ.get(PLUGIN_ENV, "").split(os.pathsep) if item]


def debug() -> bool:
    """True when ``FLOWTEX_DEBUG`` is set to anything non-empty (the CLI then re-raises internal errors)."""
    return bool(os.environ.get(DEBUG_ENV))


def worker_env(**switches: str) -> dict[str, str]:
    """This process's environment with ``switches`` (variable name -> value) set: what a compile worker inherits."""
    return {**os.environ, **switches}
