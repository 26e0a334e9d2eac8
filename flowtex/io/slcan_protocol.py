"""slcan (Lawicel ASCII) protocol: one frame -> its line (:func:`encode_frame`), a byte stream -> frames (:class:`SlcanParser`).

Pure bytes work, no file descriptors: the transport that reads and writes them is
:class:`flowtex.io.slcan_fast.FastSlcanBus`.

Protocol (classic CAN, Lawicel/CANUSB slcan ASCII; every line ends with ``\\r``):

- ``tiiildd..`` standard data frame: ``iii`` 3 hex digits (<= 0x7FF), ``l`` DLC 0-8,
  ``dd`` 2 hex digits per data byte; ``Tiiiiiiiildd..`` extended (8 hex digits,
  <= 0x1FFFFFFF); ``riiil`` / ``Riiiiiiiil`` remote frames (DLC, no data).
- Optional timestamp: 4 more hex digits after the data (milliseconds, 0..0xEA5F, wraps
  every 60 s), sent by adapters after the ``Z1`` command.
- Replies: ``\\r`` alone is OK, ``\\a`` (BEL) is an error, ``z``/``Z`` acknowledge a
  transmitted frame; ``V``/``v``/``N``/``F`` answer version/serial/status queries.
- Host commands: ``O`` open, ``L`` open listen-only, ``C`` close, ``S0``-``S8`` bitrate
  (10k..1M), ``Z0``/``Z1`` timestamps off/on, and others the device role answers with OK.

Lines that cannot be a frame (bad hex, DLC > 8, identifier out of range, wrong length,
unknown letter, or more than ``MAX_LINE`` bytes without a terminator) are skipped and
counted in ``malformed``; the last few are kept in ``malformed_lines`` for diagnostics.
Lowercase hex is accepted on input; output uses uppercase. CAN FD is not supported.
"""

from __future__ import annotations

import binascii
import collections

from can import Message

MAX_LINE = 64
"""A pending line longer than this (bytes, no terminator yet) is discarded as malformed (the longest valid line has 30)."""

BITRATE_COMMANDS = {
    10_000: b"S0",
    20_000: b"S1",
    50_000: b"S2",
    100_000: b"S3",
    125_000: b"S4",
    250_000: b"S5",
    500_000: b"S6",
    750_000: b"S7",
    800_000: b"S7",
    1_000_000: b"S8",
}
"""Lawicel ``Sn`` bitrate commands (bit/s -> command; S7 is 800k in Lawicel's spec, 750k in python-can's table)."""

_HEX = b"0123456789ABCDEFabcdef"
_CR = b"\r"
_BEL = b"\x07"
_T, _X, _R, _RX = ord("t"), ord("T"), ord("r"), ord("R")
_TS_WRAP_MS = 60_000


def encode_frame(msg: Message, timestamp_ms: int | None = None) -> bytes:
    """One slcan line (with the ``\\r``) for a classic CAN ``msg``; optional 4-hex-digit ms timestamp.

    Raises ValueError for CAN FD, error frames, DLC > 8 or an identifier out of range.
    """
    if msg.is_fd or msg.is_error_frame:
        raise ValueError("slcan_fast: CAN FD and error frames are not supported")
    ident = msg.arbitration_id
    dlc = msg.dlc
    if not 0 <= dlc <= 8:
        raise ValueError(f"slcan_fast: DLC {dlc} out of range 0..8 for id 0x{ident:X}")
    if msg.is_extended_id:
        if not 0 <= ident <= 0x1FFFFFFF:
            raise ValueError(f"slcan_fast: extended id 0x{ident:X} out of range (max 0x1FFFFFFF)")
        head = b"R%08X%d" if msg.is_remote_frame else b"T%08X%d"
    else:
        if not 0 <= ident <= 0x7FF:
            raise ValueError(f"slcan_fast: standard id 0x{ident:X} out of range (max 0x7FF); set is_extended_id=True")
        head = b"r%03X%d" if msg.is_remote_frame else b"t%03X%d"
    line = head % (ident, dlc)
    if not msg.is_remote_frame:
        if len(msg.data) != dlc:
            raise ValueError(f"slcan_fast: id 0x{ident:X}: DLC {dlc} but {len(msg.data)} data bytes")
        line += binascii.hexlify(msg.data).upper()
    if timestamp_ms is not None:
        line += b"%04X" % (timestamp_ms % _TS_WRAP_MS)
    return line + _CR


class SlcanParser:
    """Incremental slcan line parser: :meth:`feed` chunks of any size; complete frames land in ``messages``.

    Counters: ``frames`` (parsed), ``malformed`` (skipped lines), ``acks`` (empty OK lines
    and ``z``/``Z`` transmit acks), ``errors`` (BEL replies). Non-frame lines go to
    ``commands`` in the device role and to ``replies`` (``V``/``v``/``N``/``F``) in the
    host role (anything else there is malformed).
    """

    def __init__(self, role: str = "host", channel: object = None, device_timestamps: bool = False, keep_malformed: int = 8) -> None:
        if role not in ("host", "device"):
            raise ValueError(f"slcan_fast: role must be 'host' or 'device', got {role!r}")
        self.device = role == "device"
        self.channel = channel
        self.device_timestamps = device_timestamps
        self.messages: collections.deque[Message] = collections.deque()
        self.commands: collections.deque[bytes] = collections.deque()
        self.replies: collections.deque[bytes] = collections.deque(maxlen=32)
        self.malformed_lines: collections.deque[bytes] = collections.deque(maxlen=keep_malformed)
        self.frames = 0
        self.malformed = 0
        self.acks = 0
        self.errors = 0
        self._partial = b""
        self._ts_last = -1
        self._ts_offset_ms = 0
        self._ts_anchor = 0.0

    def _bad(self, line: bytes) -> None:
        self.malformed += 1
        self.malformed_lines.append(bytes(line[:MAX_LINE]))

    def _device_time(self, raw_ms: int, host_now: float) -> float:
        """Unwrap a 0..59999 ms adapter timestamp into host-anchored seconds."""
        if self._ts_last < 0:
            self._ts_anchor = host_now - raw_ms / 1000.0
        elif raw_ms < self._ts_last:
            self._ts_offset_ms += _TS_WRAP_MS
        self._ts_last = raw_ms
        return self._ts_anchor + (self._ts_offset_ms + raw_ms) / 1000.0

    def feed(self, data: bytes, host_now: float) -> None:
        """Parse ``data`` (any chunk of the byte stream) received at host time ``host_now`` (s)."""
        if self._partial:
            data = self._partial + data
        if b"\n" in data:
            data = data.replace(b"\n", b"")
        lines = data.split(_CR)
        partial = lines.pop()
        if _BEL in partial:
            partial = self._bells(partial)
        if len(partial) > MAX_LINE:
            self._bad(partial)
            partial = b""
        self._partial = partial
        out = self.messages
        channel = self.channel
        for line in lines:
            if _BEL in line:
                line = self._bells(line)
            n = len(line)
            if n == 0:
                self.acks += 1
                continue
            k = line[0]
            if k == _T or k == _R:
                idlen = 3
                ext = False
            elif k == _X or k == _RX:
                idlen = 8
                ext = True
            else:
                self._other(line)
                continue
            head = idlen + 2
            if n < head or line.translate(None, _HEX)[1:]:
                self._bad(line)
                continue
            dlc = line[head - 1] - 48
            if dlc > 8:
                self._bad(line)
                continue
            remote = k == _R or k == _RX
            end = head if remote else head + 2 * dlc
            rest = n - end
            ident = int(line[1 : head - 1], 16)
            if (rest != 0 and rest != 4) or ident > (0x1FFFFFFF if ext else 0x7FF):
                self._bad(line)
                continue
            stamp = host_now
            if rest == 4:
                raw = int(line[end:], 16)
                if raw >= _TS_WRAP_MS:
                    self._bad(line)
                    continue
                if self.device_timestamps:
                    stamp = self._device_time(raw, host_now)
            data_bytes = binascii.unhexlify(line[head:end]) if end > head else None
            out.append(
                Message(
                    timestamp=stamp,
                    arbitration_id=ident,
                    is_extended_id=ext,
                    is_remote_frame=remote,
                    dlc=dlc,
                    data=data_bytes,
                    channel=channel,
                    is_rx=True,
                )
            )
            self.frames += 1

    def _bells(self, line: bytes) -> bytes:
        """Count BEL error replies (they end a reply like CR does); return what follows the last one."""
        pieces = line.split(_BEL)
        for piece in pieces[:-1]:
            self.errors += 1
            if piece:
                self._bad(piece)
        return pieces[-1]

    def _other(self, line: bytes) -> None:
        k = line[:1]
        if self.device:
            self.commands.append(bytes(line))
        elif len(line) == 1 and k in (b"z", b"Z"):
            self.acks += 1
        elif k in (b"V", b"v", b"N", b"F"):
            self.replies.append(bytes(line))
        else:
            self._bad(line)
