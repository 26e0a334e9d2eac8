"""Helpers shared by the pattern and compliance fits: named, checked signals from a recording."""

from __future__ import annotations

import numpy as np

from ..errors import DataError
from ..io.atomic import write_json_atomic  # noqa: F401 -- re-exported for the fit modules
from ..io.recordings import Recording
from .inputs import check_plausible, recording_rate  # noqa: F401 -- the one rate rule, re-exported


def signal(rec: Recording, name: str, option: str, widths: tuple[int, ...]) -> np.ndarray:
    """Signal ``name`` as float64 (n,) if 1 is in ``widths`` and it is a scalar, else (n, width); checked finite."""
    if name not in rec.arrays:
        have = ", ".join(sorted(rec.arrays)) or "none"
        raise DataError(f"{rec.path}: no signal {name!r} (given by {option}); the recording has: {have}")
    arr = np.asarray(rec.arrays[name], dtype=np.float64)
    flat = arr.reshape(arr.shape[0], -1)
    if flat.shape[1] not in widths:
        want = " or ".join(map(str, widths))
        raise DataError(f"{rec.path}: signal {name!r} ({option}) has {flat.shape[1]} components per sample, expected {want}")
    if not np.all(np.isfinite(flat)):
        bad = int(np.argmax(~np.all(np.isfinite(flat), axis=1)))
        raise DataError(f"{rec.path}: signal {name!r} ({option}) has NaN or infinite values (first at sample {bad}); clean the recording")
    check_plausible(flat, f"{rec.path}: signal {name!r} ({option})", option)
    return flat[:, 0].copy() if flat.shape[1] == 1 and 1 in widths else flat
