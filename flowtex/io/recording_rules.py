"""What makes a recording a recording: the checks every format (npz, CSV, HDF5) passes through after reading.

Rules (``docs/recordings.md``), each refused with one line naming the file,
the signal and the fix:

* at least one signal; every signal numeric and real (complex or text is refused,
  never silently cast);
* time is the first axis: a signal is ``(n,)`` or ``(n, k, ...)``; one whose
  per-sample width exceeds both :data:`~flowtex.limits.MAX_SIGNAL_WIDTH` and
  its number of samples looks transposed (a ``(3, n)`` array) and is refused;
* at least 2 samples (an empty or one-sample recording has no signal to process);
* every signal has the same number of samples;
* a 1-D signal named ``time`` increases strictly, with no step longer than
  :data:`~flowtex.limits.TIME_GAP_TOLERANCE` median steps (samples are missing there).

One rule applies where a signal is used, not where it is read: a signal whose unit the file states
(``Recording.units``) is refused by a consumer that takes another unit (:func:`check_stated_unit`), since
flowtex converts no unit.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import DataError
from ..limits import MAX_SIGNAL_WIDTH, TIME_GAP_TOLERANCE, excerpt
from ..node_decl import simplify_unit

TIME_SIGNAL = "time"
"""A signal of this name holds sample times (seconds) and is checked for order and gaps."""


def numeric_signal(arr: np.ndarray, path: Path | str, name: str) -> np.ndarray:
    """``arr`` as float64 if it holds real numbers (booleans, integers, floats); else :class:`DataError`."""
    kind = arr.dtype.kind
    if kind == "c":
        raise DataError(f"{path}: signal {excerpt(name)} is complex; flowtex signals are real: store the real and "
                        "imaginary parts (or magnitude and phase) as two signals")
    if kind not in "biuf":
        raise DataError(f"{path}: signal {excerpt(name)} holds {str(arr.dtype)[:40]} values, not numbers; "
                        "store text (names, units) outside the recording")
    return np.asarray(arr, dtype=np.float64)


def check_signals(arrays: dict[str, np.ndarray], path: Path | str) -> None:
    """Apply the module's rules to float64 signals read from ``path``."""
    if not arrays:
        raise DataError(f"{path}: the recording holds no signals; store one array per signal, time first")
    for name, a in arrays.items():
        n = a.shape[0]
        width = int(np.prod(a.shape[1:], dtype=np.int64))
        if a.ndim > 1 and width > MAX_SIGNAL_WIDTH and width > n:
            raise DataError(f"{path}: signal {excerpt(name)} has shape {a.shape}: {n} samples of {width} values each looks "
                            f"transposed (time is the first axis); store it as shape {a.shape[::-1]} (array.T)")
        if n < 2:
            what = "no samples (the recording is empty)" if n == 0 else "one sample"
            raise DataError(f"{path}: signal {excerpt(name)} has {what}; a recording needs at least 2 samples")
    lengths = {name: a.shape[0] for name, a in arrays.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{excerpt(n, 30)}: {k}" for n, k in list(lengths.items())[:8])
        raise DataError(f"{path}: signals have different lengths ({detail}); time must be the first axis of every array")
    time = arrays.get(TIME_SIGNAL)
    if time is not None and time.ndim == 1:
        check_time(time, path)


def check_time(time: np.ndarray, path: Path | str) -> None:
    """Refuse a time column that does not increase strictly or that jumps (a step > TIME_GAP_TOLERANCE median steps)."""
    step = np.diff(time)
    back = np.flatnonzero(~(step > 0))  # also catches NaN
    if back.size:
        i = int(back[0])
        raise DataError(f"{path}: signal 'time' does not increase at sample {i + 1} ({time[i]:g} then {time[i + 1]:g}; "
                        f"{back.size} such step(s)); sort the rows, cut the repeated part, or drop the time column")
    median = float(np.median(step))
    gaps = np.flatnonzero(step > TIME_GAP_TOLERANCE * median)
    if gaps.size:
        i = int(gaps[0])
        raise DataError(f"{path}: signal 'time' jumps from {time[i]:g} to {time[i + 1]:g} at sample {i + 1}, "
                        f"{step[i] / median:.3g} times its median step of {median:g} (at most {TIME_GAP_TOLERANCE:g}; "
                        f"{gaps.size} gap(s)): samples are missing; cut the recording at the gap or fill it")


UNIT_FACTORS = {("m/s", "mm/s"): 1e3, ("cm/s", "mm/s"): 10.0, ("m", "mm"): 1e3, ("cm", "mm"): 10.0, ("um", "mm"): 1e-3,
                ("g", "m/s^2"): 9.80665, ("mm/s^2", "m/s^2"): 1e-3, ("mN", "N"): 1e-3, ("kN", "N"): 1e3}
"""(stated unit, unit taken) -> the factor that converts the first into the second, for the fix a refusal names."""
NO_UNIT = ("", "-", "*")
"""Units that state nothing: a dimensionless signal or input, or a port that takes any unit."""


def _plain(unit: str) -> str:
    """``unit`` as :func:`~flowtex.node_decl.simplify_unit` reads it: superscript powers written ``^n`` (``m/s²``, as HDF5
    writers put it, is ``m/s^2``), a space between two factors a product (``mm s^-1`` is ``mm*s^-1``), and the second
    spelled out as DBC files often do (``mm/sec``, ``m/second``) the symbol ``s`` (``msec`` stays a millisecond)."""
    unit = re.sub(r"\s*([*/^])\s*", r"\1", unit.strip().replace("\u00b2", "^2").replace("\u00b3", "^3"))
    unit = re.sub(r"\b(?:secs?|seconds?)\b", "s", unit)
    return re.sub(r"\s+", "*", unit)


def plain_unit(unit: str) -> str:
    """``unit`` as units are compared here: read by :func:`_plain`, then :func:`~flowtex.node_decl.simplify_unit`
    (``m*s^-1``, ``m s^-1`` and ``m/s`` are all ``m/s``)."""
    return simplify_unit(_plain(unit))


SPEED_UNITS = frozenset(plain_unit(f"{length}/s") for length in ("mm", *(a for a, b in UNIT_FACTORS if b == "mm")))
"""The speed units flowtex recognises (a length of :data:`UNIT_FACTORS` per second: mm/s, m/s, cm/s, um/s)."""


def is_speed_unit(unit: str) -> bool:
    """True if ``unit`` (any spelling :func:`plain_unit` reads) is a length per second of :data:`SPEED_UNITS`."""
    return plain_unit(unit) in SPEED_UNITS


def is_unit_of(unit: str, base: str) -> bool:
    """True if ``unit`` is ``base`` in any spelling :func:`plain_unit` reads, or a unit :data:`UNIT_FACTORS` converts
    into it (``g`` and ``mm/s^2`` for ``m/s^2``, ``mN`` and ``kN`` for ``N``): the same quantity on another scale."""
    stated, wanted = plain_unit(unit), plain_unit(base)
    return stated == wanted or (stated, wanted) in UNIT_FACTORS


def unit_factor(stated: str, wanted: str) -> float | None:
    """The factor that converts a value in ``stated`` into ``wanted`` (both as :func:`plain_unit` writes them), read from
    :data:`UNIT_FACTORS` in either direction or through a unit both convert into (``m/s`` -> ``cm/s`` via ``mm/s``);
    None when the table knows none (or the units are equal)."""
    if (stated, wanted) in UNIT_FACTORS:
        return UNIT_FACTORS[(stated, wanted)]
    if (wanted, stated) in UNIT_FACTORS:
        return 1.0 / UNIT_FACTORS[(wanted, stated)]
    for (a, base), f in UNIT_FACTORS.items():
        if a == stated and (wanted, base) in UNIT_FACTORS:
            return f / UNIT_FACTORS[(wanted, base)]
    return None


def check_stated_unit(units: Mapping[str, str], name: str, unit: str, path: Path | str, consumer: str) -> None:
    """Refuse signal ``name`` when the file states a unit (``units``, ``Recording.units``) other than ``unit``.

    ``consumer`` names who takes ``unit`` (``"graph 'g' input 'speed'"``, ``"--speed"``). Units are compared as
    :func:`~flowtex.node_decl.simplify_unit` writes them (``m/s/s`` is ``m/s^2``); a unit that states nothing on
    either side (absent, ``-``) passes. flowtex converts no unit: a speed stated in m/s fed to an input in mm/s
    rendered 1000x too slow, silently; a fit of an acceleration in g gave a surface 20 dB too quiet.
    """
    raw = str(units.get(name, ""))
    stated = plain_unit(raw)
    want = plain_unit(unit)
    if stated in NO_UNIT or want in NO_UNIT or stated == want:
        return
    factor = unit_factor(stated, want)
    fix = (f"multiply it by {factor:g} and state its unit as {want}" if factor is not None
           else f"convert it to {want} and state that unit")
    raise DataError(f"{path}: signal {excerpt(name)} is in {excerpt(raw.strip())} (the file's units) but {consumer} takes "
                    f"{want}; flowtex converts no unit: {fix}")
