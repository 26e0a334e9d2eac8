"""Table-driven CAN codecs for the live hot path: one compiled (numba) call per tick.

The generated Python functions of :mod:`flowtex.io.codec` cost about 0.5-2 us per message, most of it
bytecode dispatch, and three to four times that when the loop sleeps between ticks
and the caches are cold. The live loop therefore decodes every sensor frame of a
tick and encodes every actuator frame in one compiled call each, driven by integer
and float tables built from the same :class:`SignalLayout` objects. The arithmetic
is the same sequence of IEEE double operations as the Python functions (and as
cantools), so the values and bytes are identical; signals where that could not hold
(more than 52 bits, or integer scales whose products may exceed 2**53) keep the
Python functions (``fast_ok`` False), as do payloads longer than 8 bytes. This second path is kept because it
pays: benchmarks/bench_live_paths.py (section "codec") times it against the Python functions side by side.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

from ..cache import configure_numba_cache
from .codec import MessageCodec, SignalLayout

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)

# integer table columns (decode and encode)
_C_SLOT, _C_BIG, _C_LSB, _C_LEN, _C_SIGNED, _C_KIND, _C_INDEX, _C_IDENT, _C_HASMIN, _C_HASMAX, _C_IDRAW = range(11)
_NI = 11
# float table columns
_C_SCALE, _C_OFFSET, _C_K, _C_C, _C_MIN, _C_MAX, _C_RAWMIN, _C_RAWMAX = range(8)
_NF = 8
_KIND_INT, _KIND_F32, _KIND_F64 = 0, 1, 2


def fast_ok(codec: MessageCodec) -> bool:
    """True when every signal of ``codec`` can use the compiled table path with results identical to the Python path."""
    if codec.length > 8:
        return False
    for s in codec.layouts:
        if s.is_float:
            continue
        if s.length > 52 or not isinstance(s.scale, (int, float)) or not isinstance(s.offset, (int, float)):
            return False
        if isinstance(s.scale, int) and abs(s.scale) * (1 << s.length) >= 1 << 53:
            return False
        if isinstance(s.offset, int) and abs(s.offset) >= 1 << 52:
            return False
    return True


def _row(s: SignalLayout, slot: int, index: int, k: float, c: float) -> tuple[list[int], list[float]]:
    kind = (_KIND_F32 if s.length == 32 else _KIND_F64) if s.is_float else _KIND_INT
    ident = int(k == 1.0 and c == 0.0)
    idraw = int((not s.is_float) and s.scale == 1 and s.offset == 0)
    ints = [slot, int(s.big_endian), s.lsb, s.length, int(s.signed), kind, index, ident,
            int(s.minimum is not None), int(s.maximum is not None), idraw]
    floats = [float(s.scale), float(s.offset), float(k), float(c),
              float(s.minimum) if s.minimum is not None else 0.0, float(s.maximum) if s.maximum is not None else 0.0,
              float(s.raw_min), float(s.raw_max)]
    return ints, floats


def pack_int64(parts: Sequence[np.ndarray], header: int = 0) -> tuple[np.ndarray, list[np.ndarray], list[int]]:
    """One int64 buffer holding ``header`` free slots then every part; returns it, views of the parts, their offsets.

    The compiled calls take one buffer instead of one argument per table: each
    array argument costs the numba dispatcher a type check and an unboxing, about
    0.04 us warm and several times that right after the thread slept.
    """
    sizes = [int(np.size(p)) for p in parts]
    buf = np.zeros(header + sum(sizes), dtype=np.int64)
    views, offsets = [], []
    o = header
    for p, n in zip(parts, sizes, strict=True):
        v = buf[o:o + n]
        v[:] = np.ravel(p)
        views.append(v.reshape(np.shape(p)))
        offsets.append(o)
        o += n
    return buf, views, offsets


class TableDecoder:
    """Decode several sensor messages into one float64 arena with one compiled call.

    ``entries``: per message ``(codec, targets, marks)`` where ``targets[i]`` is
    ``(arena_index, k, c)`` or None for signal ``i`` (``arena[arena_index] = physical *
    k + c``) and ``marks`` lists indices into ``stamps`` set to the tick whenever the
    message is decoded (the watchdog's ``last`` array). Every codec must pass
    :func:`fast_ok`. Per tick: the caller stores each received payload's
    ``int.from_bytes(data, 'little', signed=True)`` in ``words[slot]`` (``slot_of``:
    frame id -> slot, ``lengths[slot]``: the payload length required, ``extended[slot]``: the
    frame format required), ORs ``1 << slot``
    into a mask and calls :meth:`run`.
    """

    def __init__(self, entries: Sequence[tuple[MessageCodec, Sequence[tuple[int, float, float] | None], Sequence[int]]]):
        if len(entries) > 62:
            raise ValueError("TableDecoder: at most 62 messages")
        ints: list[list[int]] = []
        floats: list[list[float]] = []
        marks: list[tuple[int, int]] = []
        self.slot_of: dict[int, int] = {}
        self.lengths: list[int] = []
        self.extended: list[bool] = []
        """Per slot: the message is an extended (29-bit) frame; a frame of the other format with its number is another message."""
        for slot, (codec, targets, wd) in enumerate(entries):
            if not fast_ok(codec):
                raise ValueError(f"TableDecoder: message {codec.name!r} needs the Python codec")
            self.slot_of[codec.frame_id] = slot
            self.lengths.append(codec.length)
            self.extended.append(bool(codec.is_extended))
            for s, t in zip(codec.layouts, targets, strict=True):
                if t is not None:
                    i, f = _row(s, slot, int(t[0]), t[1], t[2])
                    ints.append(i)
                    floats.append(f)
            marks.extend((slot, int(w)) for w in wd)
        n = max(1, len(entries))
        parts = [np.zeros(n, dtype=np.int64), np.array(self.lengths + [0] * (n + 1 - len(self.lengths)), dtype=np.int64),
                 np.array(marks, dtype=np.int64).reshape(len(marks), 2), np.array(ints, dtype=np.int64).reshape(len(ints), _NI),
                 np.zeros(1, dtype=np.int64)]
        self.ibuf, (self.words, self.blen, self.marks, self.itab, self._scratch), offs = pack_int64(parts, header=8)
        """All integer tables in one buffer (header: slots, then offset/size of each table); ``words`` etc. are views."""
        self.ibuf[:8] = [n, offs[0], offs[1], offs[2], len(marks), offs[3], len(ints), offs[4]]
        self.ftab = np.array(floats, dtype=np.float64).reshape(len(floats), _NF)
        self.fbuf = self.ftab.reshape(-1)
        self.has_float = [any(row[_C_SLOT] == slot and row[_C_KIND] != _KIND_INT for row in ints) for slot in range(len(entries))]
        """Per slot: a bound signal is a float, so a frame may be no measurement (NaN or inf; :meth:`finite`)."""

    def finite(self, words: np.ndarray, slot: int) -> bool:
        """True when the payload ``words[slot]`` is a measurement: every bound signal finite (:func:`slot_finite`)."""
        return bool(slot_finite(self.ibuf, self.fbuf, words, slot))

    def run(self, mask: int, tick: int, arena: np.ndarray, stamps: np.ndarray) -> None:
        """Decode the messages whose bit is set in ``mask`` from ``words`` into ``arena``; stamp their marks with ``tick``."""
        decode_packed(self.ibuf, self.fbuf, mask, tick, arena, stamps)


class TableEncoder:
    """Encode several actuator messages from one float64 vector into one byte buffer with one compiled call.

    ``entries``: per message ``(codec, sources)`` where ``sources[i]`` is
    ``(index, k, c)`` (physical = ``values[index] * k + c``) or None (physical 0,
    clamped) for signal ``i``. Message ``m``'s payload is written to
    ``payload[offsets[m]:offsets[m + 1]]`` (``payload`` is a bytearray, so slices copy
    straight into frame data).
    """

    def __init__(self, entries: Sequence[tuple[MessageCodec, Sequence[tuple[int, float, float] | None]]]):
        ints: list[list[int]] = []
        floats: list[list[float]] = []
        offsets = [0]
        for slot, (codec, sources) in enumerate(entries):
            if not fast_ok(codec):
                raise ValueError(f"TableEncoder: message {codec.name!r} needs the Python codec")
            for s, t in zip(codec.layouts, sources, strict=True):
                i, f = _row(s, slot, -1 if t is None else int(t[0]), 1.0 if t is None else t[1], 0.0 if t is None else t[2])
                ints.append(i)
                floats.append(f)
            offsets.append(offsets[-1] + codec.length)
        self.itab = np.array(ints, dtype=np.int64).reshape(len(ints), _NI)
        self.ftab = np.array(floats, dtype=np.float64).reshape(len(floats), _NF)
        self.offsets = np.array(offsets, dtype=np.int64)
        self.payload = bytearray(max(1, offsets[-1]))
        self.payload_view = np.frombuffer(self.payload, dtype=np.uint8)
        self.words = np.zeros((max(1, len(entries)), 2), dtype=np.int64)
        """Per message, its little- and big-endian integer words while encoding (scratch of :meth:`run`)."""
        self.scratch = np.zeros(1, dtype=np.int64)
        """One word for the float bit casts of :meth:`run`."""

    def int_tables(self) -> list[np.ndarray]:
        """The encoder's int64 tables in the order :meth:`rebind` takes them: offsets, words, scratch, itab."""
        return [self.offsets, self.words, self.scratch, self.itab]

    def rebind(self, ints: Sequence[np.ndarray], ftab: np.ndarray) -> None:
        """Use views holding the same values as :meth:`int_tables` and ``ftab`` from now on (e.g. inside one packed buffer
        a compiled caller takes as a single argument, see :func:`pack_int64`)."""
        for new, old in zip([*ints, ftab], [*self.int_tables(), self.ftab], strict=True):
            if new.shape != old.shape or new.dtype != old.dtype or not np.array_equal(new, old, equal_nan=True):
                raise ValueError("TableEncoder.rebind: each table must keep its shape, dtype and values")
        self.offsets, self.words, self.scratch, self.itab = ints
        self.ftab = ftab

    def run(self, values: np.ndarray) -> None:
        """Encode every message from ``values`` into ``payload``."""
        _encode_tables(values, self.itab, self.ftab, self.offsets, self.words, self.payload_view, self.scratch)


@njit(cache=True)
def _decode_tables(words, mask, tick, itab, ftab, blen, marks, arena, stamps, scratch):  # pragma: no cover - compiled
    # a frame with a NaN or inf float signal is no measurement: the whole frame is dropped (no input written, no
    # watchdog stamp), so that one corrupt frame cannot poison the graph's state for the rest of the session
    for r in range(itab.shape[0]):
        slot = itab[r, _C_SLOT]
        if (mask >> slot) & 1 and not _row_finite(words, r, itab, ftab, blen, scratch):
            mask &= ~(1 << slot)
    for r in range(itab.shape[0]):
        slot = itab[r, _C_SLOT]
        if (mask >> slot) & 1:
            arena[itab[r, _C_INDEX]] = _row_value(words, r, itab, ftab, blen, scratch)
    for i in range(marks.shape[0]):
        if (mask >> marks[i, 0]) & 1:
            stamps[marks[i, 1]] = tick


@njit(cache=True, inline="always")
def _row_value(words, r, itab, ftab, blen, scratch):  # pragma: no cover - compiled
    """The graph value of table row ``r`` (one bound signal) from its slot's payload word."""
    f32 = scratch.view(np.float32)
    u32 = scratch.view(np.uint32)
    f64 = scratch.view(np.float64)
    slot = itab[r, _C_SLOT]
    w = words[slot]
    if itab[r, _C_BIG]:
        L = blen[slot]
        wb = 0
        for b in range(L):
            wb = (wb << 8) | ((w >> (8 * b)) & 0xFF)
        w = wb
    n = itab[r, _C_LEN]
    kind = itab[r, _C_KIND]
    if kind == _KIND_F64:
        scratch[0] = w
        x = f64[0]
    elif kind == _KIND_F32:
        scratch[0] = 0
        u32[0] = np.uint32((w >> itab[r, _C_LSB]) & 0xFFFFFFFF)
        x = np.float64(f32[0])
    else:
        xi = (w >> itab[r, _C_LSB]) & ((1 << n) - 1)
        if itab[r, _C_SIGNED]:
            sb = 1 << (n - 1)
            xi = (xi ^ sb) - sb
        x = np.float64(xi)
    v = x * ftab[r, _C_SCALE] + ftab[r, _C_OFFSET]
    if not itab[r, _C_IDENT]:
        v = v * ftab[r, _C_K] + ftab[r, _C_C]
    return v


@njit(cache=True, inline="always")
def _row_finite(words, r, itab, ftab, blen, scratch):  # pragma: no cover - compiled
    """False when table row ``r`` is a float signal whose graph value is NaN or inf (an integer signal always is finite)."""
    return itab[r, _C_KIND] == _KIND_INT or np.isfinite(_row_value(words, r, itab, ftab, blen, scratch))


@njit(cache=True)
def slot_finite(ib, fb, words, slot):  # pragma: no cover - compiled
    """True when every bound signal of the payload ``words[slot]`` is finite (the packed tables of :func:`decode_packed`):
    the frame is a measurement :func:`decode_packed` would decode rather than drop."""
    ob, oi, r, osc = ib[2], ib[5], ib[6], ib[7]
    itab = ib[oi:oi + r * _NI].reshape((r, _NI))
    ftab = fb[:r * _NF].reshape((r, _NF))
    blen = ib[ob:ob + ib[0] + 1]
    scratch = ib[osc:osc + 1]
    for row in range(r):
        if itab[row, _C_SLOT] == slot and not _row_finite(words, row, itab, ftab, blen, scratch):
            return False
    return True


@njit(cache=True)
def decode_packed(ib, fb, mask, tick, arena, stamps):  # pragma: no cover - compiled
    """:meth:`TableDecoder.run` on the packed tables (``TableDecoder.ibuf``, ``fbuf``): one call per tick in the live loop."""
    n, ow, ob, om, m, oi, r, osc = ib[0], ib[1], ib[2], ib[3], ib[4], ib[5], ib[6], ib[7]
    _decode_tables(ib[ow:ow + n], mask, tick, ib[oi:oi + r * _NI].reshape((r, _NI)), fb[:r * _NF].reshape((r, _NF)),
                   ib[ob:ob + n + 1], ib[om:om + 2 * m].reshape((m, 2)), arena, stamps, ib[osc:osc + 1])


@njit(cache=True)
def _encode_tables(values, itab, ftab, offsets, words, payload, scratch):  # pragma: no cover - compiled
    f32 = scratch.view(np.float32)
    u32 = scratch.view(np.uint32)
    f64 = scratch.view(np.float64)
    words[:, :] = 0
    for r in range(itab.shape[0]):
        idx = itab[r, _C_INDEX]
        if idx < 0:
            v = 0.0
        else:
            v = values[idx]
            if not itab[r, _C_IDENT]:
                v = v * ftab[r, _C_K] + ftab[r, _C_C]
        if itab[r, _C_HASMAX] and v > ftab[r, _C_MAX]:
            v = ftab[r, _C_MAX]
        if itab[r, _C_HASMIN] and v < ftab[r, _C_MIN]:
            v = ftab[r, _C_MIN]
        n = itab[r, _C_LEN]
        kind = itab[r, _C_KIND]
        if kind == _KIND_F64:
            f64[0] = (v - ftab[r, _C_OFFSET]) / ftab[r, _C_SCALE]
            raw = scratch[0]
        elif kind == _KIND_F32:
            scratch[0] = 0
            f32[0] = np.float32((v - ftab[r, _C_OFFSET]) / ftab[r, _C_SCALE])
            raw = np.int64(u32[0])
        else:
            if itab[r, _C_IDRAW]:
                q = np.rint(v)  # no saturation (the Python path masks the exact integer)
                if abs(q) >= 4.0e18:
                    q = np.fmod(q, 2.0 ** n)  # exact, congruent modulo 2**n
            else:
                q = np.rint((v - ftab[r, _C_OFFSET]) / ftab[r, _C_SCALE])
                if q > ftab[r, _C_RAWMAX]:
                    q = ftab[r, _C_RAWMAX]
                elif q < ftab[r, _C_RAWMIN]:
                    q = ftab[r, _C_RAWMIN]
            raw = np.int64(q)
        if n < 64:
            raw = raw & ((1 << n) - 1)
        words[itab[r, _C_SLOT], itab[r, _C_BIG]] |= raw << itab[r, _C_LSB]
    for m in range(offsets.shape[0] - 1):
        a = offsets[m]
        L = offsets[m + 1] - a
        wl = words[m, 0]
        wb = words[m, 1]
        for b in range(L):
            payload[a + b] = np.uint8(((wl >> (8 * b)) | (wb >> (8 * (L - 1 - b)))) & 0xFF)
