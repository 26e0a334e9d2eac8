"""Fast slcan (Lawicel ASCII) CAN transport over a tty or a pseudo-terminal.

Why. python-can's stock ``slcan`` interface reads one byte per call through pyserial and
manages a few thousand frames/s; a 1 kHz haptic loop with several frames per tick in each
direction needs more headroom. :class:`FastSlcanBus` reads whatever is available in one
``os.read`` (up to ``chunk_size`` bytes) on a non-blocking fd, waits with ``select``,
splits complete ``\\r``-terminated lines and parses them with a few bytes operations, and
writes each frame (or a batch, :meth:`FastSlcanBus.send_many`) with one ``os.write``.

Protocol: :mod:`flowtex.io.slcan_protocol` (encoding, parsing, what counts as malformed).
Terminal setup and pty pairs: :mod:`flowtex.io.slcan_pty`. Their names (``encode_frame``,
``SlcanParser``, ``MAX_LINE``, ``BITRATE_COMMANDS``, ``open_pty``, ``SlcanPty``) still import from here.

Roles. ``role="host"`` (default) is the computer side: on open it sends ``C``, the
bitrate command if ``bitrate`` is given, and ``O`` (``L`` when ``listen_only``); on
shutdown ``C``. ``role="device"`` is the adapter side, for simulators: it answers every
command line (OK, or a version/status reply), records the commands in ``commands``, keeps
``is_open`` from ``O``/``L``/``C``, appends millisecond timestamps to the frames it sends
while ``Z1`` is in force, and drops (and counts in ``tx_dropped``) frames sent while the
channel is closed, as a real adapter does.

Across processes. :func:`~flowtex.io.slcan_pty.open_pty` creates a pseudo-terminal in raw mode and keeps
both ends open: a device simulator serves ``FastSlcanBus(pty.master_fd, role="device")`` and
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

import errno
import os
import select
import termios
import time

import can
from can import BusABC, CanOperationError, Message

from .slcan_protocol import _CR, BITRATE_COMMANDS, MAX_LINE, SlcanParser, encode_frame
from .slcan_pty import SlcanPty, open_pty, set_raw

__all__ = ["BITRATE_COMMANDS", "INTERFACE_NAME", "MAX_LINE", "FastSlcanBus", "SlcanParser", "SlcanPty", "encode_frame", "open_pty",
           "register_interface"]

INTERFACE_NAME = "flowtex_slcan"
"""Name under which :func:`register_interface` (or the entry point) makes this bus known to python-can."""


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
                set_raw(self._fd, tty_baudrate)
            self.channel_info = f"slcan {path}"
        self._parser = SlcanParser(role, channel=channel, device_timestamps=device_timestamps)
        self.is_open = role == "host"
        self.times_opened = 0
        """Device role: ``O``/``L`` commands received so far (an open and its close may arrive in one read)."""
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
                self.times_opened += 1
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
