"""Opening CAN buses by name and moving frames on and off them, for the live loop and the simulated device.

``--bus INTERFACE[:CHANNEL]`` names any python-can interface (docs/live.md). A bus
that cannot be opened is a :class:`BusError` with one line, never a traceback.
:func:`receiver` and :func:`sender` pick the fastest way a bus offers to move a
tick's frames (``recv_available``/``send_many`` on flowtex's own slcan transport,
one ``recv``/``send`` per frame otherwise), once, before the loop starts.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import can

from ..errors import FlowtexError
from ..io.dbc import one_line

CAN_ERR_BUSOFF = 0x40
"""Bit of a SocketCAN error frame's id that reports bus-off."""

SEND_TIMEOUT_S = 0.5
"""Longest wait for a bus to take a frame (python-can's ``send(msg, timeout)``), s. A bus whose transmit buffer stays
full that long (an adapter that stopped reading its tty, a socket queue that no longer drains) is a bus error: without
a bound the loop would wait in the send forever, where no Ctrl-C or SIGTERM reaches it. As long as the sound card
may stop calling back before the session ends (flowtex.runtime.audio)."""


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


def open_bus(spec: str, bitrate: int | None = None) -> can.BusABC:
    """Open the python-can bus named by ``spec`` (bitrate in bit/s); :class:`BusError` (one line) if that fails."""
    interface, channel, kwargs = parse_bus_spec(spec)
    if bitrate:
        kwargs["bitrate"] = int(bitrate)
    if interface not in can.VALID_INTERFACES:
        raise BusError(f"--bus {spec!r}: unknown interface {interface!r}; python-can knows {', '.join(sorted(can.VALID_INTERFACES))}")
    try:
        return can.Bus(interface=interface, channel=channel, **kwargs)
    except Exception as exc:  # python-can raises CanError, OSError, ImportError, ValueError, serial errors...
        raise BusError(f"cannot open CAN bus {spec!r}: {one_line(exc)}") from None


def receiver(bus: can.BusABC) -> Callable[[list[Any]], None]:
    """``receive(frames)``: append every frame pending on ``bus`` (``recv_available()`` if the bus has it, else
    ``recv(timeout=0)`` until None)."""
    recv_available = getattr(bus, "recv_available", None)
    if recv_available is not None:
        def receive(frames: list[Any]) -> None:
            frames.extend(recv_available())
        return receive
    recv = bus.recv

    def receive_each(frames: list[Any]) -> None:
        msg = recv(0.0)
        while msg is not None:
            frames.append(msg)
            msg = recv(0.0)

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
            send(m, timeout_s)

    return send_each
