"""Read and write tap library files (JSON, format ``flowtex-tap-library`` version 1; docs/tap-library.md).

Every problem with a file raises :class:`flowtex.errors.DataError` naming the
file, the field (``taps[2].speed``) and the fix.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..limits import excerpt
from ..models.taps import TapLibrary
from ..schema.core import Collector, check_keys, check_unknown, get
from ..schema.datafiles import RATE_KEY, TAP, TAP_LIBRARY
from .jsondoc import read_json_document

FORMAT = "flowtex-tap-library"
VERSION = 1
SPEED_UNIT = "mm/s"
ACCEL_UNIT = "m/s^2"


def _number(path: Path, field: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DataError(f"{path}: field {field!r}: expected a finite number, got {excerpt(value)}")
    return float(value)


def read_tap_library(path: str | Path) -> TapLibrary:
    """Load a tap library file; see docs/tap-library.md for the format.

    Transients shorter than the longest are padded with zeros at the end.
    """
    path = Path(path)
    doc = read_json_document(path, "tap library", FORMAT, (VERSION,))
    c = Collector(str(path))
    check_unknown(c, doc, TAP_LIBRARY)
    c.raise_first_as_data_error()
    for key, unit in (("speed_unit", SPEED_UNIT), ("acceleration_unit", ACCEL_UNIT)):
        if key in doc and doc[key] != unit:
            raise DataError(f"{path}: field {key!r}: must be {unit!r}, got {doc[key]!r} (convert the data to {unit})")
    value, spelling = get(doc, TAP_LIBRARY, RATE_KEY)
    if spelling is None:
        raise DataError(f"{path}: {TAP_LIBRARY.keys[RATE_KEY].missing}")
    rate = _number(path, spelling, value)
    if rate <= 0:
        raise DataError(f"{path}: field {spelling!r}: must be > 0, got {rate:g}")
    name = doc.get("name", path.stem)
    if not isinstance(name, str):
        raise DataError(f"{path}: field 'name': expected a string, got {name!r}")
    taps = doc.get("taps")
    if not isinstance(taps, list) or not taps:
        raise DataError(f"{path}: field 'taps': expected a non-empty list of {{\"speed\": mm/s, \"acceleration\": [m/s^2, ...]}}")
    speeds: list[float] = []
    series: list[np.ndarray] = []
    for k, tap in enumerate(taps):
        where = f"taps[{k}]"
        if not isinstance(tap, dict):
            raise DataError(f"{path}: field {where!r}: expected an object with 'speed' and 'acceleration'")
        check_keys(c, tap, TAP, where=where)
        c.raise_first_as_data_error()
        speed = _number(path, f"{where}.speed", tap["speed"])
        if speed <= 0:
            raise DataError(f"{path}: field '{where}.speed': incoming speed must be > 0 mm/s, got {speed:g}")
        acc = tap["acceleration"]
        if not isinstance(acc, list) or not acc:
            raise DataError(f"{path}: field '{where}.acceleration': expected a non-empty list of numbers (m/s^2)")
        values = np.array([_number(path, f"{where}.acceleration[{i}]", a) for i, a in enumerate(acc)])
        if speed in speeds:
            other = speeds.index(speed)
            raise DataError(f"{path}: field '{where}.speed': speed {speed:g} mm/s repeats taps[{other}].speed; average or drop one of them")
        speeds.append(speed)
        series.append(values)
    length = max(len(a) for a in series)
    order = np.argsort(speeds)
    tr = np.zeros((len(series), length))
    for row, k in enumerate(order):
        tr[row, :len(series[k])] = series[k]
    return TapLibrary(np.asarray(speeds)[order], tr, rate, name)


def write_tap_library(path: str | Path, lib: TapLibrary, notes: str = "") -> Path:
    """Write ``lib`` as a version-1 tap library file (JSON, numbers with full float64 precision)."""
    path = Path(path)
    doc: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "name": lib.name,
        RATE_KEY: lib.sample_rate_hz,
        "speed_unit": SPEED_UNIT,
        "acceleration_unit": ACCEL_UNIT,
    }
    if notes:
        doc["notes"] = notes
    doc["taps"] = [{"speed": float(v), "acceleration": [float(a) for a in row]} for v, row in zip(lib.speeds, lib.transients, strict=True)]
    from .atomic import write_text_atomic

    return write_text_atomic(path, json.dumps(doc, indent=1) + "\n")
