"""Where compiled code is cached, and when it is stale.

numba's ``cache=True`` checks only the file that defines a function (its
modification time, or its contents in newer numba), not the files of the
functions it calls: edit a kernel in
``flowtex/dsp`` and a cached node kernel in ``flowtex/nodes`` that calls it
would keep the old machine code. flowtex therefore keys numba's cache folder
by a fingerprint of its whole source tree (every ``.py`` file's path and
contents): any edit to flowtex gives a fresh folder, and unchanged sources load
instantly. Inside that folder, a kernel's entries are filed by its module's path
within the package (:func:`file_by_package_path`), not by where the package lies
on disk, so another checkout or a reinstall of the same sources (a fresh clone,
a CI run, a branch switched away and back) finds the compiled code of the first.
The modules flowtex generates (the fused tier's graphs, the live tick, the
dispatch tier's driver and wrappers: :data:`GENERATED`) are filed under
``generated/`` by their file's name, a digest of everything their code depends
on, so a cache copied or moved elsewhere (a CI cache restored in another
workspace, a cache baked into a container image) loads them too. Every entry
these locators file is stamped with its source file's contents, never its time.
A process compiling with numba's bounds checking (``NUMBA_BOUNDSCHECK=1``: the
runtime checks of ``flowtex plugin check``) uses a sibling tree of folders
(:func:`numba_cache_folder`), filed and guarded the same way.
Setting ``NUMBA_CACHE_DIR`` yourself turns this off.

numba binds a function's cache folder when the function is decorated, so
:func:`configure_numba_cache` runs just before the first module holding
kernels is imported (the packages and modules with ``@njit(cache=True)`` call
it first), never at ``import flowtex``. Older folders are pruned by
:func:`prune_numba_cache`, which the compile service calls once, at the first
compile of a process (the newest few, and any used in the last hour, are kept).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import secrets
import shutil
import time
from pathlib import Path

from .config import CACHE_ENV, cache_dir, contract_enabled
from .errors import FlowtexError
from .interrupts import guard_compiles
from .plugincode import PLUGIN_CODE, hash_sources, plugin_code_id, plugin_code_of

__all__ = ["CACHE_ENV", "GENERATED", "GENERATED_FOLDER", "cache_dir", "configure_numba_cache", "file_by_package_path", "guard_numba_cache",
           "numba_cache_folder", "prune_cache_tree", "prune_numba_cache", "shares_compiled_code", "source_fingerprint",
           "write_cache_file"]

KEEP_OLD = 3
IN_USE_S = 3600.0
"""A folder used this recently is never pruned: another checkout of flowtex (another source tree) may be compiling into it."""


PACKAGE = Path(__file__).resolve().parent
"""The flowtex package folder whose sources the fingerprint covers."""


@functools.lru_cache(maxsize=1)
def source_fingerprint() -> str:
    """Hash of the path (within the package) and contents of every flowtex source file, and of the FMA-contraction
    setting: the same for every copy of the same sources, wherever it lies and whenever it was written.

    Computed once per process (the tree a process runs is the one it imported).
    """
    h = hash_sources(PACKAGE, sorted(PACKAGE.rglob("*.py")))
    h.update(f"contract={contract_enabled()};".encode())  # flowtex.dsp.fastmath's setting changes the machine code
    return h.hexdigest()[:16]


def numba_cache_folder(boundscheck: bool = False) -> Path:
    """The numba cache folder of this source tree: ``numba/<fingerprint>`` in :func:`cache_dir`, or
    ``boundscheck/<fingerprint>`` for code compiled with numba's bounds checking (``NUMBA_BOUNDSCHECK=1``, as
    ``flowtex plugin check`` runs kernels), which numba's cache keys do not tell apart: bounds-checked machine code
    must never be loaded by a normal run. Both are filed and guarded alike (:func:`configure_numba_cache`)."""
    return cache_dir() / ("boundscheck" if boundscheck else "numba") / source_fingerprint()


_CONFIGURED: list[Path] = []
"""The numba cache folder this process chose (empty until configured, or when the user's NUMBA_CACHE_DIR rules)."""
_DONE: list[bool] = []


def configure_numba_cache() -> str:
    """Point numba's cache at a folder for this source tree (once per process); returns the fingerprint.

    Runs before any flowtex module with ``@njit(cache=True)`` decorates its kernels, so it is also where a Ctrl-C
    during numba's compiles starts being kept for every caller (:func:`flowtex.interrupts.guard_compiles`).
    """
    fingerprint = source_fingerprint()
    if _DONE:
        return fingerprint
    _DONE.append(True)
    guard_compiles()
    if os.environ.get("NUMBA_CACHE_DIR"):
        return fingerprint
    import numba

    guard_numba_cache()
    file_by_package_path()
    try:
        folder = numba_cache_folder(boundscheck=bool(numba.config.BOUNDSCHECK))
        folder.mkdir(parents=True, exist_ok=True)
    except (OSError, FlowtexError):
        return fingerprint  # no usable cache folder: numba falls back to its own default; the verbs say why (cache_dir)
    numba.config.CACHE_DIR = str(folder)
    _CONFIGURED.append(folder)
    return fingerprint


PLUGIN_KEEP_S = 30 * 86400.0
"""A plugin code folder (``plugins/<code id>``) in which nothing was written for this long is pruned: every edit of a
plugin folder gives a new code id, so a plugin author's edits would otherwise pile up. Code still in use is compiled
once more."""


def prune_numba_cache() -> None:
    """:func:`prune_cache_tree` of the numba cache folder this process chose (none: nothing to do)."""
    if _CONFIGURED:
        prune_cache_tree(_CONFIGURED[0])


def prune_cache_tree(current: Path) -> None:
    """Delete the siblings of the numba cache folder ``current`` (one per flowtex source tree) but the newest few, and
    any used in the last hour (another checkout may be compiling into it), and the plugin code folders of ``current``
    left unwritten for :data:`PLUGIN_KEEP_S`."""
    _prune_plugin_code(current / "plugins", time.time() - PLUGIN_KEEP_S)
    root = current.parent
    try:
        others = sorted((p for p in root.iterdir() if p.is_dir() and p != current), key=lambda p: p.stat().st_mtime)
    except OSError:
        return
    for old in others[:-KEEP_OLD] if len(others) > KEEP_OLD else []:
        _remove_unused_since(old, time.time() - IN_USE_S)


def _remove_unused_since(folder: Path, before: float) -> None:
    """Delete ``folder`` if it and every file directly in it were last written before ``before`` (seconds)."""
    try:
        if max([folder.stat().st_mtime] + [c.stat().st_mtime for c in folder.iterdir()]) >= before:
            return
    except OSError:
        return
    shutil.rmtree(folder, ignore_errors=True)


def _prune_plugin_code(folder: Path, before: float) -> None:
    """Delete the subfolders of ``folder`` whose newest file (or the folder itself) was written before ``before``."""
    try:
        codes = [p for p in folder.iterdir() if p.is_dir()]
    except OSError:
        return
    for code in codes:
        _remove_unused_since(code, before)


SEAL_SUFFIX = ".sha256"
"""Beside each numba index (``.nbi``) and data (``.nbc``) file: the sha256 of its bytes, written after numba wrote it."""


def folder_in_package(py_file: str) -> Path | None:
    """The folder of ``py_file`` relative to the flowtex package, or None for a file outside it (a plugin's)."""
    try:
        return Path(py_file).resolve().parent.relative_to(PACKAGE)
    except (OSError, ValueError):
        return None


def shares_compiled_code(compiled_from: str | Path, func: object) -> bool:
    """True when machine code whose debug locations name the file ``compiled_from`` may be the code of ``func``'s file.

    Compiled code is shared by copies (:func:`file_by_package_path`): a location baked into it (a kernel's ``raise``)
    names the copy that compiled it, which may be another checkout of flowtex or another copy of a plugin folder,
    perhaps deleted since. The same file, the same file within the flowtex package, or a file of the same name in a
    plugin folder with the same code id (or one no longer there to check) counts.
    """
    code = getattr(func, "__code__", None)
    if code is None:
        return False
    here, there = Path(code.co_filename).resolve(), Path(compiled_from).resolve()
    if here == there:
        return True
    inside = folder_in_package(str(here))
    if inside is not None:
        return there.parent.parts[-len(inside.parts) - 1:] == ("flowtex", *inside.parts) and there.name == here.name
    found = plugin_code_of(func)
    if found is None or there.name != here.name:
        return False
    if isinstance(getattr(func, "__globals__", {}).get(PLUGIN_CODE), str):  # a plugin folder's file
        return not there.exists() or plugin_code_id(there) == found.code
    tail = len(found.parts) + 2  # an installed package's file: the same package folder, subfolders and file name
    return there.parts[-tail:] == here.parts[-tail:]


GENERATED = "__flowtex_generated__"
"""Global of a module flowtex generated and imported from its cache (set by :func:`flowtex.graph.jit.import_source`
before the module runs). Its file's name is a digest of its source and of everything its code calls, so numba's
entries of its functions are filed by that name under ``generated/`` of the numba cache folder
(:func:`file_by_package_path`), not by the folder the cache lies in."""

GENERATED_FOLDER = "generated"
"""Subfolder of the numba cache folder holding the entries of :data:`GENERATED` modules."""


def is_generated(py_func: object) -> bool:
    """True when ``py_func`` is defined in a module flowtex generated (:data:`GENERATED`)."""
    return getattr(py_func, "__globals__", {}).get(GENERATED) is True


def source_stamp(py_file: str) -> bytes:
    """numba's source stamp of an entry filed by :func:`file_by_package_path`: the sha256 of the source file's bytes
    (what numba 0.68 stamps too; numba 0.67 and older stamped the file's modification time and size, which a copy
    changes). Hashed once per file version in a process (many kernels share a file).

    numba drops an entry whose stamp differs from its source's and compiles again, and keys an entry only by its
    function's bytecode, which leaves out the constants: the stamp is what keeps an edited file from loading the
    machine code of the old one."""
    st = os.stat(py_file)
    return _content_hash(py_file, (st.st_ino, st.st_mtime_ns, st.st_ctime_ns, st.st_size))


@functools.lru_cache(maxsize=512)
def _content_hash(path: str, version: tuple[int, ...]) -> bytes:
    """sha256 of the file ``path``; ``version`` (inode, modification and change times, size) only keys the memo: a file
    written again, or replaced, is hashed again."""
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).digest()


def file_by_package_path() -> None:
    """Make numba file the cache entries of flowtex's own kernels under ``flowtex/<subpackage>`` of its cache folder,
    and those of plugin files and registered plugin packages under ``plugins/<code id>`` (numba's own locator names the
    folder after the absolute path of the source, so every checkout, and every copy of a plugin folder, compiled anew,
    and keys an entry by its own file only, so an edited helper in another file of a package left stale code).

    Generated modules (:data:`GENERATED`) are filed under ``generated/`` by their file's name (a digest of their
    contents), so a copied or moved cache loads them: numba's locator named their folder after the cache's own path.

    Entries stay keyed by the content hash of the source file (:func:`source_stamp`), the folder by
    :func:`source_fingerprint`, and a plugin's subfolder by :func:`plugin_code_id`: two copies share an entry only
    when their sources are the same. Other numba functions outside the package keep numba's own locators. Once per
    process; numba's ``NUMBA_CACHE_LOCATOR_CLASSES``, when set, still rules.
    """
    import numba
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)  # numba >= 0.62 / older
    numba_locator = getattr(caching, "UserProvidedCacheLocator", None) or getattr(caching, "_UserProvidedCacheLocator", None)
    if impl is None or numba_locator is None or not isinstance(getattr(impl, "_locator_classes", None), list):
        return  # another numba layout: its own locators (every checkout compiles anew, nothing is wrong)
    if any(getattr(cls, "flowtex_package", False) for cls in impl._locator_classes):
        return

    class PackageCacheLocator(numba_locator):  # type: ignore[misc, valid-type]
        """numba's locator for ``numba.config.CACHE_DIR``, with a subfolder named by the path within flowtex, the plugin
        code id or ``generated/``, and a stamp of the source's contents."""

        flowtex_package = True

        @classmethod
        def get_suitable_cache_subpath(cls, py_file: str) -> str:
            inside = folder_in_package(py_file)
            return os.path.join("flowtex", *inside.parts) if inside is not None else super().get_suitable_cache_subpath(py_file)

        def __init__(self, py_func, py_file):  # type: ignore[no-untyped-def]
            super().__init__(py_func, py_file)
            found = plugin_code_of(py_func)
            if is_generated(py_func):
                self._cache_path = os.path.join(numba.config.CACHE_DIR, GENERATED_FOLDER)
            elif found is not None:
                self._cache_path = os.path.join(numba.config.CACHE_DIR, "plugins", found.code, *found.parts)

        def get_source_stamp(self) -> bytes:
            return source_stamp(self._py_file)

        @classmethod
        def from_function(cls, py_func, py_file):  # type: ignore[no-untyped-def]
            ours = folder_in_package(py_file) is not None or plugin_code_of(py_func) is not None or is_generated(py_func)
            return super().from_function(py_func, py_file) if ours else None

    impl._locator_classes = [PackageCacheLocator, *impl._locator_classes]


def guard_numba_cache() -> None:
    """Make numba's per-function cache (the node and dsp kernels' ``cache=True``) detect damaged entries and rebuild them.

    numba trusts its files: an empty (disk full), truncated (crash) or flipped-byte ``.nbi``/``.nbc`` file raises
    ``EOFError``/``UnpicklingError``/``UnicodeDecodeError`` on every later load, or loads damaged machine code. Each
    file numba saves gets a seal (:data:`SEAL_SUFFIX`); a file whose bytes differ from its seal, or that has none,
    is not loaded: the entry's files are deleted and numba compiles the kernel again. Any other failure while loading
    an entry is handled the same way (a cache is never worth an error).
    """
    from numba.core import caching

    if getattr(caching.Cache, "_flowtex_guarded", False):
        return
    files = caching.IndexDataCacheFile
    load_overload, load_index, save_index = caching.Cache.load_overload, files._load_index, files._save_index
    load_data, save_data = files._load_data, files._save_data

    def guarded_load_overload(self, sig, target_context):  # type: ignore[no-untyped-def]
        try:
            return load_overload(self, sig, target_context)
        except Exception:  # damaged entry: forget it, numba compiles and saves it again
            _discard(self._cache_file)
            return None

    def sealed_load_index(self):  # type: ignore[no-untyped-def]
        if os.path.exists(self._index_path) and not _sealed(self._index_path):
            _discard(self)
            return {}
        return load_index(self)

    def sealed_save_index(self, overloads):  # type: ignore[no-untyped-def]
        save_index(self, overloads)
        _seal(self._index_path)

    def sealed_load_data(self, name):  # type: ignore[no-untyped-def]
        if not _sealed(self._data_path(name)):
            raise ValueError(f"numba cache file {self._data_path(name)} does not match its seal")
        return load_data(self, name)

    def sealed_save_data(self, name, data):  # type: ignore[no-untyped-def]
        save_data(self, name, data)
        _seal(self._data_path(name))

    caching.Cache.load_overload = guarded_load_overload
    files._load_index, files._save_index = sealed_load_index, sealed_save_index
    files._load_data, files._save_data = sealed_load_data, sealed_save_data
    caching.Cache._flowtex_guarded = True


def write_cache_file(path: str | Path, data: bytes) -> None:
    """Replace the cache file ``path`` by ``data`` atomically: a temporary file beside it (created exclusively, mode
    from the umask), renamed over it, and removed on any failure, so another process reading the entry sees the old
    file or the new one, never half of one, and nothing is left behind. The cache's one writer (user outputs go
    through :func:`flowtex.io.atomic.atomic_output`, which also guards inputs and special files). Raises OSError."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "xb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _digest(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def _seal(path: str) -> None:
    with contextlib.suppress(OSError):
        write_cache_file(path + SEAL_SUFFIX, _digest(path).encode())


def _sealed(path: str) -> bool:
    try:
        with open(path + SEAL_SUFFIX) as fh:
            return fh.read().strip() == _digest(path)
    except OSError:
        return False


def _discard(cache_file: object) -> None:
    """Delete an entry's index, its data files and their seals (another process may be doing the same)."""
    index = getattr(cache_file, "_index_path", None)
    if not index:
        return
    folder, stem = os.path.split(index[: -len(".nbi")])
    try:
        names = [n for n in os.listdir(folder) if n.startswith(stem + ".")]
    except OSError:
        return
    for n in names:
        with contextlib.suppress(OSError):
            os.unlink(os.path.join(folder, n))
