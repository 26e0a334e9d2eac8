"""The options of a live session, as one typed, checked value: :class:`LiveConfig`.

``flowtex live``, ``flowtex scene live``, the tests and the benchmarks build one and hand it
to :func:`~flowtex.runtime.live.run_live`. Every option's value is checked here, once, when
the config is made (one line naming the option and the fix); what needs the files or the
graph (output paths against the session's inputs, the map's audio section, the bus itself)
is checked by :func:`~flowtex.runtime.preflight.preflight_live` and ``run_live``.
"""

from __future__ import annotations

import math
import numbers
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from ..errors import FlowtexError
from ..limits import MAX_SEED
from .buses import BusError, parse_bus_spec

if TYPE_CHECKING:
    from ..io.recordings import Recording

Drop = Mapping[str, tuple[int, int | None]]
"""Sensor message name -> (first tick, stop tick or None: forever) during which the simulated device does not send it."""


@dataclass(frozen=True)
class LiveConfig:
    """Everything a live session needs besides the graph. Frozen: a session never changes its options.

    Units are in the names: seconds (``_s``), Hz, ticks (one graph tick, ``1 / graph.rate`` seconds).
    The CLI flag of each field is named in its error messages. ``dataclasses.replace`` makes a checked copy.
    """

    dbc_path: str | Path
    """DBC file describing the device's messages (``--dbc``)."""
    map_path: str | Path
    """Map YAML binding DBC signals to graph inputs and outputs (``--map``, docs/live.md)."""
    bus: str | None = None
    """``INTERFACE[:CHANNEL]`` (``--bus``), e.g. ``socketcan:can0``; with :attr:`simulate` None or ``virtual[:CHANNEL]``."""
    simulate: str | Path | Recording | None = None
    """A recording path or :class:`~flowtex.io.recordings.Recording` (``--simulate``): a simulated device then runs in this
    process on a private ``virtual`` bus, stepped once per executed tick."""
    duration_s: float | None = None
    """Seconds to run (``--duration``, > 0); None: until Ctrl-C, SIGTERM or :attr:`max_ticks`."""
    max_ticks: int | None = None
    """End after this many executed ticks (>= 1; a deterministic length for tests and benchmarks)."""
    record: str | Path | None = None
    """Log every frame read and written to this ``.blf``/``.log`` file (``--record``)."""
    record_audio: str | Path | None = None
    """Write the samples handed to the sound card as a float32 WAV (``--record-audio``; the map needs an ``audio`` section)."""
    stats_path: str | Path | None = None
    """Write the end-of-run statistics as JSON here (``--stats``)."""
    rt: bool = False
    """Ask for SCHED_FIFO real-time scheduling and pin the loop to a CPU (``--rt``)."""
    rt_priority: int = 80
    """SCHED_FIFO priority with :attr:`rt` (``--rt-priority``, 1..99 on Linux; one the system refuses is a warning at start)."""
    rt_cpu: int | None = None
    """CPU to pin the loop to with :attr:`rt` (``--cpu``); None: the highest-numbered one this process may use."""
    seed: int | None = None
    """Noise seed (``--seed``, 0..2^63-1); None: the graph's."""
    status: TextIO | None = sys.stderr
    """Where the status line and event lines go; None: quiet (``--quiet``; events then go to logging)."""
    bitrate: int | None = None
    """Bus bitrate in bit/s (``--bitrate``, >= 1) for interfaces that need one."""
    drop: Drop | None = None
    """Simulation only: sensor messages the simulated device does not send, by name -> (first tick, stop tick or None)."""
    install_signals: bool = True
    """SIGINT/SIGTERM end the session cleanly (main thread only); False leaves the handlers alone (tests, embedding)."""
    warm: bool = True
    """Cache warming shortly before each deadline (:func:`~flowtex.runtime.tick.warmer`)."""
    show: tuple[str, ...] = ()
    """Graph outputs or inputs (``NAME`` or ``NAME[i]``) whose values follow the status line (``--show``)."""
    inputs: tuple[str | Path, ...] = ()
    """Other files the session was built from (e.g. a scene file): :attr:`record` and :attr:`stats_path` must not be one."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "show", tuple(self.show))
        object.__setattr__(self, "inputs", tuple(self.inputs))
        _check(self)

    def tick_limit(self, rate_hz: float) -> int | None:
        """Ticks to run at ``rate_hz``: :attr:`max_ticks`, or :attr:`duration_s` in ticks when that is fewer; None: no limit."""
        n = self.max_ticks
        if self.duration_s is not None:
            n = min(n or 1 << 62, int(round(self.duration_s * float(rate_hz))))
        return n


def _bad(name: str, flag: str, value: Any, need: str) -> FlowtexError:
    return FlowtexError(f"live option {name} ({flag}) = {value!r}: {need}")


def _is_int(value: Any) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _check(c: LiveConfig) -> None:
    """Every option value on its own and against the others; raises one line naming the option and the fix."""
    if c.duration_s is not None:
        if isinstance(c.duration_s, bool) or not isinstance(c.duration_s, numbers.Real) or not (
                c.duration_s > 0 and math.isfinite(c.duration_s)):
            raise _bad("duration_s", "--duration", c.duration_s, "must be a positive number of seconds")
    if c.max_ticks is not None and not (_is_int(c.max_ticks) and c.max_ticks >= 1):
        raise _bad("max_ticks", "max_ticks", c.max_ticks, "must be a whole number of ticks >= 1, or None for no limit")
    # What the operating system grants (priority range, allowed CPUs) is its answer at start, a warning, not an error here.
    if not _is_int(c.rt_priority):
        raise _bad("rt_priority", "--rt-priority", c.rt_priority, "must be an integer SCHED_FIFO priority (1..99 on Linux)")
    if c.rt_cpu is not None and not _is_int(c.rt_cpu):
        raise _bad("rt_cpu", "--cpu", c.rt_cpu, "must be an integer CPU number, or None")
    if c.seed is not None and not (_is_int(c.seed) and 0 <= c.seed <= MAX_SEED):
        raise _bad("seed", "--seed", c.seed, "must be an integer 0..2^63-1, or None for the graph's seed")
    if c.bitrate is not None and not (_is_int(c.bitrate) and c.bitrate >= 1):
        raise _bad("bitrate", "--bitrate", c.bitrate, "must be a whole number of bit/s >= 1, or None")
    for name in ("dbc_path", "map_path"):
        if not isinstance(getattr(c, name), (str, Path)) or not str(getattr(c, name)):
            flag = "--dbc" if name == "dbc_path" else "--map"
            raise _bad(name, flag, getattr(c, name), "must be a file path")
    if c.drop and c.simulate is None:
        raise _bad("drop", "drop", dict(c.drop), "only applies to a simulated device: give simulate= (--simulate RECORDING)")
    if c.simulate is None and c.bus is None:
        raise BusError("no --bus given (e.g. --bus socketcan:can0), and no --simulate RECORDING")
    if c.bus is not None:
        interface = parse_bus_spec(c.bus)[0]  # BusError for a spec that is no INTERFACE[:CHANNEL]
        if c.simulate is not None and interface != "virtual":
            raise BusError(f"--simulate runs the device on a 'virtual' bus in this process; drop --bus {c.bus!r} or use --bus virtual")
