"""Pattern files (docs/pattern-format.md): versioned JSON holding a patterned texture's features and IIR filters."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..limits import excerpt
from ..models.patterns import Pattern, filter_problem
from ..schema.core import Collector, check_unknown, get
from ..schema.datafiles import FEATURE, PATTERN, RATE_KEY
from .atomic import write_json_atomic
from .jsondoc import read_json_document

FORMAT_NAME = "flowtex-pattern"
FORMAT_VERSION = 1


def write_pattern(path: str | Path, pat: Pattern) -> Path:
    """Write ``pat`` (bit-exact floats) through a temporary file; returns the path."""
    doc = {
        "format": FORMAT_NAME, "version": FORMAT_VERSION, RATE_KEY: float(pat.sample_rate_hz),
        "axis": [float(v) for v in pat.axis], "origin_mm": [float(v) for v in pat.origin],
        "features": [{"position_mm": float(x), "amplitude": float(amp), "b": [float(v) for v in b], "a": [float(v) for v in a]}
                     for x, amp, b, a in zip(pat.positions_mm, pat.amplitudes, pat.b, pat.a, strict=True)],
        "metadata": pat.metadata,
    }
    return write_json_atomic(path, doc)


def _numbers(value: Any, where: str, path: Path, length: int | None = None) -> np.ndarray:
    if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise DataError(f"{path}: {where} must be a list of numbers")
    if length is not None and len(value) != length:
        raise DataError(f"{path}: {where} must have {length} numbers, got {len(value)}")
    return np.asarray(value, dtype=np.float64)


def read_pattern(path: str | Path) -> Pattern:
    """Read and check a pattern file; every problem raises DataError naming the file and the key."""
    path = Path(path).expanduser()
    doc = read_json_document(path, "pattern", FORMAT_NAME, (FORMAT_VERSION,))
    c = Collector(str(path))
    check_unknown(c, doc, PATTERN)
    c.raise_first_as_data_error()
    rate, key = get(doc, PATTERN, RATE_KEY)
    if not isinstance(rate, (int, float)) or isinstance(rate, bool) or not rate > 0:
        raise DataError(f"{path}: key {key or RATE_KEY!r} must be a positive number of Hz, got {excerpt(None if key is None else rate)}")
    axis = _numbers(doc.get("axis"), "key 'axis'", path, 3)
    norm = float(np.linalg.norm(axis))
    if not norm > 0:
        raise DataError(f"{path}: key 'axis' must be a non-zero direction")
    origin = _numbers(doc.get("origin_mm"), "key 'origin_mm'", path, 3)
    feats = doc.get("features")
    if not isinstance(feats, list) or not feats:
        raise DataError(f"{path}: key 'features' must be a non-empty list of features")
    xs, amps, bs, as_ = [], [], [], []
    for i, f in enumerate(feats):
        where = f"features[{i}]"
        if not isinstance(f, dict):
            raise DataError(f"{path}: {where} must be an object with position_mm, amplitude, b, a")
        check_unknown(c, f, FEATURE, where=where)
        c.raise_first_as_data_error()
        for key in ("position_mm", "amplitude"):
            v = f.get(key)
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                raise DataError(f"{path}: {where}.{key} must be a number, got {excerpt(v)}")
        b = _numbers(f.get("b"), f"{where}.b", path)
        a = _numbers(f.get("a"), f"{where}.a", path)
        problem = filter_problem(b, a)
        if problem:
            raise DataError(f"{path}: {where}: {problem}")
        xs.append(float(f["position_mm"]))
        amps.append(float(f["amplitude"]))
        bs.append(b)
        as_.append(a)
    order = np.argsort(xs, kind="stable")
    meta = doc.get("metadata", {})
    return Pattern(float(rate), axis / norm, origin, np.asarray(xs)[order], np.asarray(amps)[order],
                   [bs[i] for i in order], [as_[i] for i in order], meta if isinstance(meta, dict) else {})
