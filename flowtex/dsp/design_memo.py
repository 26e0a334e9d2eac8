"""Filter designs remembered on disk, so that a warm run need not import ``scipy.signal``.

A filter design (a Butterworth section list, for example) is a pure function of its
arguments and of scipy's version, and it is computed at every graph build. With
scipy 1.17, ``import scipy.signal`` alone takes most of a second (it rewrites the
docstring of each of its functions at import), more than the rest of a warm
``flowtex run``. :func:`remembered` keeps scipy's exact output in
``<cache>/designs/`` (the cache folder of :func:`flowtex.config.cache_dir`), one
``.npz`` file per design (written by :func:`flowtex.cache.write_cache_file`), named by a hash of the design's name, its arguments and
scipy's version, and holding that key beside the coefficients. A file that does
not load, holds another key, or holds anything but a finite float64 array of the
shape the caller expects is ignored and written again; a cache folder that cannot
be used (unwritable, or a bad ``FLOWTEX_CACHE_DIR``) only costs the import: the
memo never makes a design fail. The coefficients returned are the ones scipy
computed, bit for bit, so outputs do not depend on whether the memo was warm.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..cache import cache_dir, write_cache_file
from ..errors import FlowtexError

FOLDER = "designs"


def _key(name: str, args: tuple) -> str:
    import scipy

    return f"{name}{args!r} scipy {scipy.__version__}"


def _path(key: str) -> Path | None:
    try:
        root = cache_dir()
    except FlowtexError:  # reported by the compile cache, which needs the folder; a design does not
        return None
    return root / FOLDER / (hashlib.sha256(key.encode()).hexdigest()[:32] + ".npz")


def _load(path: Path, key: str, shape: tuple[int, ...]) -> np.ndarray | None:
    try:
        with np.load(path, allow_pickle=False) as f:
            if str(f["key"]) != key:
                return None
            coef = f["coef"]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    if coef.dtype != np.float64 or coef.shape != shape or not np.all(np.isfinite(coef)):
        return None
    return coef


def _store(path: Path, key: str, coef: np.ndarray) -> None:
    """Write through the cache's atomic writer; give up quietly if the folder refuses."""
    buf = io.BytesIO()
    np.savez(buf, key=np.array(key), coef=coef)
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        write_cache_file(path, buf.getvalue())


def remembered(name: str, args: tuple, shape: tuple[int, ...], design: Callable[[], np.ndarray]) -> np.ndarray:
    """``design()`` (a float64 array of ``shape``), read from the memo when an earlier call with the same ``name``,
    ``args`` (a tuple with an exact ``repr``: numbers and strings) and scipy version stored it; computed and stored
    otherwise (and only computed when the cache folder cannot be used)."""
    key = _key(name, args)
    path = _path(key)
    coef = None if path is None else _load(path, key, shape)
    if coef is None:
        coef = np.ascontiguousarray(design(), dtype=np.float64)
        if coef.shape != shape:
            raise ValueError(f"design {name}{args!r} returned shape {coef.shape}, expected {shape}")
        if path is not None:
            _store(path, key, coef)
    return coef
