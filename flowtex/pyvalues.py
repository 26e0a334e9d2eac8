"""Values handed to flowtex from Python rather than read from a file: made plain, or refused in one line.

The in-memory API (``Node.processor``, :class:`flowtex.graph.builder.GraphBuilder`, ``Graph.run``) receives what
Python code computes: numpy scalars (``np.int64(4)`` from ``len`` of an array, ``np.float32`` from a float32
recording), 1-D arrays where a list is meant, ``pathlib.Path`` objects. :func:`plain` turns them into the values a
YAML file gives (``int``, ``float``, ``bool``, ``str``, ``list``), so one set of checks serves files and code alike.
:func:`float_signal` turns a signal (time first) into float64, refusing what would be silently mangled by the
conversion (complex values lose their imaginary part, timestamps become nanosecond counts) or cannot be converted
(strings, objects), with a :class:`~flowtex.errors.InputError` naming the signal.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from .errors import InputError
from .limits import MAX_PORT_VALUES, excerpt


def plain(value: Any) -> Any:
    """``value`` with numpy scalars as Python numbers, 0-D and 1-D numeric arrays (up to
    :data:`~flowtex.limits.MAX_PORT_VALUES` items) as numbers and lists, paths as strings, inside lists, tuples and
    dicts too (plain ones, not subclasses); anything else (a loaded model object, a wrong value to be refused by its check) unchanged."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        if value.ndim <= 1 and value.size <= MAX_PORT_VALUES and value.dtype.kind in "biuf":
            return value.tolist()
        return value
    if isinstance(value, os.PathLike):
        path = os.fspath(value)
        return path if isinstance(path, str) else value
    if type(value) in (list, tuple):  # exactly: a subclass (a mapping read with its positions) is kept as it is
        return [plain(v) for v in value]
    if type(value) is dict:
        return {k: plain(v) for k, v in value.items()}
    return value


def whole_count(what: str, value: Any, least: int) -> int:
    """``value`` as an int of at least ``least`` (numpy integers too), or :class:`InputError` naming ``what``."""
    value = plain(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise InputError(f"{what} must be an integer >= {least}, got {excerpt(value)}")
    return value


def positive_rate(what: str, value: Any) -> float:
    """``value`` as a positive, finite float of Hz (numpy numbers too), or :class:`InputError` naming ``what``."""
    rate = plain(value)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not (np.isfinite(rate) and rate > 0):
        raise InputError(f"{what} must be a positive number of Hz, got {excerpt(value)}")
    return float(rate)


_REFUSED_KINDS = {"c": "complex", "M": "timestamps (datetime64)", "m": "durations (timedelta64)",
                  "U": "text", "S": "bytes", "V": "structured records", "O": "Python objects"}
"""numpy dtype kinds a signal may not have, and what to call them."""


def float_signal(name: str, value: Any, what: str = "input") -> np.ndarray:
    """Signal ``value`` as a float64 array (a view when it already is one), or :class:`InputError` naming ``what
    name`` when its values are not real numbers (complex, text, timestamps, objects that are not numbers)."""
    arr = value if isinstance(value, np.ndarray) else None
    if isinstance(value, np.ma.MaskedArray):
        _refuse_masked(name, value, what)
        arr = value.data
    if arr is None:
        try:
            arr = np.asarray(value)
        except (ValueError, TypeError) as exc:  # ragged nested lists
            raise InputError(f"{what} {name!r}: not an array of numbers ({exc}); pass a numpy array, time first") from None
    kind = arr.dtype.kind
    if kind == "O":
        try:
            return np.asarray(arr, dtype=np.float64)
        except (ValueError, TypeError):
            pass
    if kind in _REFUSED_KINDS:
        fix = "; pass its real part (x.real) or magnitude (np.abs(x))" if kind == "c" else \
            "; pass numbers in the signal's unit (time is the row index: one row per tick)"
        raise InputError(f"{what} {name!r} holds {_REFUSED_KINDS[kind]} (dtype {arr.dtype}), not real numbers{fix}; "
                         f"got {excerpt(value)}")
    x = np.asarray(arr, dtype=np.float64)
    if (kind in "iu" and arr.dtype.itemsize >= 8) or (kind == "f" and arr.dtype.itemsize > 8):
        _refuse_rounded(name, arr, x, what)
    return x


def _bad_rows(bad: np.ndarray) -> np.ndarray:
    """Indices of the rows (ticks) of a boolean array with any True value (a 0-D array is one row)."""
    return np.flatnonzero(bad.reshape(bad.shape[0], -1).any(axis=1) if bad.ndim and bad.size else bad.reshape(-1))


def _refuse_masked(name: str, value: np.ma.MaskedArray, what: str) -> None:
    """Refuse a masked array with masked samples: converting it keeps the values under the mask as if they were data."""
    masked = _bad_rows(np.ma.getmaskarray(value))
    if masked.size:
        raise InputError(f"{what} {name!r} is a masked array with {masked.size} masked sample(s) (the first at index "
                         f"{masked[0]}), whose values would be used as data; pass x.filled(value), or x.filled(np.nan) "
                         "where NaN is handled (nonfinite= of Graph.run and Node.processor)")


def _refuse_rounded(name: str, arr: np.ndarray, x: np.ndarray, what: str) -> None:
    """Refuse 64-bit integers or extended floats that float64 cannot hold exactly: the run would use other numbers."""
    with np.errstate(invalid="ignore", over="ignore"):  # a value beyond the integer range casts back to another one
        changed = _bad_rows(x.astype(arr.dtype) != arr)
    if changed.size:
        raise InputError(f"{what} {name!r} (dtype {arr.dtype}) holds {changed.size} sample(s) that float64 cannot hold "
                         f"exactly (the first at index {changed[0]}); flowtex computes in float64: rescale the signal "
                         "(e.g. to its physical unit) or pass it as float64")
