"""Checks of a map's actuator messages as a whole: what the frames carry besides the bound signals, and who sends them.

Every actuator frame (safe and exit frames included) carries every signal of its message. Signals the map does not
bind are sent as physical 0 (:mod:`flowtex.io.codec`, rule 4), so that 0 must survive the DBC exactly as a bound
output's safe value must (:func:`flowtex.io.dbcrange.check_value`): a DBC ``Enable [1|1]`` would otherwise send
"enabled" in every frame meant to make the device safe. And the host must not transmit a message the DBC says the
device itself transmits (its ``BO_`` line's transmitter): two senders on one CAN ID. And what the guard lets through
must arrive within the clamp (:func:`check_clamps`): the bounds it clamps to are moved inward onto the DBC's grid. And
a message longer than 8 bytes must be CAN FD to be sent at all (:func:`check_frame_lengths`).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from cantools.database.can import Database

from .codec import MessageCodec
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


CLASSIC_MAX_BYTES = 8
"""Most data bytes a classic CAN frame carries (CAN FD: 64)."""


def check_frame_lengths(db: Database, outputs: Sequence, add: Report) -> None:
    """Refuse an actuator message longer than a classic CAN frame that the DBC does not mark CAN FD.

    The runtime sends such a message as a classic frame of more than 8 bytes, which no bus takes: the session failed on
    its first send, before any frame reached the device, and could not send the safe values either (python-can's
    virtual bus, and so ``--simulate``, carries it without a word). A sensor message is not judged: a device may send
    it in CAN FD frames, which the decoder takes whatever the DBC says.
    """
    seen: set[str] = set()
    for b in outputs:
        for m in dict.fromkeys(m for m, _ in b.signals):
            msg = db.get_message_by_name(m)
            if m in seen or msg.length <= CLASSIC_MAX_BYTES or msg.is_fd:
                continue
            seen.add(m)
            add((b.loc.line, b.loc.column),
                f"output {b.name!r} sends message {m!r} (CAN ID {msg.frame_id:#x}), which the DBC gives {msg.length} data bytes "
                f"but does not mark CAN FD: a classic CAN frame carries at most {CLASSIC_MAX_BYTES}, so no bus would take it "
                "(nor the safe values); mark the message CAN FD in the DBC (its VFrameFormat attribute: StandardCAN_FD or "
                f"ExtendedCAN_FD) or give it at most {CLASSIC_MAX_BYTES} bytes in its BO_ line")


def peak_low(lo: np.ndarray, hi: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Lower peak bound for a map's ``peak: {limit: L}``: the margin above HIGH mirrored below LOW, ``LOW - (L - HIGH)``.

    The map's ``limit`` is the largest value a transient may reach above the clamp
    (``|value| up to L`` for a symmetric clamp ``[-H, H]``, where this gives ``-L``);
    for an asymmetric clamp the same margin ``L - HIGH`` is allowed below ``LOW``.
    """
    return np.asarray(lo, dtype=np.float64) - (np.asarray(limit, dtype=np.float64) - np.asarray(hi, dtype=np.float64))


FLOAT_NOISE = 8 * 2.0**-52
"""Relative float64 rounding allowed when a decoded value is compared with a clamp bound: the decoder's
``raw * scale + offset`` and the map's unit conversion each round to the nearest double (``3 * 0.1`` is
0.30000000000000004, not 0.3); many orders of magnitude below any LSB the bounds are snapped for."""

SNAP_STEPS = 16
"""Tries at moving one bound inward until what it sends arrives inside (one LSB, then float steps, normally succeed)."""


@dataclass(frozen=True)
class GuardBounds:
    """What the output guard clamps one output to (graph units, one value per component): the map's clamp and peak
    range, each bound that the DBC would send beyond them moved inward onto the DBC's grid (:func:`check_clamps`)."""

    lo: np.ndarray
    hi: np.ndarray
    peak_lo: np.ndarray
    """Lower end of the peak range (``lo`` without ``peak``)."""
    peak_hi: np.ndarray
    """Upper end of the peak range (``hi`` without ``peak``)."""


def map_ranges(b) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, low, high) of the ranges output binding ``b``'s map asks the guard to hold, graph units: the clamp, then
    the peak range when the map has a peak rule (what the guard lets through for up to max_ms; docs/live.md, "Peak
    rule")."""
    ranges = [("clamp", b.lo, b.hi)]
    if b.peak_limit is not None:
        ranges.append(("peak range", peak_low(b.lo, b.hi, b.peak_limit), b.peak_limit))
    return ranges


def _guarded(b) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`map_ranges` of ``b`` beside what its guard holds of each: (name, low, high, guarded low, guarded high)."""
    g = b.guard
    held = [(g.lo, g.hi), (g.peak_lo, g.peak_hi)]
    return [(what, lo, hi, *held[k]) for k, (what, lo, hi) in enumerate(map_ranges(b))]


def check_clamps(db: Database, outputs: Sequence, add: Report) -> None:
    """Refuse a clamp the DBC cannot send; set each output's :class:`GuardBounds` (``guard``) to what it can.

    The guard keeps each output inside its clamp in graph units; the encoder then rounds to the signal's LSB, and for
    ``scale 1`` without a DBC range wraps what the bit field cannot hold. A bound must arrive (encoded with flowtex's
    codec, decoded with cantools, back in graph units) as the DBC's range and bit width limit it (a DBC range narrower
    than the clamp is fine: the encoder clamps to it), not wrapped around (a clamp of [0, 10] on a 3-bit field sent 10
    as 2): else the map is refused. Rounding to the nearest step would still carry a bound up to half an LSB beyond
    the clamp (a clamp of [-1, 1] A on a 0.6 A LSB sent 1.2 A): such a bound is moved inward onto the grid
    (:func:`snap_bound`; 1 A becomes 0.6 A), for the clamp and for the peak range alike. Encoding is monotonic (every
    step of it is), so once both bounds arrive inside, every value the guard lets through between them does.
    ``outputs``: the map's output bindings (``signals``, ``scale``, ``offset``, ``lo``, ``hi``, ``safe``,
    ``peak_limit``, ``loc``, ``name``); ``guard`` is set on each that passes.
    """
    codecs: dict[str, MessageCodec] = {}
    for b in outputs:
        ends = {"clamp": ("clamp LOW", "clamp HIGH"), "peak range": ("peak range low", "peak limit")}
        ranges = [(*ends[what], lo, hi) for what, lo, hi in map_ranges(b)]
        found = _first_bound_problem(db, b, ranges)
        if found is None:
            found = _guard_bounds(db, b, ranges, codecs)
        if found is not None:  # one line per output
            j, m, s, which, bound, problem = found
            comp = f"[{j}]" if len(b.signals) > 1 else ""
            add((b.loc.line, b.loc.column), f"output {b.name!r}{comp}: {which} {bound:g} cannot be sent in {m}.{s}: "
                                            f"{problem}")


def _first_bound_problem(db: Database, b, ranges: list) -> tuple | None:
    """(component, message, signal, bound's name, bound, why) of the first bound of ``ranges`` (name of the low and
    of the high bound, lows, highs; graph units) that output binding ``b`` cannot send, or None."""
    for low_name, high_name, lo, hi in ranges:
        for j, (m, s) in enumerate(b.signals):
            msg = db.get_message_by_name(m)
            sig = msg.get_signal_by_name(s)
            scale, offset = float(b.scale[j]), float(b.offset[j])
            for which, bound in ((low_name, float(lo[j])), (high_name, float(hi[j]))):
                problem = _clamp_bound_problem(msg, sig, bound * scale + offset)
                if problem is not None:
                    return j, m, s, which, bound, problem + _FIX_CLAMP
    return None


_FIX_CLAMP = "; choose a clamp the DBC carries or fix the DBC"


def _clamp_bound_problem(msg, sig, physical: float) -> str | None:
    """Why ``physical`` (a clamp bound in the signal's unit) cannot be sent (packed, or limited without wrapping), or None."""
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
    return None


def _guard_bounds(db: Database, b, ranges: list, codecs: dict[str, MessageCodec]) -> tuple | None:
    """Set ``b.guard`` to ``ranges`` (the clamp, then the peak range if any) snapped inward (:func:`snap_bound`);
    a problem tuple as :func:`_first_bound_problem`'s when a range holds no value the DBC sends inside it, or the safe
    value would arrive beyond the clamp. A safe value between a snapped bound and the clamp's that arrives inside widens
    the guard's bounds to it (the guard requires ``lo <= safe <= hi``; all values between arrive inside too)."""
    snapped = []
    for low_name, high_name, lo, hi in ranges:
        new_lo, new_hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
        for j, (m, s) in enumerate(b.signals):
            if m not in codecs:
                codecs[m] = MessageCodec(db.get_message_by_name(m))
            send = Sender(codecs[m], s, float(b.scale[j]), float(b.offset[j]))
            a, z = float(lo[j]), float(hi[j])
            new_lo[j], new_hi[j] = snap_bound(send, a, a, z, +1), snap_bound(send, z, a, z, -1)
            if not new_lo[j] <= new_hi[j]:  # NaN (no try succeeded) or crossed: no step of the grid inside
                step = lsb(send.sig, float(lo[j]) * send.scale + send.offset)
                which, bound = (high_name, z) if math.isnan(new_hi[j]) and not math.isnan(new_lo[j]) else (low_name, a)
                return j, m, s, which, bound, (f"no value it sends arrives inside [{a:g}, {z:g}] (its LSB is {step:g}"
                                               f"{' ' + send.sig.unit if send.sig.unit else ''}, rounded to the nearest step)" + _FIX_CLAMP)
        snapped.append((new_lo, new_hi))
    (lo, hi), (plo, phi) = snapped[0], snapped[-1]
    for j, (m, s) in enumerate(b.signals):  # the guard sends the safe value as it is: it must arrive inside too
        send = Sender(codecs[m], s, float(b.scale[j]), float(b.offset[j]))
        safe, got = float(b.safe[j]), send.arrives(float(b.safe[j]))
        if not send.inside(got, float(b.lo[j]), float(b.hi[j])):
            unit = f" {send.sig.unit}" if send.sig.unit else ""
            return j, m, s, "safe value", safe, (f"it would arrive as {got:g}{unit}, beyond the clamp [{b.lo[j]:g}, "
                                                 f"{b.hi[j]:g}] (the DBC rounds to its LSB of {lsb(send.sig, got):g}{unit}); "
                                                 "choose a safe value on the DBC's grid")
        lo[j], hi[j] = min(lo[j], safe), max(hi[j], safe)  # both arrive inside, so does all between them
    # the peak range holds the clamp: a clamp bound that stays where the peak bound moved is still sent inside both
    b.guard = GuardBounds(lo, hi, np.minimum(plo, lo), np.maximum(phi, hi))
    return None


def moved_bounds(b) -> str | None:
    """What :func:`check_clamps` moved of output binding ``b``'s clamp and peak range, as ``"NAME: clamp [LOW, HIGH]
    guarded as [LOW', HIGH']"`` (graph units; one pair per component of a vector output), or None if nothing moved."""
    parts = [f"{what} {_pairs(lo, hi)} guarded as {_pairs(glo, ghi)}" for what, lo, hi, glo, ghi in _guarded(b)
             if not (np.array_equal(lo, glo) and np.array_equal(hi, ghi))]
    return f"{b.name}: {'; '.join(parts)}" if parts else None


SHRINK_WARN_SHARE = 0.01
"""A clamp or peak range that the DBC's grid narrows by more than this share of its width is named when a session
starts (:func:`shrunk_bounds`): the actuator then gets visibly less than the map asks for (a [-1, 1] A clamp on a
0.6 A LSB runs at +-0.6 A). Half an LSB of a fine grid (the bundled scene map: 0.0001 A of 2 A) stays quiet."""


def shrunk_bounds(outputs: Sequence) -> list[str]:
    """One line per output binding whose clamp or peak range :func:`check_clamps` narrowed by more than
    :data:`SHRINK_WARN_SHARE` of its width (:func:`moved_bounds`' text, and the fix)."""
    lines = []
    for b in outputs:
        lost = max(float(np.max(((glo - lo) + (hi - ghi)) / np.maximum(hi - lo, 1e-300)))
                   for _, lo, hi, glo, ghi in _guarded(b))
        if lost > SHRINK_WARN_SHARE:
            lines.append(f"{moved_bounds(b)}: the DBC's LSB is too coarse to send the bounds the map asks for, so the "
                         "guard keeps to the nearest values it can send (a finer DBC signal or a clamp on its grid avoids it)")
    return lines


def _pairs(lo: np.ndarray, hi: np.ndarray) -> str:
    pairs = [f"[{a:.6g}, {z:.6g}]" for a, z in zip(lo, hi, strict=True)]
    return pairs[0] if len(pairs) == 1 else f"[{', '.join(pairs)}]"


class Sender:
    """One output component as the runtime sends it: graph value -> ``value * scale + offset`` (the map's) -> flowtex's
    encoder of the message (the generated Python one; the compiled tables give the same bytes) -> decoded by cantools."""

    def __init__(self, codec: MessageCodec, signal: str, scale: float, offset: float):
        self.msg = codec.message
        self.sig = self.msg.get_signal_by_name(signal)
        self.scale, self.offset = scale, offset
        self._value = np.zeros(1)
        sources = [None] * len(codec.signals)
        sources[codec.index[signal]] = (self._value, 0, scale, offset)
        self._encode = codec.encoder(sources)
        self._buf = bytearray(codec.length)

    def arrives(self, value: float) -> float:
        """The physical value (DBC unit) a receiver decodes when the guard lets ``value`` (graph units) through."""
        self._value[0] = value
        self._encode(self._buf)
        return float(self.msg.decode(bytes(self._buf), decode_choices=False, scaling=True)[self.sig.name])

    def inside(self, physical: float, lo: float, hi: float) -> bool:
        """True if the decoded ``physical`` is, in graph units, within ``[lo, hi]`` (up to :data:`FLOAT_NOISE`)."""
        g = (physical - self.offset) / self.scale
        noise = FLOAT_NOISE * ((abs(physical) + abs(float(self.sig.offset)) + abs(self.offset)) / abs(self.scale)
                               + max(abs(lo), abs(hi)))
        return math.isfinite(g) and lo - noise <= g <= hi + noise


def snap_bound(send: Sender, bound: float, lo: float, hi: float, inward: int) -> float:
    """``bound`` (graph units; ``inward`` +1 for a low bound, -1 for a high one) if what it sends arrives within
    ``[lo, hi]``; else the graph value of the DBC step one LSB inward of what it sends (nudged by float steps until it
    does arrive inside); NaN if :data:`SNAP_STEPS` tries fail. Changes nothing for a bound on the grid."""
    g = bound
    for _ in range(SNAP_STEPS):
        p = send.arrives(g)
        if send.inside(p, lo, hi):
            return g
        target = p + inward * math.copysign(lsb(send.sig, p), send.scale)  # one step inward, in the signal's unit
        nxt = (target - send.offset) / send.scale
        g = nxt if (nxt - g) * inward > 0 else math.nextafter(g, inward * math.inf)
        if not lo <= g <= hi:  # past the other bound: no step of the grid arrives inside
            break
    return math.nan
