"""Runtime safety layer: output clamps with a bounded peak allowance, and a watchdog.

Safety belongs to the runtime, not to each graph: every actuator output the live loop
sends passes through an :class:`OutputGuard`, and a :class:`Watchdog` decides when all
outputs must be forced to their safe values.

OutputGuard rules (per actuator channel ``i``, applied every tick by :meth:`OutputGuard.apply`):

The peak allowance is a budget per channel (a token bucket, in integer units so that live, offline and replay
compute it bit for bit): ``P = peak_max_ticks`` peak ticks when full, one spent per tick
limited to the peak range, refilled by ``P / R`` of a tick (``R = peak_recover_ticks``) per tick that is not
beyond ``[lo, hi]``. In units: capacity ``P * cost``, ``cost = R / g`` spent per peak tick, ``gain = P / g``
added per refilling tick (``g = gcd(P, R)``), capped at the capacity. It starts full.

1. ``force_safe`` -> output ``safe[i]`` for every channel (watchdog tripped, shutdown).
   Not counted as a clamp event; the budget refills (the safe value lies within ``[lo, hi]``).
2. Commanded value NaN, +inf or -inf -> output ``safe[i]``; counted in the return value
   and in ``nonfinite_counts[i]``; the budget refills (the output is the safe value).
3. Finite value within ``[lo[i], hi[i]]`` (bounds inclusive) -> passed through unchanged;
   the budget refills.
4. Finite value outside ``[lo, hi]``: while the budget holds at least one peak tick
   (``budget >= cost``) the value is clamped to the peak range ``[peak_lo[i], peak_hi[i]]``
   (so a value inside it passes unchanged; beyond it is a peak-limit event) and one peak
   tick is spent; otherwise it is clamped to ``[lo, hi]`` (a clamp event), which neither
   spends nor refills: a command that stays beyond the clamp stays clamped.

   Bounds this gives, for any command sequence: at most ``P`` consecutive ticks beyond
   ``[lo, hi]`` (a full budget holds ``P``); over any window of ``W`` ticks at most
   ``P * (R + W) / (R + P)`` of them, so the long-run share of ticks beyond ``[lo, hi]``
   is at most ``P / (P + R)``. ``R`` is the number of refilling ticks that refill an empty
   budget. ``peak_max_ticks = 0`` (or no ``peak_hi``) means no peaks at all. ``peak_lo``
   defaults to the mirror of the upper margin, ``lo - (peak_hi - hi)``, i.e. ``-peak_hi``
   for symmetric limits; pass ``peak_lo=lo`` to allow peaks on the upper side only.

The return value of :meth:`OutputGuard.apply` is the number of channels whose output
differs from the command because of rules 2 and 4 (0 when all pass); cumulative
per-channel counts are in ``nonfinite_counts`` (rule 2), ``peak_counts`` (rule 4, limited to
the peak range within the allowance) and ``clamp_counts`` (rule 4, clamped to ``[lo, hi]``).

Watchdog rules (:class:`Watchdog`):

- Each sensor input ``i`` has a timeout in ticks. The loop calls
  ``fresh(i, tick)`` when a new frame for that input arrives. The input is *stale* at
  ``tick`` when ``tick - last[i] > timeout[i]`` (an age exactly equal to the timeout
  is still fresh). An input never updated is stale.
- ``check(tick, overrun_ns)`` trips when any input is stale or ``overrun_ns`` exceeds
  ``overrun_limit_ns`` (strictly greater; pass the tick's lateness or how far its
  compute ran past the period, whichever the loop uses). The tripped tick is
  remembered (the latest tick at which a trip condition held).
- Recovery: the watchdog stays tripped until a ``check`` at which no trip condition
  holds and *every* input has been refreshed strictly after the latest trip tick
  ("inputs are fresh again"). So after an overrun at tick t, outputs are safe at
  tick t and return at the first later tick by which every sensor has sent a new frame.
- At construction the watchdog is tripped (reason ``"startup"``, not counted as an
  event): outputs stay safe until every input has reported once.
- ``events`` counts transitions from OK to tripped (split by cause into
  ``stale_events`` and ``overrun_events``; a tick with both counts as stale); each is appended to ``log`` as
  ``(tick, reason, detail)`` (reason ``"stale"`` with the input index, or ``"overrun"``
  with the overrun in ns) and logged through :mod:`logging` (logger
  ``flowtex.runtime.safety``). The log keeps the first ``log_capacity`` events;
  ``events`` keeps counting past that.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from numba import njit

from ..cache import configure_numba_cache
from ..schema.devmap import PEAK_RECOVER_RATIO

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)

_log = logging.getLogger(__name__)

# Rows of the OutputGuard parameter matrices.
_LO, _HI, _SAFE, _PLO, _PHI = 0, 1, 2, 3, 4
_CAP, _BUDGET, _NCLAMP, _NNONFINITE, _NPEAK, _COST, _GAIN = 0, 1, 2, 3, 4, 5, 6
_IROWS = 7
_MAX_UNITS = 1 << 62
"""Largest budget capacity in units (``P * R / gcd(P, R)``): the int64 budget plus one gain cannot overflow."""


@njit(cache=True)
def guard_kernel(fp: np.ndarray, ip: np.ndarray, values: np.ndarray, out: np.ndarray, force_safe: bool) -> int:
    """Apply the OutputGuard rules (module docstring) to one tick; returns the event count.

    ``fp`` is ``(5, n)`` float64: rows lo, hi, safe, peak_lo, peak_hi. ``ip`` is ``(7, n)``
    int64: rows budget capacity, budget, clamp count, non-finite count, peak-limit count,
    cost of a peak tick, gain of a refilling tick (budget units); rows 1-4 are updated in
    place. ``values`` and ``out`` are ``(n,)``.
    """
    n = out.shape[0]
    if force_safe:
        for i in range(n):
            out[i] = fp[_SAFE, i]
            ip[_BUDGET, i] = min(ip[_CAP, i], ip[_BUDGET, i] + ip[_GAIN, i])
        return 0
    events = 0
    for i in range(n):
        v = values[i]
        if not np.isfinite(v):
            out[i] = fp[_SAFE, i]
            ip[_NNONFINITE, i] += 1
            ip[_BUDGET, i] = min(ip[_CAP, i], ip[_BUDGET, i] + ip[_GAIN, i])
            events += 1
            continue
        lo = fp[_LO, i]
        hi = fp[_HI, i]
        if v >= lo and v <= hi:
            out[i] = v
            ip[_BUDGET, i] = min(ip[_CAP, i], ip[_BUDGET, i] + ip[_GAIN, i])
            continue
        peak = ip[_BUDGET, i] >= ip[_COST, i]
        if peak:
            ip[_BUDGET, i] -= ip[_COST, i]
            lo = fp[_PLO, i]
            hi = fp[_PHI, i]
        if v > hi:
            out[i] = hi
        elif v < lo:
            out[i] = lo
        else:
            out[i] = v
            continue
        if peak:
            ip[_NPEAK, i] += 1
        else:
            ip[_NCLAMP, i] += 1
        events += 1
    return events


def _ticks(name: str, x, n: int, least: int) -> np.ndarray:
    """``x`` as an int64 vector of ``n`` tick counts, each at least ``least`` (a scalar is broadcast)."""
    a = np.atleast_1d(np.asarray(x))
    if a.ndim != 1 or not np.issubdtype(a.dtype, np.integer) or np.any(a < least):
        raise ValueError(f"OutputGuard: {name} must be an int >= {least} (or one per output), got {x!r}")
    if a.shape[0] == 1:
        a = np.full(n, a[0])
    if a.shape[0] != n:
        raise ValueError(f"OutputGuard: {name} has {a.shape[0]} entries, expected {n}")
    return a.astype(np.int64)


def budget_units(peak: int, recover: int) -> tuple[int, int, int]:
    """(capacity, cost of a peak tick, gain of a refilling tick) in integer budget units for an allowance of ``peak``
    ticks refilled from empty by ``recover`` refilling ticks: ``gain / cost = peak / recover`` exactly."""
    if peak == 0:
        return 0, 1, 0
    g = math.gcd(peak, recover)
    cost, gain = recover // g, peak // g
    if peak * cost >= _MAX_UNITS:
        raise ValueError(f"OutputGuard: a peak allowance of {peak} ticks refilled in {recover} ticks needs a budget of "
                         f"{peak * cost} units, more than the guard's int64 holds: shorten peak max_ms or recover_ms")
    return peak * cost, cost, gain


def _vector(name: str, x, n: int) -> np.ndarray:
    """``x`` as a float64 vector of length ``n`` (a scalar or 1-element value is broadcast)."""
    a = np.atleast_1d(np.asarray(x, dtype=np.float64))
    if a.ndim != 1:
        raise ValueError(f"OutputGuard: {name} must be a scalar or a 1-D array, got shape {a.shape}")
    if a.shape[0] == 1 and n > 1:
        a = np.full(n, a[0])
    if a.shape[0] != n:
        raise ValueError(f"OutputGuard: {name} has {a.shape[0]} entries, expected {n} (one per actuator output)")
    return a


class OutputGuard:
    """Clamp + NaN/inf guard + bounded peak allowance for a vector of actuator outputs.

    ``lo``, ``hi``, ``safe``, ``peak_hi``, ``peak_lo`` are scalars or arrays with one
    entry per actuator output (in the output's own unit, e.g. N); ``peak_max_ticks`` (the
    allowance, ``P``) and ``peak_recover_ticks`` (refilling ticks that refill an empty
    allowance, ``R``; default :data:`~flowtex.schema.devmap.PEAK_RECOVER_RATIO` times ``P``)
    are scalars or per-channel ints (ticks of the live rate). See the module docstring for
    the exact rules. ``safe`` must lie within ``[lo, hi]``.
    """

    def __init__(self, lo, hi, safe, peak_hi=None, peak_max_ticks=0, peak_lo=None, peak_recover_ticks=None) -> None:
        sizes = (lo, hi, safe, peak_hi, peak_lo, peak_max_ticks, peak_recover_ticks)
        n = max(int(np.size(x)) for x in sizes if x is not None)
        lo_a = _vector("lo", lo, n)
        hi_a = _vector("hi", hi, n)
        safe_a = _vector("safe", safe, n)
        for name, a in (("lo", lo_a), ("hi", hi_a), ("safe", safe_a)):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"OutputGuard: {name} must be finite, got {a.tolist()}")
        if np.any(lo_a > hi_a):
            raise ValueError(f"OutputGuard: lo must be <= hi for every output (lo={lo_a.tolist()}, hi={hi_a.tolist()})")
        if np.any(safe_a < lo_a) or np.any(safe_a > hi_a):
            raise ValueError(f"OutputGuard: safe values {safe_a.tolist()} must lie within [lo, hi]")
        if peak_hi is None:
            phi = hi_a.copy()
        else:
            phi = _vector("peak_hi", peak_hi, n)
            if not np.all(np.isfinite(phi)) or np.any(phi < hi_a):
                raise ValueError(f"OutputGuard: peak_hi must be finite and >= hi, got {phi.tolist()}")
        if peak_lo is None:
            plo = lo_a - (phi - hi_a)
        else:
            plo = _vector("peak_lo", peak_lo, n)
            if not np.all(np.isfinite(plo)) or np.any(plo > lo_a):
                raise ValueError(f"OutputGuard: peak_lo must be finite and <= lo, got {plo.tolist()}")
        pmax = _ticks("peak_max_ticks", peak_max_ticks, n, 0)
        if peak_recover_ticks is None:
            rec = pmax * int(PEAK_RECOVER_RATIO)
        else:
            rec = _ticks("peak_recover_ticks", peak_recover_ticks, n, 1)
        self.n = n
        self._fp = np.ascontiguousarray(np.stack([lo_a, hi_a, safe_a, plo, phi]))
        self._ip = np.zeros((_IROWS, n), dtype=np.int64)
        for i in range(n):
            self._ip[[_CAP, _COST, _GAIN], i] = budget_units(int(pmax[i]), max(1, int(rec[i])))
        self._ip[_BUDGET] = self._ip[_CAP]

    @property
    def tables(self) -> tuple[np.ndarray, np.ndarray]:
        """The float and int arrays ``guard_kernel`` works on (for callers that fuse it into their own kernel)."""
        return self._fp, self._ip

    @property
    def lo(self) -> np.ndarray:
        return self._fp[_LO]

    @property
    def hi(self) -> np.ndarray:
        return self._fp[_HI]

    @property
    def safe(self) -> np.ndarray:
        return self._fp[_SAFE]

    @property
    def peak_lo(self) -> np.ndarray:
        return self._fp[_PLO]

    @property
    def peak_hi(self) -> np.ndarray:
        return self._fp[_PHI]

    @property
    def peak_max_ticks(self) -> np.ndarray:
        """Each channel's peak allowance when full, in ticks (``P``)."""
        return self._ip[_CAP] // self._ip[_COST]

    @property
    def peak_recover_ticks(self) -> np.ndarray:
        """Refilling ticks that refill each channel's empty allowance (``R``; 0 where there is no allowance)."""
        return np.where(self._ip[_CAP] > 0, self._ip[_COST] * self.peak_max_ticks // np.maximum(self._ip[_GAIN], 1), 0)

    @property
    def peak_ticks_left(self) -> np.ndarray:
        """Peak ticks each channel's budget holds now (whole ticks, rounded down)."""
        return self._ip[_BUDGET] // self._ip[_COST]

    @property
    def clamp_counts(self) -> np.ndarray:
        return self._ip[_NCLAMP]

    @property
    def nonfinite_counts(self) -> np.ndarray:
        return self._ip[_NNONFINITE]

    @property
    def peak_counts(self) -> np.ndarray:
        """Ticks each channel was limited to its peak range (a transient beyond ``[peak_lo, peak_hi]`` within the allowance)."""
        return self._ip[_NPEAK]

    def apply(self, values: np.ndarray, out: np.ndarray, force_safe: bool) -> int:
        """Write guarded ``values`` (float64 ``(n,)``) into ``out`` (float64 ``(n,)``); return the event count."""
        return guard_kernel(self._fp, self._ip, values, out, force_safe)

    def safe_values(self, out: np.ndarray) -> None:
        """Write every channel's safe value into ``out`` (for exit paths)."""
        out[:] = self._fp[_SAFE]

    def reset(self) -> None:
        """Refill every channel's peak allowance and zero the event counts."""
        self._ip[_BUDGET] = self._ip[_CAP]
        self._ip[_NCLAMP:_NPEAK + 1] = 0


@njit(cache=True)
def first_stale(last: np.ndarray, timeouts: np.ndarray, tick: int) -> int:
    """Index of the first input whose age ``tick - last`` exceeds its timeout, or -1."""
    for i in range(last.shape[0]):
        if tick - last[i] > timeouts[i]:
            return i
    return -1


@njit(cache=True)
def all_updated_after(last: np.ndarray, tick: int) -> bool:
    """True when every input was refreshed strictly after ``tick``."""
    for i in range(last.shape[0]):
        if last[i] <= tick:
            return False
    return True


_NEVER = np.iinfo(np.int64).min // 4


class Watchdog:
    """Sensor-staleness and overrun watchdog (rules in the module docstring).

    ``timeouts_ticks``: one int per sensor input, the largest allowed age in ticks.
    ``overrun_limit_ns``: a tick whose ``overrun_ns`` (passed to :meth:`check`) exceeds
    this trips the watchdog.
    """

    def __init__(self, timeouts_ticks: np.ndarray, overrun_limit_ns: int, log_capacity: int = 1000, emit_log: bool = True) -> None:
        t = np.atleast_1d(np.asarray(timeouts_ticks))
        if t.ndim != 1 or not (np.issubdtype(t.dtype, np.integer) or np.all(t == np.round(t))) or np.any(t < 0):
            raise ValueError(f"Watchdog: timeouts_ticks must be non-negative integers, one per sensor input, got {timeouts_ticks!r}")
        if int(overrun_limit_ns) < 0:
            raise ValueError(f"Watchdog: overrun_limit_ns must be >= 0, got {overrun_limit_ns!r}")
        self.timeouts = np.ascontiguousarray(t.astype(np.int64))
        self.overrun_limit_ns = int(overrun_limit_ns)
        self.last = np.full(self.timeouts.shape[0], _NEVER, dtype=np.int64)
        self.tripped = True
        self.reason = "startup"
        self.trip_tick = _NEVER
        self.events = 0
        self.stale_events = 0
        self.overrun_events = 0
        self.log: list[tuple[int, str, int]] = []
        self.log_capacity = int(log_capacity)
        self.emit_log = emit_log

    def fresh(self, index: int, tick: int) -> None:
        """Mark sensor input ``index`` as updated at ``tick``."""
        self.last[index] = tick

    def check(self, tick: int, overrun_ns: int) -> bool:
        """Evaluate the watchdog at ``tick``; True while outputs must be safe."""
        stale = first_stale(self.last, self.timeouts, tick)
        overrun = overrun_ns > self.overrun_limit_ns
        if stale >= 0 or overrun:
            self.trip_tick = tick
            if not self.tripped:
                self.tripped = True
                self.events += 1
                if stale >= 0:
                    self.reason, detail = "stale", int(stale)
                    self.stale_events += 1
                else:
                    self.reason, detail = "overrun", int(overrun_ns)
                    self.overrun_events += 1
                if len(self.log) < self.log_capacity:
                    self.log.append((int(tick), self.reason, detail))
                if self.emit_log:
                    if stale >= 0:
                        _log.warning("watchdog: tick %d: sensor input %d stale (timeout %d ticks); outputs safe", tick, stale, self.timeouts[stale])
                    else:
                        _log.warning("watchdog: tick %d: overrun %d ns > limit %d ns; outputs safe", tick, overrun_ns, self.overrun_limit_ns)
            return True
        if self.tripped:
            if all_updated_after(self.last, self.trip_tick):
                self.tripped = False
                self.reason = ""
                return False
            return True
        return False
