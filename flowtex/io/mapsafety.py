"""Checks of a map's actuator messages as a whole: what the frames carry besides the bound signals, and who sends them.

Every actuator frame (safe and exit frames included) carries every signal of its message. Signals the map does not
bind are sent as physical 0 (:mod:`flowtex.io.codec`, rule 4), so that 0 must survive the DBC exactly as a bound
output's safe value must (:func:`flowtex.io.dbcrange.check_value`): a DBC ``Enable [1|1]`` would otherwise send
"enabled" in every frame meant to make the device safe. And the host must not transmit a message the DBC says the
device itself transmits (its ``BO_`` line's transmitter): two senders on one CAN ID. And what the guard lets through
must arrive within the clamp (:func:`check_clamps`).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence

import numpy as np
from cantools.database.can import Database

from .dbcrange import check_value, lsb, round_trip, sendable_range

Report = Callable[[tuple[int, int] | None, str], None]


def check_unbound_signals(db: Database, outputs: Sequence, add: Report) -> None:
    """Refuse an actuator message whose unbound signal would not arrive as physical 0 (the value it is sent as).

    ``outputs``: the map's output bindings (``signals`` as ``(message, signal)``, ``loc``, ``name``).
    """
    bound = {k for b in outputs for k in b.signals}
    seen: set[str] = set()
    for b in outputs:
        for m in dict.fromkeys(m for m, _ in b.signals):
            if m in seen:
                continue
            seen.add(m)
            msg = db.get_message_by_name(m)
            for sig in msg.signals:
                if (m, sig.name) in bound:
                    continue
                got = check_value(msg, sig, 0.0)
                if got is None:
                    continue
                lo, hi = sendable_range(sig)
                unit = f" {sig.unit}" if sig.unit else ""
                add((b.loc.line, b.loc.column),
                    f"output {b.name!r} sends message {m!r}, whose signal {sig.name!r} no output binds: it is sent as 0, "
                    f"which would arrive as {got:g}{unit} in every frame (the safe and exit frames too), because the DBC "
                    f"range of {m}.{sig.name} is [{lo:g}, {hi:g}]{unit}; bind {m}.{sig.name} to a graph output with a safe "
                    "value inside that range, or fix the DBC")


def check_transmitters(db: Database, inputs: Sequence, outputs: Sequence, add: Report) -> None:
    """Refuse an output message transmitted (per the DBC) by a node that transmits the map's sensor messages.

    The sensor messages' transmitters are the device; the host sending one of the device's own messages puts two
    senders on one CAN ID. Messages whose DBC names no transmitter are not judged.
    """
    device = {s: m for b in inputs for m, _ in b.signals for s in db.get_message_by_name(m).senders}
    for b in outputs:
        for m in dict.fromkeys(m for m, _ in b.signals):
            msg = db.get_message_by_name(m)
            both = [s for s in msg.senders if s in device]
            if both:
                add((b.loc.line, b.loc.column),
                    f"output {b.name!r} writes message {m!r} (CAN ID {msg.frame_id:#x}), which the DBC says {both[0]} "
                    f"transmits, as it does {device[both[0]]!r} that this map reads: the host would send on the device's own "
                    f"ID; bind the output to a message the host transmits")


def peak_low(lo: np.ndarray, hi: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Lower peak bound for a map's ``peak: {limit: L}``: the margin above HIGH mirrored below LOW, ``LOW - (L - HIGH)``.

    The map's ``limit`` is the largest value a transient may reach above the clamp
    (``|value| up to L`` for a symmetric clamp ``[-H, H]``, where this gives ``-L``);
    for an asymmetric clamp the same margin ``L - HIGH`` is allowed below ``LOW``.
    """
    return np.asarray(lo, dtype=np.float64) - (np.asarray(limit, dtype=np.float64) - np.asarray(hi, dtype=np.float64))


ROUNDING_SLACK = 0.01
"""How far beyond the clamp (a fraction of its width) the rounding to the DBC's LSB may carry a bound: a signal whose LSB
is at most 2 % of the clamp's width. A coarser one crosses the clamp by a step a device notices."""


def check_clamps(db: Database, outputs: Sequence, add: Report) -> None:
    """Refuse a clamp bound that the DBC sends as a value outside the clamp.

    The guard keeps each output inside its clamp in graph units; the encoder then rounds to the signal's LSB, and for
    ``scale 1`` without a DBC range wraps what the bit field cannot hold. Rounding is monotonic, so checking both bounds
    covers every value between them. A bound must arrive (encoded with flowtex's codec, decoded with cantools, back in
    graph units) as the DBC's range and bit width limit it (a DBC range narrower than the clamp is fine: the encoder
    clamps to it), not wrapped around (a clamp of [0, 10] on a 3-bit field sent 10 as 2), and no further beyond the
    clamp than :data:`ROUNDING_SLACK` of its width (a clamp of [-1, 1] A on a 0.6 A LSB sent 1.2 A; the rounding of the
    bundled DBC, 0.0001 A against a clamp 2 A wide, passes).
    ``outputs``: the map's output bindings (``signals``, ``scale``, ``offset``, ``lo``, ``hi``, ``loc``, ``name``).
    """
    for b in outputs:
        ranges = [("clamp LOW", "clamp HIGH", b.lo, b.hi)]
        if b.peak_limit is not None:  # what the guard lets through for up to max_ms (docs/live.md, "Peak rule")
            ranges.append(("peak range low", "peak limit", peak_low(b.lo, b.hi, b.peak_limit), b.peak_limit))
        found = _first_bound_problem(db, b, ranges)
        if found is not None:  # one line per output
            j, m, s, which, bound, problem = found
            comp = f"[{j}]" if len(b.signals) > 1 else ""
            add((b.loc.line, b.loc.column), f"output {b.name!r}{comp}: {which} {bound:g} cannot be sent in {m}.{s}: "
                                            f"{problem}; choose a clamp the DBC carries or fix the DBC")


def _first_bound_problem(db: Database, b, ranges: list) -> tuple | None:
    """(component, message, signal, bound's name, bound, why) of the first bound of ``ranges`` (name of the low and
    of the high bound, lows, highs; graph units) that output binding ``b`` cannot send, or None."""
    for low_name, high_name, lo, hi in ranges:
        for j, (m, s) in enumerate(b.signals):
            msg = db.get_message_by_name(m)
            sig = msg.get_signal_by_name(s)
            scale, offset = float(b.scale[j]), float(b.offset[j])
            for which, bound in ((low_name, float(lo[j])), (high_name, float(hi[j]))):
                problem = _clamp_bound_problem(msg, sig, bound * scale + offset, scale, offset, float(lo[j]), float(hi[j]))
                if problem is not None:
                    return j, m, s, which, bound, problem
    return None


def _clamp_bound_problem(msg, sig, physical: float, scale: float, offset: float, lo: float, hi: float) -> str | None:
    """Why ``physical`` (a clamp bound in the signal's unit) arrives outside ``[lo, hi]`` (graph units), or None."""
    unit = f" {sig.unit}" if sig.unit else ""
    s_lo, s_hi = sendable_range(sig)
    try:
        got = round_trip(msg, sig, physical)
        limited = round_trip(msg, sig, min(max(physical, s_lo), s_hi))
    except (OverflowError, ValueError, struct.error):
        return f"its bit field cannot pack it ({sig.length} bits)"
    if got != limited:
        return (f"it would arrive as {got:g}{unit}: the bit field ({sig.length} bits, scale {sig.scale:g}, no DBC range) "
                f"wraps it around instead of limiting it to [{s_lo:g}, {s_hi:g}]{unit}")
    g = (got - offset) / scale
    slack = ROUNDING_SLACK * (hi - lo) + 1e-9 * max(1.0, abs(lo), abs(hi))
    if math.isfinite(g) and lo - slack <= g <= hi + slack:
        return None
    step = lsb(sig, physical)
    return (f"it would arrive as {got:g}{unit}, {g:g} in graph units, beyond the clamp by more than {ROUNDING_SLACK:.0%} of "
            f"its width: the DBC's LSB there is {step:g}{unit} and the encoder rounds to the nearest step")
