"""Bring every signal of a recording to another rate (any rational ratio): what ``flowtex resample`` does.

Zero delay (signals stay aligned in time), length n * r2 / r1 rounded, Kaiser
polyphase filter (flowtex.dsp.resample). The output states its new rate and the units the source states.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..dsp.resample import DEFAULT_ATTEN_DB, rational_ratio, resample_signal
from ..errors import DataError, FlowtexError
from .formats import AUDIO, RECORDING, kind_of
from .recordings import load_recording, save_recording

MAX_RATE_RATIO = 64.0
"""Largest change of rate (up or down) in one call: the polyphase filter's length grows with the ratio."""


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
    arrays = {}
    for name, a in rec.arrays.items():
        if not np.all(np.isfinite(a)):
            raise DataError(f"{src}: signal {name!r} has NaN or inf values; clean it before resampling")
        try:
            arrays[name] = resample_signal(a, rate_in, rate_hz, atten_db=atten_db)
        except ValueError as exc:
            raise FlowtexError(f"{src}: signal {name!r}: {exc}") from None
    save_recording(out, arrays, rate=rate_hz, units=rec.units)
    return (f"{out}: {len(arrays)} signal(s), {rec.samples} samples at {rate_in:g} Hz -> "
            f"{next(iter(arrays.values())).shape[0] if arrays else 0} at {rate_hz:g} Hz (x {up}/{down})")
