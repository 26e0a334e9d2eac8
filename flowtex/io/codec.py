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

The live loop's compiled, table-driven codecs built from the same :class:`SignalLayout`
objects live in :mod:`flowtex.io.codec_tables`; their names (``fast_ok``, ``pack_int64``,
``TableDecoder``, ``TableEncoder``, ``decode_packed``) still import from here, lazily, so
that importing this module loads no numba.
"""

from __future__ import annotations

import functools
import math
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import CodeType
from typing import Any

from cantools.database.can import Message

from ..errors import DataError
from ..moved import moved_names

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
        the DBC length, or one in which a bound float signal is NaN or inf (no
        measurement: written into a graph input it would poison every stateful
        node after it for the rest of the session).
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
        stores = []
        floats = []
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
                lines.append(f"    v{i} = ({expr}){conv}")
                stores.append(f"    t{i}[{int(idx)}] = v{i}")
                if s.is_float:
                    floats.append(f"v{i}")
        if floats:  # a NaN or inf float signal is no measurement: the frame is dropped whole, as the compiled decoder does
            ns["_finite"] = math.isfinite
            lines.append(f"    if not ({' and '.join(f'_finite({v})' for v in floats)}):")
            lines.append("        return False")
        lines.extend(stores)
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


@functools.lru_cache(maxsize=4096)
def _compiled(source: str, filename: str) -> CodeType:
    """The code object of a generated codec function: the same DBC message gives the same source in every CanIO a process
    builds (each session, replay and test opens the DBC anew), and compiling it is most of a codec's build time."""
    return compile(source, filename, "exec")


def _build(lines: list[str], ns: dict[str, Any], fname: str, msg: str) -> Callable:
    source = "\n".join(lines) + "\n"
    code = _compiled(source, f"<flowtex codec {msg}.{fname}>")
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


__getattr__ = moved_names(__name__, dict.fromkeys(("fast_ok", "pack_int64", "TableDecoder", "TableEncoder", "decode_packed"),
                                                  "flowtex.io.codec_tables"))
"""Names that moved to :mod:`flowtex.io.codec_tables` still import from here (lazily: codec_tables imports this module)."""
