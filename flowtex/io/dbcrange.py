"""What a DBC signal can carry: its sendable range, and what a value becomes once sent and decoded.

The live runtime sends an output's ``safe`` value on every safe frame and at every exit. If the
DBC cannot carry that value (its ``[min|max]`` excludes it, or the bit length cannot hold it),
the encoder clamps or saturates it and the device receives something else: a "safe" 0 A sent as
0.5 A. :func:`round_trip` encodes a physical value with flowtex's own codec (exactly what the
runtime sends: DBC clamp, ``round((v - offset) / scale)``, saturation or, for ``scale 1`` without
a range, wrap-around of the raw integer) and decodes the payload with cantools, an independent
decoder; :func:`check_value` compares the two within half an LSB (:func:`lsb`): the rounding to the nearest raw
value, no more. A whole LSB would pass a 1-bit ``Enable`` sent as 1 for a safe 0.

Physical values are in the signal's DBC unit.
"""

from __future__ import annotations

import math
import struct

import numpy as np
from cantools.database.can import Message, Signal

from .codec import MessageCodec


def raw_limits(sig: Signal) -> tuple[float, float]:
    """Smallest and largest raw value of ``sig``'s bit field (floats: the float32/float64 range)."""
    if sig.is_float:
        top = float(np.finfo(np.float32 if sig.length == 32 else np.float64).max)
        return -top, top
    if sig.is_signed:
        return float(-(1 << (sig.length - 1))), float((1 << (sig.length - 1)) - 1)
    return 0.0, float((1 << sig.length) - 1)


def sendable_range(sig: Signal) -> tuple[float, float]:
    """Physical range ``sig`` carries: its raw range scaled, intersected with the DBC ``[min|max]`` when given."""
    r0, r1 = raw_limits(sig)
    a, b = r0 * float(sig.scale) + float(sig.offset), r1 * float(sig.scale) + float(sig.offset)
    lo, hi = min(a, b), max(a, b)
    if sig.minimum is not None:
        lo = max(lo, float(sig.minimum))
    if sig.maximum is not None:
        hi = min(hi, float(sig.maximum))
    return lo, hi


def lsb(sig: Signal, value: float) -> float:
    """One least significant bit of ``sig`` at physical ``value`` (``|scale|``; floats: the float spacing there)."""
    if sig.is_float:
        dtype = np.float32 if sig.length == 32 else np.float64
        raw = (value - float(sig.offset)) / float(sig.scale)
        return float(np.spacing(dtype(abs(raw)))) * abs(float(sig.scale))
    return abs(float(sig.scale))


def round_trip(msg: Message, sig: Signal, value: float, codec: MessageCodec | None = None) -> float:
    """The physical value a receiver decodes (cantools) when flowtex sends ``value`` in ``sig`` (flowtex's codec)."""
    codec = codec or MessageCodec(msg)
    payload = codec.encode({sig.name: float(value)})
    return float(msg.decode(payload, decode_choices=False, scaling=True)[sig.name])


def check_value(msg: Message, sig: Signal, value: float, codec: MessageCodec | None = None) -> float | None:
    """None when ``value`` arrives as itself within half an LSB (the rounding); else the value that arrives instead."""
    try:
        got = round_trip(msg, sig, value, codec)
    except (OverflowError, ValueError, struct.error):  # beyond what a float32 field or the raw integer can pack
        return math.inf if value > 0 else -math.inf
    if math.isfinite(got) and abs(got - value) <= lsb(sig, value) / 2 * (1 + 1e-9):
        return None
    return got
