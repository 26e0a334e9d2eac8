"""Opening CAN buses by name and moving frames on and off them, for the live loop and the simulated device.

``--bus INTERFACE[:CHANNEL]`` names any python-can interface (docs/live.md). A bus
that cannot be opened is a :class:`BusError` with one line, never a traceback.
:func:`receiver` and :func:`sender` pick the fastest way a bus offers to move a
tick's frames (``recv_available``/``send_many`` on flowtex's own slcan transport,
one ``recv``/``send`` per frame otherwise), once, before the loop starts.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import can
from can.interfaces.virtual import VirtualBus

from ..errors import FlowtexError
from ..io.codec import MessageCodec
from ..io.dbc import one_line
from ..io.mapsafety import CLASSIC_MAX_BYTES
from ..limits import MAX_TICK_FRAMES

CAN_ERR_BUSOFF = 0x40
"""Bit of a SocketCAN error frame's id that reports bus-off."""

SEND_TIMEOUT_S = 0.5
"""Longest wait for a bus to take a frame (python-can's ``send(msg, timeout)``), s. A bus whose transmit buffer stays
full that long (an adapter that stopped reading its tty, a socket queue that no longer drains) is a bus error: without
a bound the loop would wait in the send forever, where no Ctrl-C or SIGTERM reaches it. As long as the sound card
may stop calling back before the session ends (flowtex.runtime.audio)."""


TICK_FRAMES = MAX_TICK_FRAMES
"""Most frames one live tick receives (:func:`receiver`): what the replay reads in one tick (flowtex.limits), so a
session's log always replays."""


class BusError(FlowtexError):
    """The CAN bus could not be opened, failed, or went bus-off."""


def parse_bus_spec(spec: str) -> tuple[str, str | None, dict[str, Any]]:
    """``"socketcan:can0"`` -> ``("socketcan", "can0", {})``.

    The channel is everything after the first colon (``slcan:/dev/ttyACM0@115200``
    keeps its ``@``-suffix as python-can's slcan expects). ``socketcand`` takes
    ``socketcand:CHANNEL@HOST:PORT`` (default host 127.0.0.1, port 29536).
    """
    interface, _, channel = spec.partition(":")
    interface = interface.strip()
    if not interface:
        raise BusError(f"--bus {spec!r}: expected INTERFACE[:CHANNEL], e.g. virtual, socketcan:can0, slcan:/dev/ttyACM0")
    kwargs: dict[str, Any] = {}
    if interface == "socketcand":
        chan, _, hostport = channel.partition("@")
        host, _, port = hostport.partition(":")
        if port and not port.isdigit():
            raise BusError(f"--bus {spec!r}: port {port!r} is not a number; write socketcand:CHANNEL@HOST:PORT, e.g. "
                           "socketcand:can0@127.0.0.1:29536")
        kwargs = {"host": host or "127.0.0.1", "port": int(port) if port else 29536}
        channel = chan or "can0"
    return interface, (channel or None), kwargs


def open_bus(spec: str, bitrate: int | None = None, fd: bool = False, needs_fd: Sequence[str] = ()) -> can.BusABC:
    """Open the python-can bus named by ``spec`` (bitrate in bit/s); :class:`BusError` (one line) if that fails.

    ``fd`` (the session has CAN FD messages in its DBC) or any ``needs_fd``: the bus is opened for CAN FD (python-can's
    ``fd``; socketcan's raw socket otherwise refuses to send an FD frame and never delivers one). ``needs_fd``: the
    messages this end can carry only in CAN FD frames (:func:`fd_needed`); a bus that speaks classic CAN only (its
    ``protocol``; flowtex_slcan, for one) is then refused before any frame (:func:`check_fd`): the session used to
    start and end at its first send, unable to send the safe values either. The ``virtual`` bus carries any frame."""
    interface, channel, kwargs = parse_bus_spec(spec)
    if bitrate:
        kwargs["bitrate"] = int(bitrate)
    if fd or needs_fd:
        kwargs["fd"] = True
    if interface not in can.VALID_INTERFACES:
        raise BusError(f"--bus {spec!r}: unknown interface {interface!r}; python-can knows {', '.join(sorted(can.VALID_INTERFACES))}")
    try:
        bus = can.Bus(interface=interface, channel=channel, **kwargs)
    except Exception as exc:  # python-can raises CanError, OSError, ImportError, ValueError, serial errors...
        raise BusError(f"cannot open CAN bus {spec!r}: {one_line(exc)}") from None
    check_fd(bus, f"--bus {spec!r}", needs_fd)
    return bus


def fd_needed(codecs: Mapping[str, MessageCodec], sends: Sequence[str], receives: Sequence[str]) -> list[str]:
    """The messages one end of a session can carry only in CAN FD frames: the CAN FD messages (DBC) it ``sends`` (an FD
    frame does not go out as a classic one), and those it ``receives`` that are longer than a classic frame (a CAN FD
    message of at most 8 bytes may arrive in classic frames, which the decoder takes)."""
    return ([m for m in sends if codecs[m].is_fd]
            + [m for m in receives if codecs[m].is_fd and codecs[m].length > CLASSIC_MAX_BYTES])


def check_fd(bus: can.BusABC, what: str, needs_fd: Sequence[str]) -> None:
    """Shut ``bus`` (named ``what`` in the message) and raise :class:`BusError` when messages need CAN FD
    (``needs_fd``, :func:`fd_needed`) and the bus speaks classic CAN only (python-can's ``protocol``; the ``virtual``
    bus, which carries any frame whatever its protocol says, is not judged)."""
    if not needs_fd or isinstance(bus, VirtualBus) or getattr(bus, "protocol", None) != can.CanProtocol.CAN_20:
        return
    with contextlib.suppress(Exception):
        bus.shutdown()
    raise BusError(f"{what} carries classic CAN frames only, but the DBC makes {', '.join(needs_fd)} CAN FD: no "
                   "frame of it could go through (the safe values neither); use an adapter and interface that speak CAN "
                   "FD, or give the message at most 8 bytes and no CAN FD mark in the DBC")


def receiver(bus: can.BusABC) -> Callable[[list[Any]], None]:
    """``receive(frames)``: append every frame pending on ``bus`` (``recv_available()`` if the bus has it, else
    ``recv(timeout=0)`` until None), up to :data:`TICK_FRAMES` in ``frames``.

    Without the bound a bus delivering frames faster than the loop reads them (a flood on a ``vcan`` interface, which
    has no bitrate) kept the loop in its receive for ever: no tick, no watchdog, the outputs frozen at their last live
    values, and no Ctrl-C or SIGTERM obeyed (the loop checks them between ticks). The frames left wait for the next
    tick; a tick that late trips the overrun watchdog. flowtex's slcan reads its tty in chunks of a few thousand
    frames at most, far below the bound."""
    limit = TICK_FRAMES
    recv_available = getattr(bus, "recv_available", None)
    if recv_available is not None:
        def receive(frames: list[Any]) -> None:
            if len(frames) < limit:
                frames.extend(recv_available())
        return receive
    recv = bus.recv

    def receive_each(frames: list[Any]) -> None:
        while len(frames) < limit:
            msg = recv(0.0)
            if msg is None:
                return
            frames.append(msg)

    return receive_each


def sender(bus: can.BusABC, timeout_s: float = SEND_TIMEOUT_S) -> Callable[[Sequence[can.Message]], None]:
    """``send_frames(frames)``: send the frames in order (``bus.send_many`` if the bus has it, else one ``send`` each),
    each call waiting at most ``timeout_s`` for the bus to take a frame (then python-can raises ``CanOperationError``)."""
    send_many = getattr(bus, "send_many", None)
    if send_many is not None:
        return functools.partial(send_many, timeout=timeout_s)
    send = bus.send

    def send_each(frames: Sequence[can.Message]) -> None:
        for m in frames:
            try:
                send(m, timeout_s)
            except can.CanOperationError as exc:
                send_when_queued(send, m, timeout_s, exc)

    return send_each


QUEUE_RETRY_S = 0.0002
"""Pause between tries of a frame the interface's transmit queue had no room for, s (a frame takes 0.05-0.25 ms on a
1 Mbit/s bus)."""


def send_when_queued(send: Callable[..., None], msg: can.Message, timeout_s: float, exc: can.CanOperationError) -> None:
    """``send(msg, timeout_s)`` failed with ``exc``: when that is a full transmit queue (socketcan's ENOBUFS: the
    interface's queue, 10 frames by default, filled while the bus was busy; python-can's ``select`` does not wait for
    it), try again for up to ``timeout_s``, as :data:`SEND_TIMEOUT_S` allows any frame; any other failure, or a queue
    still full then, is raised. One full moment ended the session, and at its exit left the safe values unsent
    ('could not send the safe values ... make it safe by hand') when the queue had room again a millisecond later."""
    if exc.error_code != errno.ENOBUFS:
        raise exc
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(QUEUE_RETRY_S)
        try:
            send(msg, timeout_s)
            return
        except can.CanOperationError as again:
            if again.error_code != errno.ENOBUFS:
                raise
    raise can.CanOperationError(f"{exc}: the interface's transmit queue stayed full for {timeout_s:g} s (is the device "
                                "connected and acknowledging frames?)", errno.ENOBUFS) from None
