"""Non-finite samples (NaN, +-inf) in recorded signals: find them, or replace them.

One NaN fed to a recursive filter poisons its state for good: every later
output is NaN. Offline runs therefore check their inputs first and apply one
of these policies (``flowtex run --nonfinite``, ``Graph.run(nonfinite=...)``):

* ``error``: refuse the recording, naming the signal, how many samples and the
  first index (the default);
* ``hold``: replace each non-finite sample by the last finite one of the same
  channel (0 before the first finite one);
* ``zero``: replace each non-finite sample by 0;
* ``pass``: feed them to the graph unchanged (for graphs whose nodes handle
  them on purpose, e.g. ``clip``'s ``nan`` parameter or ``texture_lookup``).

Arrays have time on the first axis; values keep their unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError, FlowtexError

NONFINITE_POLICIES = ("error", "hold", "zero", "pass")


@dataclass(frozen=True)
class NonFinite:
    """Non-finite samples of one signal: how many time steps hold one, the first index and its value."""

    count: int
    first_index: int
    first_value: float

    def describe(self) -> str:
        return f"{self.count} non-finite sample(s), the first ({self.first_value!r}) at index {self.first_index}"


def find_nonfinite(a: np.ndarray) -> NonFinite | None:
    """Non-finite samples of ``a`` (time first), or None when every value is finite.

    ``count`` counts time steps with at least one non-finite component.
    """
    bad = ~np.isfinite(a)
    if not bad.any():
        return None
    rows = bad.reshape(a.shape[0], -1).any(axis=1)
    first = int(np.argmax(rows))
    value = float(a.reshape(a.shape[0], -1)[first][bad.reshape(a.shape[0], -1)[first]][0])
    return NonFinite(int(rows.sum()), first, value)


@dataclass(frozen=True)
class NonFiniteCount:
    """NaN and inf values of one signal (every component counted) and the first time step holding either."""

    nan: int
    inf: int
    first_index: int

    def describe(self) -> str:
        return f"{self.nan} NaN and {self.inf} inf value(s), the first at tick {self.first_index}"


def count_nonfinite(a: np.ndarray) -> NonFiniteCount | None:
    """NaN and inf values of ``a`` (time first), or None when every value is finite."""
    flat = np.asarray(a, dtype=np.float64).reshape(a.shape[0], -1)
    nan = np.isnan(flat)
    inf = np.isinf(flat)
    rows = (nan | inf).any(axis=1)
    if not rows.any():
        return None
    return NonFiniteCount(int(nan.sum()), int(inf.sum()), int(np.argmax(rows)))


def fill_nonfinite(a: np.ndarray, policy: str, before: np.ndarray | None = None) -> np.ndarray:
    """A copy of ``a`` (time first) with non-finite samples replaced by ``policy`` (``hold`` or ``zero``).

    ``before`` (one time step of ``a``'s shape) is what ``hold`` holds until the first finite sample (default 0): the
    last finite values of the chunk before, so that a signal filled in chunks equals it filled in one pass.
    """
    if policy not in ("hold", "zero"):
        raise ValueError(f"unknown non-finite policy {policy!r}; use hold or zero")
    flat = np.array(a, dtype=np.float64).reshape(a.shape[0], -1)
    bad = ~np.isfinite(flat)
    if policy == "zero":
        flat[bad] = 0.0
        return flat.reshape(a.shape)
    rows = np.arange(flat.shape[0])[:, None]
    last_good = np.maximum.accumulate(np.where(bad, -1, rows), axis=0)  # index of the last finite sample, -1 if none
    filled = np.take_along_axis(flat, np.maximum(last_good, 0), axis=0)
    if before is None:
        filled[last_good < 0] = 0.0
    else:
        filled = np.where(last_good < 0, np.asarray(before, dtype=np.float64).reshape(1, -1), filled)
    return filled.reshape(a.shape)


def apply_nonfinite_policy(arrays: dict[str, np.ndarray], policy: str, source: str = "",
                           fix: str = "or pass nonfinite='hold' or 'zero'",
                           held: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """``arrays`` with non-finite samples handled by ``policy`` (see :mod:`flowtex.dsp.nonfinite`).

    ``error`` raises :class:`DataError` naming ``source`` (a file, if any), the signal,
    the count and the first index; a recursive filter fed one NaN would output NaN for good.
    ``held`` (signal -> its last time step after ``hold``), kept by a caller that feeds a signal in chunks, carries
    the held value from one chunk into the next; it is updated in place.
    """
    if policy not in NONFINITE_POLICIES:
        raise FlowtexError(f"unknown non-finite policy {policy!r}; use one of {', '.join(NONFINITE_POLICIES)}")
    out = {}
    for name, a in arrays.items():
        found = find_nonfinite(a)
        if found is None or policy == "pass":
            out[name] = a
        elif policy == "error":
            prefix = f"{source}: " if source else ""
            raise DataError(f"{prefix}input {name!r} has {found.describe()}; clean the recording {fix}")
        else:
            out[name] = fill_nonfinite(a, policy, held.get(name) if held is not None and policy == "hold" else None)
        if held is not None and policy == "hold" and len(out[name]):
            held[name] = out[name][-1].copy()
    return out
