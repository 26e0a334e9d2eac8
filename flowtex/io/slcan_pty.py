"""Terminals for slcan: raw 8-bit mode on a tty (:func:`set_raw`) and pseudo-terminal pairs for device simulators (:func:`open_pty`).

Kept apart from the bus (:mod:`flowtex.io.slcan_fast`, whose docstring says how a simulator and a
runtime in two processes share a pty) because only POSIX has them; error messages keep the bus's ``slcan_fast:`` prefix.
"""

from __future__ import annotations

import os
import termios
import tty
from dataclasses import dataclass

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


def set_raw(fd: int, baudrate: int | None) -> None:
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
    set_raw(slave, None)
    set_raw(master, None)
    return SlcanPty(master_fd=master, slave_fd=slave, slave_path=os.ttyname(slave))
