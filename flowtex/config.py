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
from pathlib import Path

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
    """Root of flowtex's on-disk cache (``$FLOWTEX_CACHE_DIR`` or ``~/.cache/flowtex``)."""
    root = os.environ.get(CACHE_ENV)
    if root:
        return Path(root)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "flowtex"


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
