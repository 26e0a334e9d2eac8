"""``flowtex fit taps``: a tap library (tap_player's format) from a recording of taps (Culbertson & Kuchenbecker 2017 sec. 3.3.2).

1. Contact onsets from the normal force with hysteresis: contact starts when
   the force reaches ``on`` (0.1 N, the contact node's threshold) after a
   stretch of at least ``quiet_s`` (50 ms, ``--quiet``) without contact (force
   below ``off``, 0.05 N); the onset is then moved back to where the
   force left its out-of-contact floor (median + 4 robust sd of the samples
   below ``off``), so the cut starts with the impact, not a few ms into it.
   A recording that starts in contact therefore has no tap at its start (the
   tool was not seen arriving), and a bounce that leaves the surface for less
   than ``quiet_s`` is part of its tap, not a new one.
2. Each tap's acceleration (1-D, or 3 axes reduced by DFT321; zero-phase
   10 Hz high-pass as for textures) is cut for ``length`` (100 ms, Culbertson & Kuchenbecker 2017) from
   its onset.
3. Its incoming speed (mm/s) is the approach speed -(v . n) averaged over the
   ``approach_s`` (10 ms) before the onset, v the backward difference of the
   position (as the contact node computes it); or, with ``--speed``, the
   mean of that signal over the same window.
4. Taps whose recording ends within 100 ms of the onset, or with no incoming
   speed, are dropped (and said so); taps at equal speeds are averaged.

The spectral centroid SC = sum X^2 f / sum X^2 (Culbertson & Kuchenbecker 2017 eq. 4) is printed per
tap and averaged over the library played at 50, 60, ..., 100 mm/s
(flowtex.models.taps.spectral_centroid), Culbertson & Kuchenbecker 2017's hardness predictor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..dsp.contact import CONTACT_OFF_N, CONTACT_ON_N
from ..dsp.robust import robust_scale
from ..dsp.spectral import signal_centroid
from ..errors import DataError
from ..io.taplib import write_tap_library
from ..models.taps import TapLibrary, spectral_centroid
from .inputs import api_signals, atomic_output, check_highpass, check_not_constant, load, signal


@dataclass(frozen=True)
class Tap:
    """One detected tap: onset sample, incoming speed (mm/s), its transient (m/s^2) and spectral centroid (Hz)."""

    onset: int
    speed: float
    transient: np.ndarray
    centroid_hz: float


DEFAULT_QUIET_S = 0.05
MAX_TAP_S = 10.0
"""Longest ``--length`` and ``--quiet`` (s): a tap transient lasts ~0.1 s; 10 s is a recording, not a tap."""
"""Seconds without contact (force below ``off``) before an onset counts as a tap."""


def contact_onsets(force: np.ndarray, on: float = CONTACT_ON_N, off: float = CONTACT_OFF_N, quiet: int = 50) -> np.ndarray:
    """Sample indices of contact onsets (hysteresis ``on``/``off`` in N, moved back to the force's floor).

    An onset counts only after at least ``quiet`` consecutive samples below
    ``off`` (so never at the start of a recording that starts in contact).
    """
    force = np.asarray(force, float)
    below = force < off
    floor = float(np.median(force[below])) + 4.0 * robust_scale(force[below]) if np.any(below) else off
    floor = min(floor, off)
    onsets = []
    armed = False  # a stretch of `quiet` samples without contact has been seen since the last onset
    run = 0
    quiet = max(1, int(quiet))
    for t in range(force.shape[0]):
        if below[t]:
            run += 1
            armed = armed or run >= quiet
            continue
        run = 0
        if armed and force[t] >= on:
            armed = False
            k = t
            while k > 0 and force[k - 1] > floor:
                k -= 1
            onsets.append(k)
    return np.array(onsets, dtype=np.int64)


def approach_speed(position: np.ndarray, normal: np.ndarray, onset: int, rate: float, window: int) -> float:
    """Mean approach speed -(v . n) (mm/s) over ``window`` samples before ``onset``."""
    a = max(1, onset - window)
    if onset - a < 1:
        return float("nan")
    v = np.diff(position[a - 1:onset], axis=0) * rate
    n = normal[a:onset]
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    return float(np.mean(-np.sum(v * n, axis=1)))


def centroid(x: np.ndarray, rate: float) -> float:
    """Spectral centroid (Hz) of one transient (:func:`flowtex.dsp.spectral.signal_centroid`); 0.0 for a silent one."""
    value = signal_centroid(x, rate)
    return 0.0 if math.isnan(value) else value


def fit_taps(accel: np.ndarray, force: np.ndarray, rate: float, position: np.ndarray | None = None, normal: np.ndarray | None = None,
             speed: np.ndarray | None = None, length_s: float = 0.1, approach_s: float = 0.01, on: float = CONTACT_ON_N, off: float = CONTACT_OFF_N,
             where: str = "recording", quiet_s: float = DEFAULT_QUIET_S) -> tuple[list[Tap], list[str]]:
    """Detected taps (sorted by onset) and notes on dropped ones; see the module docstring."""
    rate, (accel, force, position, normal, speed) = api_signals(where, rate, {"position": 3, "normal": 3}, accel=accel, force=force,
                                                                position=position, normal=normal, speed=speed)
    length = int(round(length_s * rate))
    window = max(1, int(round(approach_s * rate)))
    onsets = contact_onsets(force, on, off, int(round(quiet_s * rate)))
    if onsets.size == 0:
        raise DataError(f"{where}: no tap: the force never reaches {on:g} N after {1000 * quiet_s:g} ms below {off:g} N "
                        "(a recording that starts in contact has no tap at its start); check --force names the normal force in N")
    n = accel.shape[0]
    if position is not None and normal is None:
        normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    taps, notes = [], []
    for t in onsets:
        if t + length > n:
            notes.append(f"tap at {t / rate:.3f} s dropped: the recording ends within {length_s * 1000:g} ms")
            continue
        if speed is not None:
            v = float(np.mean(speed[max(0, t - window):max(1, t)]))
        else:
            assert position is not None and normal is not None
            v = approach_speed(position, normal, int(t), rate, window)
        if not (np.isfinite(v) and v > 0):
            notes.append(f"tap at {t / rate:.3f} s dropped: no incoming speed ({v:.3g} mm/s)")
            continue
        tr = accel[t:t + length].copy()
        taps.append(Tap(int(t), v, tr, centroid(tr, rate)))
    if not taps:
        raise DataError(f"{where}: {onsets.size} contact onset(s) but no usable tap ({'; '.join(notes)})")
    return taps, notes


def library_from_taps(taps: list[Tap], rate: float, name: str) -> TapLibrary:
    """A TapLibrary sorted by speed; taps at equal speeds are averaged."""
    speeds = np.array([t.speed for t in taps])
    uniq = np.unique(speeds)
    tr = np.array([np.mean([t.transient for t in taps if t.speed == v], axis=0) for v in uniq])
    return TapLibrary(uniq, tr, rate, name)


def fit_tap_recording(recording: str | Path, accel: str, force: str, from_rate: float | None = None,
                      position: str | None = None, normal: str | None = None, speed: str | None = None,
                      length_s: float = 0.1, highpass_hz: float = 10.0,
                      name: str | None = None, quiet_s: float = DEFAULT_QUIET_S) -> tuple[TapLibrary, list[Tap], list[str], float]:
    """(library, taps, notes on dropped taps, rate in Hz) from one recording of taps; signals are named as the options.

    ``length_s`` (s) is cut after each onset; ``highpass_hz`` (0: none) is a zero-phase high-pass of the acceleration;
    an onset counts only after ``quiet_s`` seconds without contact.
    """
    from ..dsp.filter_design import zero_phase_highpass

    rec, rate = load(recording, from_rate)
    if not (np.isfinite(length_s) and 0.0 < length_s <= MAX_TAP_S):
        raise DataError(f"--length {length_s:g}: valid range is (0, {MAX_TAP_S:g}] s (Culbertson & Kuchenbecker 2017: 0.1 s)")
    if int(round(length_s * rate)) < 1:
        raise DataError(f"--length {length_s:g}: less than one sample at {rate:g} Hz; cut at least {1 / rate:g} s")
    if not (np.isfinite(quiet_s) and 0.0 <= quiet_s <= MAX_TAP_S):
        raise DataError(f"--quiet {quiet_s:g}: valid range is [0, {MAX_TAP_S:g}] s")
    check_highpass(highpass_hz, rate)
    acc = signal(rec, accel, "--accel", (1, 3))
    if acc.ndim == 2:
        from ..dsp.dft321 import dft321

        acc = dft321(acc)
    check_not_constant(acc, f"{recording}: signal {accel!r} (--accel)")
    f = signal(rec, force, "--force")
    pos = nrm = spd = None
    if position is not None:
        pos = signal(rec, position, "--position", (3,))
        nrm = signal(rec, normal, "--normal", (3,)) if normal else None
    elif speed is not None:
        spd = signal(rec, speed, "--speed")
    else:
        raise DataError(f"{recording}: give --position P (mm, 3 axes) or --speed S (approach speed, mm/s) to label taps")
    acc = zero_phase_highpass(acc, rate, highpass_hz)
    taps, notes = fit_taps(acc, f, rate, pos, nrm, spd, length_s, where=str(recording), quiet_s=quiet_s)
    return library_from_taps(taps, rate, name or Path(recording).stem), taps, notes, rate


def write_taps(path: str | Path, lib: TapLibrary, recording: str | Path) -> None:
    """Write the tap library atomically (docs/tap-library.md)."""
    with atomic_output(path) as tmp:
        write_tap_library(tmp, lib, notes=f"fitted by flowtex fit taps from {recording}")


def tap_table(taps: list[Tap], notes: list[str], lib: TapLibrary, rate: float) -> list[str]:
    """The lines ``flowtex fit taps`` prints: one per tap, the notes, the library's spectral centroid."""
    lines = [f"{'tap':>4} {'time s':>8} {'speed mm/s':>10} {'peak m/s^2':>10} {'centroid Hz':>11}"]
    for k, t in enumerate(taps):
        lines.append(f"{k:4d} {t.onset / rate:8.3f} {t.speed:10.1f} {float(np.max(np.abs(t.transient))):10.3f} {t.centroid_hz:11.1f}")
    lines += notes
    sc = spectral_centroid(lib)
    lines.append(f"{len(taps)} taps; spectral centroid over 50-100 mm/s (Culbertson & Kuchenbecker 2017 eq. 4): {sc:.1f} Hz")
    return lines
