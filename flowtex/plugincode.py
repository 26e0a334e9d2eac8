"""Identity of plugin code: what a plugin kernel's compiled code is filed and keyed by.

numba keys a cached function by its own file, and flowtex's own kernels by the
fingerprint of flowtex's whole source tree (:mod:`flowtex.cache`). A plugin's
kernel may call code from another file of its folder or package, and its
folder may be copied, moved or staged elsewhere; so a plugin's compiled code
is filed and keyed by a digest of its folder's (or installed package's)
sources, not by its path: an edit anywhere in them gives fresh machine code,
and a copy elsewhere finds what the first compiled.
"""

from __future__ import annotations

import functools
import hashlib
import itertools
import sys
from pathlib import Path
from typing import NamedTuple

__all__ = ["PACKAGE_FILES_MAX", "PLUGIN_CODE", "PluginCode", "hash_sources", "package_code_id", "plugin_code_id",
           "plugin_code_of", "register_plugin_package"]


def hash_sources(base: Path, paths: list[Path]) -> hashlib._Hash:
    """sha256 over each file's path relative to ``base``, its length and its bytes, in the order given."""
    h = hashlib.sha256()
    for path in paths:
        try:
            data = path.read_bytes()
        except OSError as exc:  # a file this process cannot read (and so does not run): its error stands for it
            data = f"unreadable: {exc.strerror}".encode()
        h.update(f"{path.relative_to(base).as_posix()}:{len(data)}:".encode())
        h.update(data)
    return h


PLUGIN_CODE = "__flowtex_plugin_code__"
"""Global of a plugin file's module (set by :func:`flowtex.registry.load_plugin_file` before the file runs): the
:func:`plugin_code_id` of its folder. Compiled code of the plugin is filed and keyed by it, not by where it lies."""


@functools.lru_cache(maxsize=64)
def _folder_digest(listing: tuple[tuple[str, int, int], ...], folder: str) -> str:
    """:func:`_hash_sources` of the files ``listing`` names (name, mtime, size: the cache key) in ``folder``."""
    base = Path(folder)
    return hash_sources(base, [base / name for name, _, _ in listing]).hexdigest()[:16]


def plugin_code_id(path: str | Path) -> str:
    """Digest of the names and contents of the ``.py`` files in the folder of the plugin file ``path``.

    A plugin folder is loaded as a whole, and a kernel may call code from another file of it: any edit in the folder
    gives its plugins a new id (fresh machine code), and a copy of the folder elsewhere (another checkout, a folder
    moved or staged and renamed) has the same id, so it finds the code compiled for the first.
    """
    folder = Path(path).resolve().parent
    try:
        listing = tuple(sorted((f.name, f.stat().st_mtime_ns, f.stat().st_size) for f in folder.glob("*.py")))
    except OSError:
        listing = ()
    return _folder_digest(listing, str(folder))


PACKAGE_FILES_MAX = 2000
"""An installed plugin package with more ``.py`` files than this is left to numba's own cache keys (hashing it at
every start would cost more than its compiles)."""

_PLUGIN_PACKAGES: set[str] = set()
"""Top-level packages of the installed plugin entry points named so far (:func:`register_plugin_package`)."""


def register_plugin_package(module: str) -> None:
    """Note that ``module`` (an installed entry point's module, ``pkg.nodes``) is about to be imported: the kernels of
    its top-level package are then filed and keyed by :func:`package_code_id`, as a plugin folder's are by
    :func:`plugin_code_id`, so that an edit to any file of an editable install (a helper a kernel calls) gives fresh
    machine code. Only the packages registered here: other numba code in the process keeps numba's own keys."""
    top = module.split(".")[0]
    if top != "flowtex":  # flowtex's own kernels are keyed by its whole source tree (flowtex.cache.source_fingerprint)
        _PLUGIN_PACKAGES.add(top)


@functools.lru_cache(maxsize=64)
def _package_listing(root: str) -> tuple[tuple[str, int, int], ...] | None:
    """(path within ``root``, mtime, size) of every ``.py`` file of the package folder ``root``; None if too many."""
    try:
        files = sorted(itertools.islice(Path(root).rglob("*.py"), PACKAGE_FILES_MAX + 1))  # stops at the cap
        if len(files) > PACKAGE_FILES_MAX:
            return None
        return tuple((f.relative_to(root).as_posix(), f.stat().st_mtime_ns, f.stat().st_size) for f in files)
    except OSError:
        return None


def _package_root(package: str) -> Path | None:
    """The folder of the imported top-level ``package`` (its first ``__path__`` entry); None for a plain module."""
    paths = list(getattr(sys.modules.get(package), "__path__", None) or [])
    return Path(paths[0]).resolve() if paths else None


def package_code_id(package: str) -> str | None:
    """Digest of the paths and contents of the ``.py`` files of the imported top-level ``package`` (None: not a folder
    package, or over :data:`PACKAGE_FILES_MAX` files). Computed once per process: a process runs what it imported."""
    root = _package_root(package)
    listing = None if root is None else _package_listing(str(root))
    return None if listing is None else _folder_digest(listing, str(root))


class PluginCode(NamedTuple):
    """Where a plugin kernel's compiled code is filed: ``plugins/<code>/<parts...>``, named ``<name>_<code>``."""

    code: str
    name: str
    """Stable name of the kernel's module: ``plugin_<file stem>`` in a plugin folder, the module's name in a package."""
    parts: tuple[str, ...]
    """Subfolders of the kernel's file within its package (none in a plugin folder)."""


def plugin_code_of(func: object) -> PluginCode | None:
    """The :class:`PluginCode` of a kernel's Python function: from a plugin folder's file (its :data:`PLUGIN_CODE`) or
    from a registered installed plugin package (:func:`register_plugin_package`); None for any other function."""
    glob = getattr(func, "__globals__", None) or {}
    file = getattr(getattr(func, "__code__", None), "co_filename", "")
    code = glob.get(PLUGIN_CODE)
    if isinstance(code, str):
        return PluginCode(code, f"plugin_{Path(file).stem}", ())
    module = str(glob.get("__name__", ""))
    top = module.split(".")[0]
    if top not in _PLUGIN_PACKAGES:
        return None
    root, code = _package_root(top), package_code_id(top)
    if root is None or code is None:
        return None
    try:
        parts = Path(file).resolve().parent.relative_to(root).parts
    except (OSError, ValueError):
        return None
    return PluginCode(code, module, parts)
