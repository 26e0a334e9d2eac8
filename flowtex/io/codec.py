"""Precompiled CAN message codecs generated from a DBC message.

cantools' ``Message.encode``/``decode`` cost 2-7 us per message: too slow for
five frames per 1 ms tick. For each message we generate the source of plain
Python functions that turn the payload into one integer (``int.from_bytes``,
little- or big-endian word), extract every signal with one shift and one mask,
and scale it with the same expression cantools uses, so decoded values equal
cantools' bit for bit. Encoding packs the word back with ``struct.pack_into``
into a preallocated ``bytearray`` (the data of a reused ``can.Message``).

Signal layout (bit numbering as in DBC files):

* little endian (Intel, ``@1``): ``start`` is the least significant bit;
  bit ``8*b + k`` of the little-endian word is bit ``k`` of byte ``b``.
* big endian (Motorola, ``@0``): ``start`` is the most significant bit in the
  "sawtooth" numbering; in the big-endian word of an ``L``-byte payload that
  bit has index ``8*(L-1-start//8) + start%8`` and the signal occupies the
  ``length`` bits below it, contiguously.

Encoding rules (decided here, documented in docs/live.md):

1. the physical value is clamped to the DBC ``[minimum, maximum]`` when the DBC
   gives a range (``[0|0]`` means none);
2. raw = ``round((value - offset) / scale)``, exactly cantools' formula
   (Python's round-half-to-even);
3. raw is saturated to what the bit length can hold (never wraps around);
4. signals of the message that nobody binds are sent as physical 0 (clamped).

Value tables (choices) are ignored: signals are numbers. NaN cannot be encoded
(``round`` raises ValueError); the live runtime replaces NaN with the output's
safe value before encoding. Multiplexed messages are not supported.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from cantools.database.can import Message
from numba import njit

from ..cache import configure_numba_cache
from ..errors import DataError

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)

_PACK_FORMATS = {1: "B", 2: "H", 4: "I", 8: "Q"}


@dataclass(frozen=True)
class SignalLayout:
    """Where one signal sits in its message's integer word, and how it scales."""

    name: str
    big_endian: bool
    lsb: int
    """Index of the signal's least significant bit in the little (or big) endian word."""
    length: int
    signed: bool
    is_float: bool
    scale: Any
    offset: Any
    minimum: float | None
    maximum: float | None
    unit: str

    @property
    def raw_min(self) -> int:
        return -(1 << (self.length - 1)) if self.signed else 0

    @property
    def raw_max(self) -> int:
        return (1 << (self.length - 1)) - 1 if self.signed else (1 << self.length) - 1


Target = tuple[Any, int, float, float]
"""``(array, index, scale, offset)``: ``array[index] = physical * scale + offset``
when decoding, ``physical = array[index] * scale + offset`` when encoding."""


class MessageCodec:
    """Fast encoder/decoder for one DBC message (see the module docstring)."""

    def __init__(self, message: Message):
        if message.is_multiplexed():
            raise DataError(f"message {message.name!r} is multiplexed; flowtex maps only plain messages")
        self.message = message
        self.name: str = message.name
        self.frame_id: int = message.frame_id
        self.is_extended: bool = bool(message.is_extended_frame)
        self.is_fd: bool = bool(getattr(message, "is_fd", False))
        self.length: int = int(message.length)
        self.layouts: list[SignalLayout] = [self._layout(s) for s in message.signals]
        self.signals: list[str] = [s.name for s in self.layouts]
        self.index: dict[str, int] = {n: i for i, n in enumerate(self.signals)}
        self._decode_list = self._compile_decoder(None, generic=True)
        self._encode_into = self._compile_encoder(None, generic=True)

    def _layout(self, sig: Any) -> SignalLayout:
        L = self.length
        if sig.byte_order == "little_endian":
            lsb = int(sig.start)
        else:
            msb = 8 * (L - 1 - sig.start // 8) + sig.start % 8
            lsb = msb - sig.length + 1
        if lsb < 0 or lsb + sig.length > 8 * L:
            raise DataError(f"message {self.name!r}: signal {sig.name!r} does not fit in {L} bytes")
        if sig.is_float and sig.length not in (32, 64):
            raise DataError(f"message {self.name!r}: float signal {sig.name!r} must be 32 or 64 bits long")
        return SignalLayout(sig.name, sig.byte_order != "little_endian", lsb, int(sig.length), bool(sig.is_signed),
                            bool(sig.is_float), sig.scale, sig.offset, sig.minimum, sig.maximum, sig.unit or "")

    # --- generic (allocating) API, for tests, tools and the simulator's setup ---
    def decode(self, data: bytes | bytearray) -> list[float]:
        """Physical values of every signal (in DBC order), as cantools would decode them."""
        values = self._decode_list(data)
        if values is None:
            raise DataError(f"message {self.name!r}: expected {self.length} data bytes, got {len(data)}")
        return values

    def encode(self, values: Sequence[float] | dict[str, float]) -> bytes:
        """Payload for ``values`` (a sequence in DBC order, or a name -> value dict; missing names are 0)."""
        if isinstance(values, dict):
            unknown = [k for k in values if k not in self.index]
            if unknown:
                raise DataError(f"message {self.name!r} has no signal(s) {', '.join(unknown)}")
            values = [values.get(n, 0.0) for n in self.signals]
        elif len(values) != len(self.signals):
            raise DataError(f"message {self.name!r} has {len(self.signals)} signals, got {len(values)} values")
        buf = bytearray(self.length)
        self._encode_into(buf, values)
        return bytes(buf)

    # --- hot path -----------------------------------------------------
    def decoder(self, targets: Sequence[Target | None]) -> Callable[[Any], bool]:
        """``f(data) -> bool`` writing each bound signal straight into its target array.

        ``targets[i]`` belongs to signal ``self.signals[i]`` (None: ignore the
        signal). Returns False (and writes nothing) for a payload shorter than
        the DBC length.
        """
        if len(targets) != len(self.signals):
            raise ValueError("one target per signal")
        return self._compile_decoder(list(targets), generic=False)

    def encoder(self, sources: Sequence[Target | None]) -> Callable[[bytearray], None]:
        """``f(buf)`` packing the message into ``buf`` (a bytearray of ``length`` bytes).

        ``sources[i]`` gives signal ``i``'s physical value as
        ``array[index] * scale + offset``; None sends physical 0 (clamped).
        """
        if len(sources) != len(self.signals):
            raise ValueError("one source per signal")
        return self._compile_encoder(list(sources), generic=False)

    # --- code generation ----------------------------------------------
    def _words(self) -> tuple[bool, bool]:
        return any(not s.big_endian for s in self.layouts), any(s.big_endian for s in self.layouts)

    def _compile_decoder(self, targets: list[Target | None] | None, generic: bool) -> Callable:
        L = self.length
        has_little, has_big = self._words()
        ns: dict[str, Any] = {"_f32": _f32_from_bits, "_f64": _f64_from_bits, "_from": int.from_bytes}
        lines = ["def decode(data):", f"    if len(data) != {L}:", f"        if len(data) < {L}:",
                 f"            return {'None' if generic else 'False'}", f"        data = bytes(data[:{L}])"]
        if has_little:
            lines.append("    wl = _from(data, 'little')")
        if has_big:
            lines.append("    wb = _from(data, 'big')")
        results = []
        for i, s in enumerate(self.layouts):
            if not generic and targets[i] is None:
                continue
            word = "wb" if s.big_endian else "wl"
            lines.append(f"    x = ({word} >> {s.lsb}) & {(1 << s.length) - 1:#x}")
            if s.is_float:
                lines.append(f"    x = _f{s.length}(x)")
            elif s.signed:
                sb = 1 << (s.length - 1)
                lines.append(f"    x = (x ^ {sb:#x}) - {sb:#x}")
            expr = f"x * {s.scale!r} + {s.offset!r}"
            if generic:
                lines.append(f"    v{i} = float({expr})")
                results.append(f"v{i}")
            else:
                arr, idx, k, c = targets[i]
                ns[f"t{i}"] = arr
                conv = "" if (k == 1.0 and c == 0.0) else f" * {float(k)!r} + {float(c)!r}"
                lines.append(f"    t{i}[{int(idx)}] = ({expr}){conv}")
        lines.append(f"    return [{', '.join(results)}]" if generic else "    return True")
        return _build(lines, ns, "decode", self.name)

    def _compile_encoder(self, sources: list[Target | None] | None, generic: bool) -> Callable:
        L = self.length
        has_little, has_big = self._words()
        ns: dict[str, Any] = {"_b32": _bits_from_f32, "_b64": _bits_from_f64, "_from": int.from_bytes}
        lines = ["def encode(buf, values=None):" if generic else "def encode(buf):", "    wl = 0", "    wb = 0"]
        for i, s in enumerate(self.layouts):
            if generic:
                lines.append(f"    v = values[{i}]")
            elif sources[i] is None:
                lines.append("    v = 0.0")
            else:
                arr, idx, k, c = sources[i]
                ns[f"s{i}"] = arr
                conv = "" if (k == 1.0 and c == 0.0) else f" * {float(k)!r} + {float(c)!r}"
                lines.append(f"    v = s{i}[{int(idx)}]{conv}")
            if s.maximum is not None:
                lines.append(f"    if v > {float(s.maximum)!r}:\n        v = {float(s.maximum)!r}")
            if s.minimum is not None:
                lines.append(f"    if v < {float(s.minimum)!r}:\n        v = {float(s.minimum)!r}")
            word = "wb" if s.big_endian else "wl"
            if s.is_float:
                lines.append(f"    r = _b{s.length}((v - {s.offset!r}) / {s.scale!r})")
            elif s.scale == 1 and s.offset == 0:
                lines.append("    r = round(v)")  # cantools' IdentityConversion: exact for big ints
            else:
                lines.append(f"    r = round((v - {s.offset!r}) / {s.scale!r})")
                lines.append(f"    if r > {s.raw_max}:\n        r = {s.raw_max}\n    elif r < {s.raw_min}:\n        r = {s.raw_min}")
            lines.append(f"    {word} |= (r & {(1 << s.length) - 1:#x}) << {s.lsb}")
        fmt = _PACK_FORMATS.get(L)
        if has_big and not has_little:
            if fmt:
                ns["_pack"] = struct.Struct(">" + fmt).pack_into
                lines.append("    _pack(buf, 0, wb)")
            else:
                lines.append(f"    buf[:] = wb.to_bytes({L}, 'big')")
        else:
            if has_big:
                lines.append(f"    wl |= _from(wb.to_bytes({L}, 'big'), 'little')")
            if fmt:
                ns["_pack"] = struct.Struct("<" + fmt).pack_into
                lines.append("    _pack(buf, 0, wl)")
            elif L:
                lines.append(f"    buf[:] = wl.to_bytes({L}, 'little')")
        return _build(lines, ns, "encode", self.name)


def _build(lines: list[str], ns: dict[str, Any], fname: str, msg: str) -> Callable:
    source = "\n".join(lines) + "\n"
    code = compile(source, f"<flowtex codec {msg}.{fname}>", "exec")
    exec(code, ns)  # noqa: S102 - source generated above from DBC numbers only
    fn = ns[fname]
    fn.source = source
    return fn


_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_F32 = struct.Struct("<f")
_F64 = struct.Struct("<d")


def _f32_from_bits(bits: int) -> float:
    return _F32.unpack(_U32.pack(bits))[0]


def _f64_from_bits(bits: int) -> float:
    return _F64.unpack(_U64.pack(bits))[0]


def _bits_from_f32(value: float) -> int:
    return _U32.unpack(_F32.pack(value))[0]


def _bits_from_f64(value: float) -> int:
    return _U64.unpack(_F64.pack(value))[0]


def build_codecs(db: Any) -> dict[str, MessageCodec]:
    """One codec per non-multiplexed message of a cantools database, by message name."""
    return {m.name: MessageCodec(m) for m in db.messages if not m.is_multiplexed()}


# --- table-driven codecs for the live hot path (one numba call per tick) -------------------
#
# The generated Python functions above cost about 0.5-2 us per message, most of it
# bytecode dispatch, and three to four times that when the loop sleeps between ticks
# and the caches are cold. The live loop therefore decodes every sensor frame of a
# tick and encodes every actuator frame in one compiled call each, driven by integer
# and float tables built from the same :class:`SignalLayout` objects. The arithmetic
# is the same sequence of IEEE double operations as the Python functions (and as
# cantools), so the values and bytes are identical; signals where that could not hold
# (more than 52 bits, or integer scales whose products may exceed 2**53) keep the
# Python functions (``fast_ok`` False), as do payloads longer than 8 bytes. This second path is kept because it
# pays: benchmarks/bench_live_paths.py (section "codec") times it against the Python functions side by side.

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
    frame id -> slot, ``lengths[slot]``: the payload length required), ORs ``1 << slot``
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
        for slot, (codec, targets, wd) in enumerate(entries):
            if not fast_ok(codec):
                raise ValueError(f"TableDecoder: message {codec.name!r} needs the Python codec")
            self.slot_of[codec.frame_id] = slot
            self.lengths.append(codec.length)
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
    f32 = scratch.view(np.float32)
    u32 = scratch.view(np.uint32)
    f64 = scratch.view(np.float64)
    for r in range(itab.shape[0]):
        slot = itab[r, _C_SLOT]
        if not (mask >> slot) & 1:
            continue
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
        arena[itab[r, _C_INDEX]] = v
    for i in range(marks.shape[0]):
        if (mask >> marks[i, 0]) & 1:
            stamps[marks[i, 1]] = tick


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
