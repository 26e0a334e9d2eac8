"""Reading the signals a fit needs from a recording, with one-line errors naming the file, the signal and the fix.

Shared by every ``flowtex fit`` kind: the rate rule (a rate stated in the
file wins; ``--from-rate`` supplies a missing one; a conflicting ``--from-rate`` is an
error), signal presence and shape, NaN/inf (how many, where), constant
signals, magnitudes no sensor produces (:data:`PLAUSIBLE`: a signal in the
wrong unit, or scaled by 1e30, is refused before any fit math runs). Outputs go
through the one writer, :mod:`flowtex.io.atomic`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError, InputError
from ..io.atomic import atomic_output  # noqa: F401 -- the one writer, re-exported for the fit modules
from ..io.recording_rules import check_stated_unit
from ..io.recordings import Recording, load_recording
from ..limits import excerpt
from ..pyvalues import float_signal, plain, positive_rate


def load(path: str | Path, rate: float | None) -> tuple[Recording, float]:
    """Load a recording and decide its rate (Hz) with :func:`recording_rate`."""
    rec = load_recording(path)
    return rec, recording_rate(rec, rate)


def recording_rate(rec: Recording, from_rate: float | None) -> float:
    """The rate in Hz: the one the file states, else ``from_rate`` (``--from-rate``); an error if neither or if they differ.

    The one rate rule of every fit (texture, friction, taps, pattern, compliance).
    """
    if rec.rate is not None and from_rate is not None and abs(from_rate - rec.rate) > 1e-9 * rec.rate:
        raise DataError(f"{rec.path}: the file states a rate of {rec.rate:g} Hz but --from-rate is {from_rate:g}; "
                        "drop --from-rate (the file's rate wins) or fix the file")
    rate = rec.rate if rec.rate is not None else from_rate
    if rate is None:
        raise DataError(f"{rec.path}: the recording states no sample rate; pass --from-rate {_rate_hint(rec)}")
    if not (np.isfinite(rate) and rate > 0):
        what = "--from-rate" if rec.rate is None else "the file's sample rate"
        raise DataError(f"{rec.path}: {what} must be a positive number of Hz, got {rate!r}")
    return float(rate)


def _rate_hint(rec: Recording) -> str:
    """``HZ``, or the rate its ``time`` column (s) steps at (a CSV often has one but no '# rate:' line): the file's
    own rate, named, is the fix; it is not taken silently, as the file does not state it."""
    t = rec.arrays.get("time")
    if t is None or t.ndim != 1 or t.shape[0] < 2:
        return "HZ"
    step = float(np.median(np.diff(t)))
    if not (np.isfinite(step) and step > 0):
        return "HZ"
    return f"{1.0 / step:.6g} (the median step of its 'time' column, {step:g} s)"


def signals_listed(rec: Recording) -> str:
    """"the file has: a, b, c": what a recording holds, for a message that asks for one of its signals."""
    return f"the file has: {', '.join(sorted(rec.arrays)) or 'nothing'}"


def signal(rec: Recording, name: str, option: str, width: tuple[int, ...] = (1,), finite: bool = True) -> np.ndarray:
    """The signal ``name`` (given by ``option``) as (n,) or (n, w) with w in ``width`` (1 means a 1-D signal).

    Raises DataError when it is missing, is stated in the file in another unit than ``option`` takes, has another
    shape, or (``finite``) holds NaN/inf samples.
    """
    where = rec.path
    if name not in rec.arrays:
        raise DataError(f"{where}: no signal {name!r} ({option}); {signals_listed(rec)}")
    quantity = QUANTITY_OF_OPTION.get(option)
    if quantity is not None:  # a unit the file states must be the one the option takes (flowtex converts none)
        check_stated_unit(rec.units, name, PLAUSIBLE[quantity][0], where, option)
    a = rec.arrays[name]
    cols = 1 if a.ndim == 1 else (a.shape[1] if a.ndim == 2 else -1)
    if a.ndim == 2 and a.shape[1] == 1 and 1 in width:
        a = a[:, 0]
        cols = 1
    if cols not in width:
        want = " or ".join("1-D (n,)" if w == 1 else f"(n, {w})" for w in width)
        raise DataError(f"{where}: signal {name!r} ({option}) has shape {a.shape}; expected {want}")
    if finite:
        check_finite(a, f"{where}: signal {name!r} ({option})")
        check_plausible(a, f"{where}: signal {name!r} ({option})", option)
    return a


PLAUSIBLE = {
    "acceleration": ("m/s^2", 1e-9, 1e5),
    "force": ("N", 0.0, 1e4),
    "speed": ("mm/s", 0.0, 1e5),
    "position": ("mm", 0.0, 1e6),
}
"""Quantity -> (unit, least nonzero peak, largest peak): a signal outside is in another unit or corrupt (0 means no floor)."""
NEGATIVE_SPEED_TOLERANCE = 0.01
"""A speed sample below -this x the peak speed is negative (filtered or resampled magnitudes dip a little below 0)."""
NEGATIVE_SPEED_SHARE = 0.05
"""More than this share of negative speed samples: a signed velocity was given where a magnitude is due."""
QUANTITY_OF_OPTION = {"--accel": "acceleration", "--force": "force", "--normal-force": "force",
                      "--friction-force": "force", "--speed": "speed", "--position": "position"}
"""The quantity each signal option of the fit verbs names (checked against :data:`PLAUSIBLE`)."""


def check_plausible(a: np.ndarray, label: str, option: str) -> None:
    """Refuse a finite signal given by ``option`` whose peak magnitude is outside :data:`PLAUSIBLE` for its quantity.

    ``label`` names the file and signal. Options not in :data:`QUANTITY_OF_OPTION` pass.
    An all-zero acceleration is refused too (no vibration was recorded).
    """
    quantity = QUANTITY_OF_OPTION.get(option)
    if quantity is None or a.size == 0:
        return
    unit, least, most = PLAUSIBLE[quantity]
    peak = float(np.max(np.abs(a)))
    if peak > most:
        raise DataError(f"{label}: peak {quantity} {peak:.3g} {unit} is beyond any sensor's range (at most {most:g} {unit}); "
                        f"is the signal in {unit}? Rescale it")
    if 0.0 < peak < least:
        raise DataError(f"{label}: peak {quantity} {peak:.3g} {unit} is below any sensor's resolution (at least {least:g} {unit}); "
                        f"is the signal in {unit}? Rescale it")


def check_speed_magnitude(a: np.ndarray, label: str, option: str = "--speed") -> None:
    """Refuse a signed velocity (mm/s) where the speed magnitude is due: more than NEGATIVE_SPEED_SHARE of it is negative."""
    peak = float(np.max(np.abs(a))) if a.size else 0.0
    negative = float(np.mean(a < -NEGATIVE_SPEED_TOLERANCE * peak)) if a.size else 0.0
    if negative > NEGATIVE_SPEED_SHARE:
        raise DataError(f"{label}: the speed is negative in {100 * negative:.0f} % of the samples; {option} takes the "
                        "speed magnitude (mm/s, >= 0), not a signed velocity: give its absolute value")


def check_finite(a: np.ndarray, label: str) -> None:
    """Raise DataError saying how many samples of ``a`` are NaN/inf and where the first ones are."""
    bad = ~np.isfinite(a)
    if bad.ndim > 1:
        bad = bad.any(axis=1)
    if bad.any():
        idx = np.flatnonzero(bad)
        first = ", ".join(str(int(i)) for i in idx[:3]) + (", ..." if idx.size > 3 else "")
        raise DataError(f"{label}: {idx.size} NaN/inf sample(s) (at sample {first}); interpolate or cut them out first")


def check_highpass(highpass_hz: float, rate_hz: float) -> None:
    """Raise DataError unless 0 <= ``highpass_hz`` < the Nyquist frequency of ``rate_hz`` (0: no high-pass)."""
    if not (np.isfinite(highpass_hz) and 0.0 <= highpass_hz < 0.5 * rate_hz):
        raise DataError(f"--highpass {highpass_hz:g}: valid range is 0 (none) to below {0.5 * rate_hz:g} Hz "
                        f"(half the recording's rate of {rate_hz:g} Hz)")


def check_not_constant(a: np.ndarray, label: str) -> None:
    """Raise DataError when ``a`` does not vary (nothing to fit)."""
    if a.size == 0 or float(np.ptp(a)) == 0.0:
        raise DataError(f"{label} is constant; check that the right signal is named and that the sensor was recording")


def api_signals(where: str, rate: Any, vectors: Mapping[str, int | None] | None = None,
                **signals: Any) -> tuple[float | None, list[np.ndarray | None]]:
    """``rate`` (Hz) and ``signals`` as Python code hands them to a fit function (lists, float32, (n, 1) columns) made
    a positive float (``rate=None``: none taken) and float64 arrays of one length, 1-D, or for a signal named in
    ``vectors`` (n, width) (width None: (n,) or (n, any)), with no NaN/inf (a signal given as None stays None), as the CLI's readers check a file's
    (:func:`signal`); else one error naming the argument and the fix, before any fit math runs on wrong arrays.
    """
    value = None if rate is None else positive_rate(f"{where}: rate", rate)
    arrays: list[np.ndarray | None] = []
    for name, given in signals.items():
        a = None if given is None else float_signal(name, given, "signal")
        width = (vectors or {}).get(name, 1)
        if a is not None and width != 1:
            if not (a.ndim == 2 and width in (None, a.shape[1])) and not (a.ndim == 1 and width is None):
                want = "a 1-D or 2-D array" if width is None else f"an (n, {width}) array"
                raise InputError(f"{where}: signal {name!r} has shape {a.shape}; pass {want}, one row per tick")
        elif a is not None:
            if a.ndim == 2 and a.shape[1] == 1:
                a = a[:, 0]
            if a.ndim != 1:
                axes = "; reduce 3 axes to one with flowtex.dsp.dft321.dft321" if a.ndim == 2 and a.shape[1] == 3 else ""
                raise InputError(f"{where}: signal {name!r} has shape {a.shape}; pass a 1-D array, one sample per tick{axes}")
        arrays.append(a)
    given = {name: a for name, a in zip(signals, arrays, strict=True) if a is not None}
    if len({a.shape[0] for a in given.values()}) > 1:
        raise InputError(f"{where}: signals have different lengths ("
                         + ", ".join(f"{name} {a.shape[0]}" for name, a in given.items()) + "); pass one sample per tick of each")
    for name, a in given.items():
        check_finite(a, f"{where}: signal {name!r}")
    return value, arrays


def sample_ranges(where: str, name: str, ranges: Any, n: int) -> list[tuple[int, int]] | None:
    """``ranges`` (None, or (start, stop) sample index pairs of a recording of ``n`` samples) as int pairs with
    0 <= start < stop <= n; else one :class:`InputError` naming the argument (``within``, ``ranges``) and the pair,
    where a reversed or negative pair was an empty selection or counted from the end."""
    if ranges is None:
        return None
    pairs = plain(ranges)
    if not isinstance(pairs, list) or not pairs:
        raise InputError(f"{where}: {name} must be a non-empty list of (start, stop) sample ranges, got {excerpt(ranges)}")
    out = []
    for k, pair in enumerate(pairs):
        pair = plain(pair)
        ok = isinstance(pair, list) and len(pair) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in pair)
        if not (ok and 0 <= pair[0] < pair[1] <= n):
            raise InputError(f"{where}: {name}[{k}] = {excerpt(pair)}: a range is (start, stop) sample indices, integers "
                             f"with 0 <= start < stop <= {n} (the recording's length)")
        out.append((pair[0], pair[1]))
    return out
