"""The live loop: CAN frames in, one graph tick, guarded CAN frames out, at the graph's rate.

Per tick (the order is the contract replay relies on, see docs/live.md):

1. wait for the tick's deadline (:class:`~flowtex.runtime.clock.DeadlineClock`);
2. receive every pending frame (``bus.recv(timeout=0)`` until None) and decode
   the mapped ones with the generated codecs straight into the graph's input
   views (inputs hold their last value between frames); mark their watchdog
   entries fresh;
3. ``graph.step_block(1)``;
4. copy the bound graph outputs into one vector, evaluate the watchdog (stale
   input or overrun -> safe values), apply the :class:`OutputGuard` (clamp,
   NaN/inf -> safe, peak allowance);
5. encode and send exactly one frame per actuator message, in map order;
6. in the slack: write the tick's received and sent frames to the ``--record``
   log, step the simulated device, statistics and the status line.

On every exit path (duration reached, Ctrl-C, SIGTERM, exception in the graph,
bus error) the safe values are encoded and sent once more, as the last frames
(and logged). Nothing in steps 2-5 allocates beyond python-can's own message
objects and small ints; the garbage collector is frozen during the loop.
"""

from __future__ import annotations

import contextlib
import gc
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import can
import numpy as np

from ..errors import DataError, FlowtexError
from ..io.canlog import SessionWriter
from ..io.canmap import CanMap, load_map
from ..io.codec import MessageCodec
from ..io.dbc import load_dbc
from .clock import DeadlineClock
from .safety import OutputGuard, Watchdog
from .stats import TickStats

CAN_ERR_BUSOFF = 0x40
"""Bit of a SocketCAN error frame's id that reports bus-off."""


class BusError(FlowtexError):
    """The CAN bus could not be opened, failed, or went bus-off."""


# --- bus -----------------------------------------------------------------------
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
        kwargs = {"host": host or "127.0.0.1", "port": int(port) if port else 29536}
        channel = chan or "can0"
    return interface, (channel or None), kwargs


def open_bus(spec: str, bitrate: int | None = None) -> can.BusABC:
    """Open the python-can bus named by ``spec``; :class:`BusError` (one line) if that fails."""
    interface, channel, kwargs = parse_bus_spec(spec)
    if bitrate:
        kwargs["bitrate"] = int(bitrate)
    if interface not in can.VALID_INTERFACES:
        raise BusError(f"--bus {spec!r}: unknown interface {interface!r}; python-can knows {', '.join(sorted(can.VALID_INTERFACES))}")
    try:
        return can.Bus(interface=interface, channel=channel, **kwargs)
    except Exception as exc:  # python-can raises CanError, OSError, ImportError, ValueError, serial errors...
        raise BusError(f"cannot open CAN bus {spec!r}: {_one_line(exc)}") from None


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


# --- the runtime side of a map ---------------------------------------------------
class CanIO:
    """Decoders into graph inputs, the output guard and encoders into reusable frames.

    Shared by the live loop and the replay so that both compute frames the same way.
    Watchdog entries are one per (graph input, sensor message) pair, so a vector input
    assembled from several messages goes stale when any of them stops.
    """

    def __init__(self, graph: Any, canmap: CanMap, codecs: Mapping[str, MessageCodec], rate_hz: float):
        self.graph = graph
        self.map = canmap
        self.codecs = codecs
        # inputs -> decoders
        wd_keys: list[tuple[str, str]] = []
        wd_timeouts: list[int] = []
        per_msg: dict[str, list[Any]] = {}
        for b in canmap.inputs.values():
            view = graph.input_view(b.name)
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                targets = per_msg.setdefault(m, [None] * len(c.signals))
                targets[c.index[s]] = (view, j, float(b.scale[j]), float(b.offset[j]))
                if (b.name, m) not in wd_keys:
                    wd_keys.append((b.name, m))
                    wd_timeouts.append(max(1, math.ceil(b.timeout_ms * rate_hz / 1000.0 - 1e-9)))
        self.watchdog_keys = wd_keys
        self.timeouts_ticks = np.array(wd_timeouts, dtype=np.int64)
        self.decoders: dict[int, tuple[Callable[[Any], bool], tuple[int, ...]]] = {}
        for m, targets in per_msg.items():
            c = codecs[m]
            if c.frame_id in self.decoders:
                raise DataError(f"two sensor messages share frame id {c.frame_id:#x}")
            entries = tuple(i for i, (_, mm) in enumerate(wd_keys) if mm == m)
            self.decoders[c.frame_id] = (c.decoder(targets), entries)
        # outputs -> guard -> encoders
        self.out_names = list(canmap.outputs)
        widths = [canmap.outputs[n].width for n in self.out_names]
        total = int(sum(widths))
        self.raw = np.zeros(total)
        self.out = np.zeros(total)
        self._copies: list[tuple[np.ndarray, np.ndarray]] = []
        lo, hi, safe, phi, pmax = [], [], [], [], []
        start = 0
        sources: dict[str, list[Any]] = {}
        for name, w in zip(self.out_names, widths, strict=True):
            b = canmap.outputs[name]
            self._copies.append((graph.output_view(name), self.raw[start:start + w]))
            lo.extend(b.lo)
            hi.extend(b.hi)
            safe.extend(b.safe)
            phi.extend(b.peak_limit if b.peak_limit is not None else b.hi)
            pmax.extend([int(round(b.peak_ms * rate_hz / 1000.0)) if b.peak_limit is not None else 0] * w)
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                src = sources.setdefault(m, [None] * len(c.signals))
                src[c.index[s]] = (self.out, start + j, float(b.scale[j]), float(b.offset[j]))
            start += w
        self.guard = OutputGuard(np.array(lo), np.array(hi), np.array(safe), peak_hi=np.array(phi),
                                 peak_max_ticks=np.array(pmax, dtype=np.int64)) if total else None
        self.tx: list[can.Message] = []
        self.encoders: list[Callable[[bytearray], None]] = []
        for m in canmap.actuator_messages():
            c = codecs[m]
            self.tx.append(can.Message(arbitration_id=c.frame_id, is_extended_id=c.is_extended, is_fd=c.is_fd,
                                       data=bytearray(c.length), is_rx=False))
            self.encoders.append(c.encoder(sources[m]))
        self.tx_ids = [(m.arbitration_id, m.is_extended_id) for m in self.tx]

    def new_watchdog(self, overrun_limit_ns: int, emit_log: bool = True) -> Watchdog:
        return Watchdog(self.timeouts_ticks, overrun_limit_ns, emit_log=emit_log)

    def decode(self, msg: can.Message, tick: int, watchdog: Watchdog) -> bool:
        """Decode one received frame into the graph inputs; True if it was a mapped sensor frame."""
        entry = self.decoders.get(msg.arbitration_id)
        if entry is None or not entry[0](msg.data):
            return False
        for w in entry[1]:
            watchdog.fresh(w, tick)
        return True

    def guard_outputs(self, force_safe: bool) -> int:
        """Copy bound graph outputs, guard them into ``self.out``; returns the guard's event count."""
        for src, dst in self._copies:
            dst[:] = src
        if self.guard is None:
            return 0
        return self.guard.apply(self.raw, self.out, force_safe)

    def encode(self) -> None:
        """Encode ``self.out`` into the reusable actuator frames ``self.tx``."""
        for enc, msg in zip(self.encoders, self.tx, strict=True):
            enc(msg.data)

    def encode_safe(self) -> None:
        """Encode every output's safe value into ``self.tx``."""
        if self.guard is not None:
            self.guard.safe_values(self.out)
        self.encode()


def load_io(graph: Any, dbc_path: str | Path, map_path: str | Path) -> CanIO:
    """Load the DBC and map (checked against ``graph``) and build the :class:`CanIO`."""
    db = load_dbc(dbc_path)
    canmap = load_map(map_path, db, dbc_path, port_widths(graph.inputs), port_widths(graph.outputs))
    used = set(canmap.sensor_messages()) | set(canmap.actuator_messages())
    codecs = {m.name: MessageCodec(m) for m in db.messages if m.name in used}
    return CanIO(graph, canmap, codecs, float(graph.rate))


def port_widths(ports: Mapping[str, Any]) -> dict[str, int]:
    """Graph port name -> number of scalars (product of its shape)."""
    return {name: int(np.prod(spec.shape)) if spec.shape else 1 for name, spec in ports.items()}


# --- exit handling ------------------------------------------------------------------
@contextlib.contextmanager
def _stop_signals(flag: list[str | None], install: bool) -> Iterator[None]:
    """SIGINT/SIGTERM set ``flag[0]`` instead of interrupting the loop (main thread only)."""
    if not install or threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        flag[0] = signal.Signals(signum).name

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextlib.contextmanager
def _frozen_gc() -> Iterator[None]:
    """No garbage collection during the loop (flowtex.runtime.realtime.freeze_gc when available)."""
    try:
        from .realtime import freeze_gc
    except ImportError:
        freeze_gc = None
    if freeze_gc is not None:
        with freeze_gc():
            yield
        return
    was = gc.isenabled()
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        gc.unfreeze()
        if was:
            gc.enable()


# --- the session ----------------------------------------------------------------------
@dataclass
class LiveReport:
    """What a live session did."""

    ticks: int
    frames_in: int
    frames_out: int
    watchdog_events: int
    guard_events: int
    exit_reason: str
    """``duration``, ``SIGINT``, ``SIGTERM`` or ``error``."""
    error: str | None = None
    summary: dict = field(default_factory=dict)
    rt_message: str = ""
    send_offset_ns: np.ndarray | None = None
    """Per tick (first ``ticks``, up to capacity): time from the tick's deadline until its last frame was sent."""
    device: Any = None
    """The in-process :class:`~flowtex.runtime.simdevice.SimulatedDevice`, if any."""

    @property
    def ok(self) -> bool:
        return self.error is None


def run_live(graph: Any, dbc_path: str | Path, map_path: str | Path, bus: str | None = None, *,
             simulate: Any = None, duration_s: float | None = None, record: str | Path | None = None,
             rt: bool = False, rt_priority: int = 80, rt_cpu: int | None = None, stats_path: str | Path | None = None,
             seed: int | None = None, status: TextIO | None = sys.stderr, bitrate: int | None = None,
             drop: Mapping[str, tuple[int, int | None]] | None = None, install_signals: bool = True,
             max_ticks: int | None = None) -> LiveReport:
    """Run ``graph`` live against a CAN bus until ``duration_s`` (None: until Ctrl-C/SIGTERM).

    ``simulate``: a recording path (or :class:`~flowtex.io.recordings.Recording`);
    a :class:`SimulatedDevice` then runs in this process on a private ``virtual``
    bus, stepped once per executed tick, and ``bus`` must be None or ``virtual``.
    ``drop`` (simulation only) silences sensor messages: name -> (first tick, stop tick or None).
    ``max_ticks`` ends the session after that many executed ticks (deterministic
    length for tests). Raises :class:`FlowtexError` for bad files or a bus that cannot
    be opened; failures during the loop end the session with safe values and are
    returned in ``LiveReport.error``.
    """
    io = load_io(graph, dbc_path, map_path)
    rate = float(graph.rate)
    device = None
    dev_bus = None
    if simulate is not None:
        from ..io.recordings import Recording, load_recording
        from .simdevice import SimulatedDevice

        rec = simulate if isinstance(simulate, Recording) else load_recording(simulate)
        if rec.rate is not None and abs(rec.rate - rate) > 1e-9 * rate:
            raise DataError(f"{simulate}: the recording states rate {rec.rate:g} Hz but graph {graph.name!r} runs at {rate:g} Hz")
        interface, channel, _ = parse_bus_spec(bus or "virtual")
        if interface != "virtual":
            raise BusError(f"--simulate runs the device on a 'virtual' bus in this process; drop --bus {bus!r} or use --bus virtual")
        channel = channel or f"flowtex-sim-{id(io):x}"
        bus_obj = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        dev_bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        device = SimulatedDevice(dev_bus, io.map, io.codecs, rec.arrays, rate_hz=rate, drop=drop)
    else:
        if bus is None:
            raise BusError("no --bus given (e.g. --bus socketcan:can0), and no --simulate RECORDING")
        if drop:
            raise FlowtexError("drop= only applies to a simulated device")
        bus_obj = open_bus(bus, bitrate)
    writer = None
    try:
        writer = SessionWriter(record) if record is not None else None
        return _loop(graph, io, bus_obj, device, writer, rate, duration_s, max_ticks, rt, rt_priority, rt_cpu,
                     stats_path, seed, status, install_signals)
    finally:
        if writer is not None:
            writer.close()
        with contextlib.suppress(Exception):
            bus_obj.shutdown()
        if dev_bus is not None:
            with contextlib.suppress(Exception):
                dev_bus.shutdown()


def _loop(graph: Any, io: CanIO, bus: can.BusABC, device: Any, writer: SessionWriter | None, rate: float,
          duration_s: float | None, max_ticks: int | None, rt: bool, rt_priority: int, rt_cpu: int | None,
          stats_path: str | Path | None, seed: int | None, status: TextIO | None, install_signals: bool) -> LiveReport:
    n_ticks = max_ticks
    if duration_s is not None:
        if not duration_s > 0:
            raise FlowtexError(f"--duration must be a positive number of seconds, got {duration_s!r}")
        n_ticks = min(n_ticks or 1 << 62, int(round(duration_s * rate)))
    capacity = int(min(n_ticks if n_ticks else 600 * rate, 3600 * rate)) + 1
    stats = TickStats(capacity)
    send_offset = np.zeros(capacity, dtype=np.int64)
    clock = DeadlineClock(rate)
    period = clock.period_ns
    watchdog = io.new_watchdog(int(round(io.map.overrun_limit_ms * 1e6)))
    graph.reset(seed)
    rt_granted = False
    rt_message = ""
    if rt:
        try:
            from .realtime import enter_realtime
        except ImportError:
            rt_message = "--rt: flowtex.runtime.realtime is not available; running without real-time scheduling"
        else:
            st = enter_realtime(rt_priority, rt_cpu)
            rt_granted, rt_message = bool(st.granted), str(st.message)
        if status is not None and rt_message:
            print(rt_message, file=status)
    stop: list[str | None] = [None]
    error: str | None = None
    guard_events = 0
    status_every = max(1, int(rate / 2))
    recv = bus.recv
    send = bus.send
    decoders = io.decoders
    fresh = watchdog.fresh
    check = watchdog.check
    step = graph.step_block
    guard_outputs = io.guard_outputs
    encoders = io.encoders
    tx = io.tx
    n_tx = len(tx)
    now = time.perf_counter_ns
    rx: list[Any] = [None] * 64
    k = 0
    if device is not None:
        device.publish(0)
    with _stop_signals(stop, install_signals), _frozen_gc():
        clock.start()
        lateness = 0
        overrun = 0
        try:
            while True:
                n_in = 0
                msg = recv(0.0)
                while msg is not None:
                    if n_in == len(rx):
                        rx.extend([None] * n_in)
                    rx[n_in] = msg
                    n_in += 1
                    msg = recv(0.0)
                t0 = now()
                for i in range(n_in):
                    msg = rx[i]
                    if msg.is_error_frame:
                        if msg.arbitration_id & CAN_ERR_BUSOFF:
                            raise BusError("CAN bus went bus-off (error frame with CAN_ERR_BUSOFF)")
                        continue
                    entry = decoders.get(msg.arbitration_id)
                    if entry is not None and entry[0](msg.data):
                        for w in entry[1]:
                            fresh(w, k)
                step(1)
                force = check(k, overrun)  # executed-tick count: replay recomputes it exactly
                guard_events += guard_outputs(force)
                for i in range(n_tx):
                    encoders[i](tx[i].data)
                t1 = now()
                for m in tx:
                    send(m)
                t2 = now()
                stats.record(lateness, t1 - t0)
                send_offset[k % capacity] = t2 - clock.deadline_ns
                stats.frames_in += n_in
                stats.frames_out += n_tx
                if writer is not None:
                    ts = time.time()
                    for i in range(n_in):
                        writer.write(rx[i], True)
                    for m in tx:
                        m.timestamp = ts
                        writer.write(m, False)
                for i in range(n_in):
                    rx[i] = None
                k += 1
                if device is not None:
                    device.collect(k - 1)
                    device.publish(k)
                if stop[0] is not None or (n_ticks is not None and k >= n_ticks):
                    break
                if status is not None and k % status_every == 0:
                    stats.watchdog_events = watchdog.events
                    print("\r" + stats.status_line(), end="", file=status, flush=True)
                lateness = clock.wait()
                if clock.skipped:
                    stats.missed += clock.skipped
                    stats.overruns += 1
                    overrun = lateness + clock.skipped * period
                else:
                    overrun = lateness
        except (can.CanError, BusError, OSError) as exc:
            error = f"CAN bus error at tick {k}: {_one_line(exc)}"
        except FlowtexError as exc:
            error = f"tick {k}: {_one_line(exc)}"
        except Exception as exc:  # an exception inside the graph or a codec must still end in safe values
            error = f"tick {k}: {type(exc).__name__}: {_one_line(exc)}"
        finally:
            safe_error = _send_safe(io, send, writer)
            if device is not None:
                device.collect(k)
    if safe_error and error is None:
        error = safe_error
    elif safe_error:
        error += f"; {safe_error}"
    stats.watchdog_events = watchdog.events
    stats.timeouts = sum(1 for e in watchdog.log if e[1] == "stale")
    if status is not None:
        print("\r" + stats.status_line(), file=status)
        print(stats.format_summary(rt_granted), file=status)
    if stats_path is not None:
        stats.write_json(stats_path, rt_granted)
    reason = "error" if error else (stop[0] or "duration")
    return LiveReport(ticks=k, frames_in=stats.frames_in, frames_out=stats.frames_out, watchdog_events=watchdog.events,
                      guard_events=guard_events, exit_reason=reason, error=error, summary=stats.summary(rt_granted),
                      rt_message=rt_message, send_offset_ns=send_offset[:min(k, capacity)], device=device)


def _send_safe(io: CanIO, send: Callable[[can.Message], None], writer: SessionWriter | None) -> str | None:
    """Encode and send every output's safe value (and log it); returns an error text if sending failed."""
    io.encode_safe()
    ts = time.time()
    problem = None
    for m in io.tx:
        try:
            send(m)
        except Exception as exc:  # keep trying the other messages
            problem = f"could not send safe values: {_one_line(exc)}"
        if writer is not None:
            m.timestamp = ts
            writer.write(m, False)
    return problem
