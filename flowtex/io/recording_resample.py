"""Bring every signal of a recording to another rate (any rational ratio): what ``flowtex resample`` does.

Zero delay (signals stay aligned in time), length n * r2 / r1 rounded, Kaiser
polyphase filter (flowtex.dsp.resample). A signal that is a state rather than a waveform (:func:`is_state_signal`:
a contact flag, a surface index) is held instead, sample by nearest sample, so it keeps its values. The output
states its new rate and the units the source states.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..dsp.resample import DEFAULT_ATTEN_DB, hold_signal, rational_ratio, resample_signal
from ..errors import DataError, FlowtexError
from .formats import AUDIO, RECORDING, kind_of
from .recording_rules import TIME_SIGNAL
from .recordings import load_recording, save_recording

MAX_RATE_RATIO = 64.0
"""Largest change of rate (up or down) in one call: the polyphase filter's length grows with the ratio."""

STATE_LEVELS = 16
"""A signal whose samples are whole numbers taking at most this many values, and that holds its value over most
steps, is a state (a flag, an index), not a waveform: :func:`is_state_signal`."""


def is_state_signal(name: str, a: np.ndarray) -> bool:
    """True when every sample of ``a`` is a whole number, ``a`` takes at most :data:`STATE_LEVELS` values and changes
    value on at most half of its steps; never for the time column (a ramp, which the filter keeps exact).

    Such a signal is held, not filtered: a filter rings around each step (docs/cli.md has the overshoot of a 0/1 flag)
    and leaves values a flag or an index never takes. A short recording's integer ramp (time 0, 1, 2, ... s; a position
    in whole mm) changes at every step: it is a waveform, and held it would become a staircase.
    """
    if name == TIME_SIGNAL or a.size == 0 or not np.all(a == np.round(a)) or np.unique(a).size > STATE_LEVELS:
        return False
    steps = a.shape[0] - 1
    changes = int(np.count_nonzero(np.any((a[1:] != a[:-1]).reshape(steps, -1), axis=1))) if steps > 0 else 0
    return 2 * changes <= steps


def resample_recording(src: str | Path, out: str | Path, rate_hz: float, from_rate: float | None = None,
                       atten_db: float = DEFAULT_ATTEN_DB) -> str:
    """Resample recording ``src`` to ``rate_hz`` (Hz) and write it to ``out`` (atomically); returns a one-line summary.

    ``from_rate`` (Hz) is the rate of a recording that states none; a conflicting one is an error.
    """
    src, out = Path(src), Path(out)
    if kind_of(out) not in (RECORDING, AUDIO):
        raise DataError(f"{out}: unknown output format {out.suffix!r}; use .npz, .csv, .h5 or .wav")
    rec = load_recording(src)
    rate_in = rec.rate
    if rate_in is None:
        if from_rate is None:
            raise DataError(f"{src}: the recording states no rate; give its rate with --from-rate HZ")
        rate_in = from_rate
    elif from_rate is not None and from_rate != rate_in:
        raise DataError(f"{src}: the recording states {rate_in:g} Hz but --from-rate says {from_rate:g} Hz; drop --from-rate")
    if not (np.isfinite(rate_hz) and rate_in / MAX_RATE_RATIO <= rate_hz <= rate_in * MAX_RATE_RATIO):
        raise DataError(f"--rate {rate_hz:g}: valid range for this {rate_in:g} Hz recording is {rate_in / MAX_RATE_RATIO:g} to "
                        f"{rate_in * MAX_RATE_RATIO:g} Hz (at most {MAX_RATE_RATIO:g}x up or down)")
    try:
        up, down = rational_ratio(rate_in, rate_hz)
    except ValueError as exc:
        raise FlowtexError(f"{src}: {exc}") from None
    arrays: dict[str, np.ndarray] = {}
    held: list[str] = []
    for name, a in rec.arrays.items():
        if not np.all(np.isfinite(a)):
            raise DataError(f"{src}: signal {name!r} has NaN or inf values; clean it before resampling")
        try:
            if is_state_signal(name, a):
                held.append(name)
                arrays[name] = hold_signal(a, rate_in, rate_hz)
            else:
                arrays[name] = resample_signal(a, rate_in, rate_hz, atten_db=atten_db)
        except ValueError as exc:
            raise FlowtexError(f"{src}: signal {name!r}: {exc}") from None
    save_recording(out, arrays, rate=rate_hz, units=rec.units)
    states = f"; held, not filtered (whole numbers of at most {STATE_LEVELS} values): {', '.join(held)}" if held else ""
    return (f"{out}: {len(arrays)} signal(s), {rec.samples} samples at {rate_in:g} Hz -> "
            f"{next(iter(arrays.values())).shape[0] if arrays else 0} at {rate_hz:g} Hz (x {up}/{down}){states}")
