"""Turn generated source into numba functions, cached on disk.

The source is written once to ``<cache>/codegen/g_<hash>.py``, where the hash
covers the source text, the identity and source of every kernel it calls,
and the numba and flowtex versions. numba's own ``cache=True`` then stores the
machine code, filed by that file name and stamped with its contents
(:data:`flowtex.cache.GENERATED`), so a second process building a graph of the
same structure (whatever its parameter values or model files) loads instead of
compiling, from this cache or from a copy of it elsewhere.
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import sys
import weakref
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numba

from ..cache import GENERATED, cache_dir, source_fingerprint, write_cache_file
from ..plugincode import plugin_code_of


def kernel_fingerprint(kernel: Callable) -> str:
    """Identity of a jitted kernel: where it lives and its source text.

    A plugin file's kernel lives in its file, named by the file and its folder's code id
    (:func:`flowtex.plugincode.plugin_code_of`), not by the folder's path: a copy of the folder finds the generated code
    compiled for the first, and an edit anywhere in the folder (a helper the kernel calls) gives new code. An
    installed plugin package's kernel is named by its module and its package's code id, for the same reason.
    """
    func = getattr(kernel, "py_func", kernel)
    found = plugin_code_of(func)
    module = func.__module__ if found is None else f"{found.name}_{found.code}"
    return f"{module}.{func.__qualname__}:{_source_digest(func)}"


_SOURCE_DIGESTS: weakref.WeakKeyDictionary[Callable, str] = weakref.WeakKeyDictionary()
"""sha256 of each kernel function's source text, by function object."""


def _source_digest(func: Callable) -> str:
    """sha256 of ``func``'s source text, read once per function object.

    A function object runs the code it was defined with, so its source is read the first time it is asked for and
    kept: reading it again (``inspect.getsource`` tokenizes the file from the definition on) cost every graph build
    once per kernel and per wrapper, and a file edited after the import would give the new text for the old code.
    An edited plugin file is imported again (a new function object), and is read then."""
    digest = _SOURCE_DIGESTS.get(func)
    if digest is None:
        try:
            source = inspect.getsource(func)
        except (OSError, TypeError):
            source = repr(func.__code__.co_code)
        digest = _SOURCE_DIGESTS[func] = hashlib.sha256(source.encode()).hexdigest()
    return digest


_LOADED: dict[str, ModuleType] = {}


def generated_digest(source: str, kernels: dict[str, Callable], extra_key: str = "") -> tuple[str, Path]:
    """Cache key of generated ``source`` calling ``kernels``, and the folder its files go to."""
    from ..version import __version__

    h = hashlib.sha256()
    h.update(source.encode())
    for name in sorted(kernels):
        h.update(f"{name}={kernel_fingerprint(kernels[name])}".encode())
    h.update(f"numba={numba.__version__};flowtex={__version__};tree={source_fingerprint()};{extra_key}".encode())
    return h.hexdigest()[:24], cache_dir() / "codegen"


def load_generated(source: str, kernels: dict[str, Callable], extra_key: str = "") -> ModuleType:
    """Import the generated ``source`` with ``kernels`` as its globals."""
    digest, folder = generated_digest(source, kernels, extra_key)
    if digest in _LOADED:
        return _LOADED[digest]
    module = import_source(folder / f"g_{digest}.py", source, kernels, f"flowtex_generated_{digest}")
    _LOADED[digest] = module
    return module


def import_source(path: Path, source: str, namespace: dict[str, Any], mod_name: str) -> ModuleType:
    """Write ``source`` to ``path`` (atomically, only if it differs) and import it as ``mod_name`` with ``namespace``
    added to its globals.

    The module is marked :data:`~flowtex.cache.GENERATED`: numba files its functions' cache entries by ``path``'s
    name alone, so that name must be a digest of everything the code depends on (a different source under the same
    name is still never given the old machine code: entries are stamped with the file's contents)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != source:
        write_cache_file(path, source.encode())
    spec = importlib.util.spec_from_file_location(mod_name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    module.__dict__.update(namespace)
    module.__dict__[GENERATED] = True
    sys.modules[mod_name] = module
    spec.loader.exec_module(module)
    return module
