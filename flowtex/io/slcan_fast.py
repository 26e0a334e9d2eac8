"""Fast slcan (Lawicel ASCII) CAN transport over a tty or a pseudo-terminal.

Why. python-can's stock ``slcan`` interface reads one byte per call through pyserial and
manages a few thousand frames/s; a 1 kHz haptic loop with several frames per tick in each
direction needs more headroom. :class:`FastSlcanBus` reads whatever is available in one
``os.read`` (up to ``chunk_size`` bytes) on a non-blocking fd, waits with ``select``,
splits complete ``\\r``-terminated lines and parses them with a few bytes operations, and
writes each frame (or a batch, :meth:`FastSlcanBus.send_many`) with one ``os.write``.

Protocol (classic CAN, Lawicel/CANUSB slcan ASCII; every line ends with ``\\r``):

- ``tiiildd..`` standard data frame: ``iii`` 3 hex digits (<= 0x7FF), ``l`` DLC 0-8,
  ``dd`` 2 hex digits per data byte; ``Tiiiiiiiildd..`` extended (8 hex digits,
  <= 0x1FFFFFFF); ``riiil`` / ``Riiiiiiiil`` remote frames (DLC, no data).
- Optional timestamp: 4 more hex digits after the data (milliseconds, 0..0xEA5F, wraps
  every 60 s), sent by adapters after the ``Z1`` command.
- Replies: ``\\r`` alone is OK, ``\\a`` (BEL) is an error, ``z``/``Z`` acknowledge a
  transmitted frame; ``V``/``v``/``N``/``F`` answer version/serial/status queries.
- Host commands: ``O`` open, ``L`` open listen-only, ``C`` close, ``S0``-``S8`` bitrate
  (10k..1M), ``Z0``/``Z1`` timestamps off/on, and others this transport answers with OK.

Lines that cannot be a frame (bad hex, DLC > 8, identifier out of range, wrong length,
unknown letter, or more than ``MAX_LINE`` bytes without a terminator) are skipped and
counted in ``malformed``; the last few are kept in ``malformed_lines`` for diagnostics.
Lowercase hex is accepted on input; output uses uppercase. CAN FD is not supported.

Roles. ``role="host"`` (default) is the computer side: on open it sends ``C``, the
bitrate command if ``bitrate`` is given, and ``O`` (``L`` when ``listen_only``); on
shutdown ``C``. ``role="device"`` is the adapter side, for simulators: it answers every
command line (OK, or a version/status reply), records the commands in ``commands``, keeps
``is_open`` from ``O``/``L``/``C``, appends millisecond timestamps to the frames it sends
while ``Z1`` is in force, and drops (and counts in ``tx_dropped``) frames sent while the
channel is closed, as a real adapter does.

Across processes. :func:`open_pty` creates a pseudo-terminal in raw mode and keeps both
ends open: a device simulator serves ``FastSlcanBus(pty.master_fd, role="device")`` and
prints ``pty.slave_path`` (``/dev/pts/N``); the runtime in another process opens that path
(``FastSlcanBus("/dev/pts/N")``), and may reconnect since the simulator keeps the slave
end open.

Selecting it in python-can (``can.Bus(interface="flowtex_slcan", channel=...)``, so the
CLI's ``--bus`` can name it): python-can finds third-party interfaces through the
``can.interface`` entry-point group, i.e. in pyproject.toml::

    [project.entry-points."can.interface"]
    flowtex_slcan = "flowtex.io.slcan_fast:FastSlcanBus"

(followed by a reinstall, ``pip install -e .``). :func:`register_interface` does the same
at run time for an installation without that entry point.

Timestamps. By default each message is stamped with the host's ``time.time()`` at the
read that delivered it (like the stock interface). With ``device_timestamps=True`` frames
carrying an adapter timestamp are stamped with the unwrapped device time, anchored to the
host clock at the first such frame.
"""

from __future__ import annotations

import binascii
import collections
import errno
import os
import select
import termios
import time
import tty
from dataclasses import dataclass

import can
from can import BusABC, CanOperationError, Message

INTERFACE_NAME = "flowtex_slcan"
"""Name under which :func:`register_interface` (or the entry point) makes this bus known to python-can."""

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
_BAUD = {
    9600: termios.B9600,
    19200: termios.B19200,
    38400: termios.B38400,
    57600: termios.B57600,
    115200: termios.B115200,
    230400: termios.B230400,
    460800: termios.B460800,
    921600: termios.B921600,
}


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


def _set_raw(fd: int, baudrate: int | None) -> None:
    """Raw 8-bit mode (no echo, no CR/NL translation) and, for real serial ports, the baud rate."""
    tty.setraw(fd, termios.TCSANOW)
    if baudrate is not None:
        if baudrate not in _BAUD:
            raise ValueError(f"slcan_fast: tty_baudrate {baudrate} not supported; use one of {sorted(_BAUD)}")
        attrs = termios.tcgetattr(fd)
        attrs[4] = attrs[5] = _BAUD[baudrate]
        termios.tcsetattr(fd, termios.TCSANOW, attrs)


@dataclass
class SlcanPty:
    """A pseudo-terminal pair in raw mode: the device side serves ``master_fd``; hosts open ``slave_path``."""

    master_fd: int
    slave_fd: int
    slave_path: str

    def close(self) -> None:
        """Close both ends (hosts still connected then see end-of-file)."""
        for fd in (self.master_fd, self.slave_fd):
            try:
                os.close(fd)
            except OSError:
                pass


def open_pty() -> SlcanPty:
    """Create a raw-mode pty pair for an slcan device simulator (see the module docstring)."""
    master, slave = os.openpty()
    _set_raw(slave, None)
    _set_raw(master, None)
    return SlcanPty(master_fd=master, slave_fd=slave, slave_path=os.ttyname(slave))


class FastSlcanBus(BusABC):
    """python-can bus speaking slcan on a tty/pty path or an already open fd, in large chunks.

    ``channel``: a device path (``/dev/ttyACM0``, ``/dev/pts/5``; an ``@baud`` suffix is
    accepted like the stock interface) or an int file descriptor (not closed by
    :meth:`shutdown` unless ``close_fd=True``). ``bitrate``: CAN bit/s for the ``Sn``
    command (host role). ``tty_baudrate``: serial line speed for real USB-serial adapters
    (None leaves it; irrelevant for ptys and USB CDC). ``chunk_size``: bytes per read.
    See the module docstring for roles and timestamps.
    """

    def __init__(
        self,
        channel: str | int,
        bitrate: int | None = None,
        role: str = "host",
        listen_only: bool = False,
        tty_baudrate: int | None = None,
        device_timestamps: bool = False,
        chunk_size: int = 65536,
        close_fd: bool | None = None,
        **kwargs,
    ) -> None:
        if role not in ("host", "device"):
            raise ValueError(f"slcan_fast: role must be 'host' or 'device', got {role!r}")
        if bitrate is not None and bitrate not in BITRATE_COMMANDS:
            raise ValueError(f"slcan_fast: bitrate {bitrate} not supported by slcan; use one of {sorted(BITRATE_COMMANDS)}")
        self.role = role
        self._chunk = int(chunk_size)
        if isinstance(channel, int):
            self._fd = channel
            self._own_fd = bool(close_fd)
            os.set_blocking(self._fd, False)
            self.channel_info = f"slcan fd {channel}"
        else:
            path = str(channel)
            if "@" in path:
                path, baud = path.rsplit("@", 1)
                tty_baudrate = int(baud)
            if not path:
                raise ValueError("slcan_fast: channel must be a tty/pty path such as /dev/ttyACM0 or /dev/pts/5")
            try:
                self._fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            except OSError as e:
                raise can.CanInitializationError(f"slcan_fast: cannot open {path}: {e.strerror}") from e
            self._own_fd = True if close_fd is None else close_fd
            if os.isatty(self._fd):
                _set_raw(self._fd, tty_baudrate)
            self.channel_info = f"slcan {path}"
        self._parser = SlcanParser(role, channel=channel, device_timestamps=device_timestamps)
        self.is_open = role == "host"
        self.timestamps_on = False
        self._t_open = time.monotonic()
        self.frames_tx = 0
        self.tx_dropped = 0
        self._closed = False
        if role == "host":
            try:
                termios.tcflush(self._fd, termios.TCIFLUSH)  # drop anything queued before we connected
            except termios.error:
                pass
            self._drain()
            cmds = [b"C\r"]
            if bitrate is not None:
                cmds.append(BITRATE_COMMANDS[bitrate] + _CR)
            cmds.append(b"L\r" if listen_only else b"O\r")
            self._write_all(b"".join(cmds), timeout=1.0)
        super().__init__(channel=channel, **kwargs)

    # -- counters ---------------------------------------------------------------
    @property
    def malformed(self) -> int:
        """Lines skipped because they were not valid slcan frames or replies."""
        return self._parser.malformed

    @property
    def frames_rx(self) -> int:
        return self._parser.frames

    @property
    def parser(self) -> SlcanParser:
        """The line parser (counters ``acks``, ``errors``, ``malformed_lines``, ``commands``, ``replies``)."""
        return self._parser

    def fileno(self) -> int:
        return self._fd

    # -- reading ----------------------------------------------------------------
    def _drain(self) -> None:
        """Discard whatever is readable now (used on connect; bounded, in case the peer keeps streaming)."""
        for _ in range(64):
            try:
                if not os.read(self._fd, self._chunk):
                    return
            except BlockingIOError:
                return
            except OSError:
                return

    def _read_chunk(self) -> bool:
        """One non-blocking read into the parser; False when nothing was available."""
        try:
            data = os.read(self._fd, self._chunk)
        except BlockingIOError:
            return False
        except OSError as e:
            if e.errno == errno.EIO:
                raise CanOperationError("slcan_fast: the other end of the tty/pty closed") from e
            raise CanOperationError(f"slcan_fast: read failed: {e.strerror}") from e
        if not data:
            raise CanOperationError("slcan_fast: end of file on the tty/pty (the other end closed)")
        self._parser.feed(data, time.time())
        if self._parser.commands:
            self._answer_commands()
        return True

    def _recv_internal(self, timeout: float | None) -> tuple[Message | None, bool]:
        q = self._parser.messages
        if q:
            return q.popleft(), False
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self._read_chunk() and q:
                return q.popleft(), False
            if deadline is None:
                wait = None
            else:
                wait = deadline - time.monotonic()
                if wait <= 0:
                    return None, False
            r, _, _ = select.select([self._fd], [], [], wait)
            if not r and deadline is not None and time.monotonic() >= deadline:
                return None, False

    def recv_available(self) -> list[Message]:
        """All frames available right now without blocking (one or more reads), oldest first."""
        while self._read_chunk():
            pass
        q = self._parser.messages
        out = list(q)
        q.clear()
        if self._filters is None:
            return out
        return [m for m in out if self._matches_filters(m)]

    # -- device role ------------------------------------------------------------
    def _answer_commands(self) -> None:
        replies = []
        for cmd in self._parser.commands:
            k = cmd[:1]
            if k in (b"O", b"L"):
                self.is_open = True
                replies.append(_CR)
            elif k == b"C":
                self.is_open = False
                replies.append(_CR)
            elif k == b"Z" and cmd[1:] in (b"0", b"1"):
                self.timestamps_on = cmd[1:] == b"1"
                replies.append(_CR)
            elif k == b"V":
                replies.append(b"V1013\r")
            elif k == b"v":
                replies.append(b"v1013\r")
            elif k == b"N":
                replies.append(b"NF001\r")
            elif k == b"F":
                replies.append(b"F00\r")
            else:
                replies.append(_CR)
        self._parser.commands.clear()
        self._write_all(b"".join(replies), timeout=0.1)

    # -- writing ----------------------------------------------------------------
    def _write_all(self, data: bytes, timeout: float | None) -> None:
        view = memoryview(data)
        deadline = None if timeout is None else time.monotonic() + timeout
        while view:
            try:
                n = os.write(self._fd, view)
                view = view[n:]
                continue
            except BlockingIOError:
                pass
            except OSError as e:
                raise CanOperationError(f"slcan_fast: write failed: {e.strerror}") from e
            wait = None if deadline is None else deadline - time.monotonic()
            if wait is not None and wait <= 0:
                raise CanOperationError(f"slcan_fast: send timed out with {len(view)} bytes unsent (the other end is not reading)")
            select.select([], [self._fd], [], wait)

    def _encode(self, msg: Message) -> bytes:
        if self.role == "device" and self.timestamps_on:
            return encode_frame(msg, int((time.monotonic() - self._t_open) * 1000.0))
        return encode_frame(msg)

    def send(self, msg: Message, timeout: float | None = None) -> None:
        """Write one frame; ``timeout`` (s, None = wait as long as needed) bounds waiting for a full tty buffer."""
        if self.role == "device" and not self.is_open:
            self.tx_dropped += 1
            return
        self._write_all(self._encode(msg), timeout)
        self.frames_tx += 1

    def send_many(self, msgs: list[Message], timeout: float | None = None) -> None:
        """Write several frames with one system call (e.g. all of a tick's output frames)."""
        if self.role == "device" and not self.is_open:
            self.tx_dropped += len(msgs)
            return
        self._write_all(b"".join([self._encode(m) for m in msgs]), timeout)
        self.frames_tx += len(msgs)

    def shutdown(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            if self.role == "host":
                try:
                    self._write_all(b"C\r", timeout=0.1)
                except CanOperationError:
                    pass
        finally:
            super().shutdown()
            if self._own_fd:
                try:
                    os.close(self._fd)
                except OSError:
                    pass


def register_interface(name: str = INTERFACE_NAME) -> None:
    """Make ``can.Bus(interface=name, ...)`` construct :class:`FastSlcanBus` in this process.

    Only needed where flowtex is installed without the ``can.interface`` entry point
    (module docstring); python-can reads its interface table at import, so this updates
    that table and the set of valid names it checks.
    """
    import can.interfaces
    import can.util

    can.interfaces.BACKENDS[name] = (__name__, "FastSlcanBus")
    names = frozenset(can.interfaces.BACKENDS)
    can.interfaces.VALID_INTERFACES = names
    can.util.VALID_INTERFACES = names
    can.VALID_INTERFACES = names
