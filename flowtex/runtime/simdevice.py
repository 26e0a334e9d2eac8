"""A simulated haptic device: plays a recording's sensor signals as CAN frames, collects actuator frames.

The map file says which DBC signals feed which graph input (``graph = physical *
scale + offset``); the device inverts that to turn the recording's graph-input
arrays (time first, keyed by graph input name) back into DBC physical values
and encodes them with the same generated codecs. Sample ``k`` of the recording
(wrapping around at its end) is published as tick ``k``'s sensor frames.

In ``flowtex live --simulate`` the device shares the runtime's process and is
stepped by the runtime's clock: ``publish(k)`` before tick ``k`` starts and
``collect(k)`` after the runtime sent tick ``k``'s actuator frames, so a
simulated session is deterministic. :func:`run_device` runs the same device as
its own process with its own clock (``flowtex simulate-device``), on any
python-can bus or on a pseudo-terminal speaking slcan (``pty=True``: the runtime
then opens ``--bus flowtex_slcan:/dev/pts/N``).

Sensor-to-actuator latency. ``publish(k)`` stamps the tick (and wall time) of the
oldest sensor sample not yet answered; the next ``collect(q)`` that receives
actuator frames records ``q - k`` in ``latency_ticks`` and the wall time from the
publish to the first such frame's timestamp in ``latency_s``. In the in-process
simulation, 0 ticks means the actuator frames computed from sample ``k`` were sent
within tick ``k``. Across processes the device collects at the start of each of its
own ticks, so an answer sent within the runtime's tick is seen one device tick later
(1 tick).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Mapping
from typing import Any, TextIO

import can
import numpy as np

from ..dsp.nonfinite import find_nonfinite
from ..errors import DataError, FlowtexError
from ..io.canmap import CanMap, load_map
from ..io.codec import MessageCodec
from ..io.dbc import load_dbc
from ..io.mapunits import keeps_unit
from ..io.recording_rules import check_stated_unit
from ..io.recordings import Recording, load_recording
from .buses import BusError, check_fd, fd_needed, open_bus, parse_bus_spec
from .clock import DeadlineClock


def check_finite(canmap: CanMap, arrays: Mapping[str, np.ndarray], source: str) -> None:
    """Refuse a recording whose sensor signals hold NaN or inf (a CAN signal cannot carry them), naming the signal and sample."""
    for b in canmap.inputs.values():
        if b.name in arrays:
            bad = find_nonfinite(np.asarray(arrays[b.name], dtype=np.float64))
            if bad is not None:
                raise DataError(f"{source}: signal {b.name!r} has {bad.describe()}; a simulated device sends every sample "
                                "as CAN frames: clean the recording (e.g. fill the gaps) before simulating it")


def check_range(canmap: CanMap, codecs: Mapping[str, MessageCodec], arrays: Mapping[str, np.ndarray], source: str) -> None:
    """Refuse a recording whose sensor signals leave what their DBC signals can carry (``[minimum|maximum]`` and the
    raw bit width): the codec would clamp every such sample without a word, and the graph would see another path."""
    for b in canmap.inputs.values():
        if b.name not in arrays:
            continue
        a = np.asarray(arrays[b.name], dtype=np.float64)
        a = a.reshape(a.shape[0], -1) if a.ndim else a.reshape(1, 1)
        for j, (m, sig) in enumerate(b.signals):
            if j >= a.shape[1]:
                break
            lay = codecs[m].layouts[codecs[m].index[sig]]
            lo, hi = -np.inf, np.inf
            if not lay.is_float:
                ends = sorted((lay.raw_min * float(lay.scale) + float(lay.offset), lay.raw_max * float(lay.scale) + float(lay.offset)))
                lo, hi = ends
            if lay.minimum is not None and lay.maximum is not None and lay.minimum < lay.maximum:
                lo, hi = max(lo, float(lay.minimum)), min(hi, float(lay.maximum))
            phys = (a[:, j] - float(b.offset[j])) / float(b.scale[j])
            out = np.flatnonzero((phys < lo) | (phys > hi))
            if out.size:
                i = int(out[0])
                unit = f" {lay.unit}" if lay.unit else ""
                raise DataError(f"{source}: signal {b.name!r}" + (f"[{j}]" if b.width > 1 else "") + f" leaves what {m}.{sig} "
                                f"can carry, [{lo:g}, {hi:g}]{unit} (DBC range and bit width), on {out.size} sample(s), the "
                                f"first {phys[i]:g}{unit} at index {i}; the device would send the clamped value instead. "
                                "Scale or cut the recording, or widen the signal in the DBC")


def check_units(canmap: CanMap, codecs: Mapping[str, MessageCodec], units: Mapping[str, str], source: str) -> None:
    """Refuse a recording that states a unit for a sensor signal other than its DBC signal's unit
    (:func:`~flowtex.io.recording_rules.check_stated_unit`; a unit that states nothing on either side passes).

    ``flowtex simulate-device`` has no graph to take units from; the DBC states each signal's unit, and the device
    sends the recording's values as that signal's physical values (``physical = (graph - offset) / scale``): a speed
    stated in m/s played onto a signal in mm/s would arrive 1000x too slow, silently. A component whose map ``scale``
    is not 1 is left alone (:func:`~flowtex.io.mapunits.keeps_unit`): that scale may itself convert units (DBC mm to
    graph m), to a unit nobody states.
    """
    for b in canmap.inputs.values():
        for j, (m, sig) in enumerate(b.signals):
            if keeps_unit(b, j):
                unit = codecs[m].layouts[codecs[m].index[sig]].unit
                check_stated_unit(units, b.name, unit, source, f"DBC signal {m}.{sig} (bound by map {canmap.path.name})")


class SimulatedDevice:
    """Publish sensor frames from recorded arrays; decode received actuator frames into graph units.

    ``drop`` maps a sensor message name to ``(first_tick, stop_tick)`` (stop None:
    forever) during which the device does not send that message (sensor dropout).
    ``history``: keep the actuator values seen after each collect (rows = ticks).
    ``source`` names the recording in errors (a NaN or inf sample is refused here, before any frame is sent).
    """

    def __init__(self, bus: can.BusABC, canmap: CanMap, codecs: Mapping[str, MessageCodec], arrays: Mapping[str, np.ndarray],
                 rate_hz: float = 1000.0, drop: Mapping[str, tuple[int, int | None]] | None = None, history: int = 0,
                 source: str = "recording"):
        check_finite(canmap, arrays, source)
        check_range(canmap, codecs, arrays, source)
        self.bus = bus
        self.rate_hz = float(rate_hz)
        columns = []
        width = 0
        sources: dict[str, list[Any]] = {}
        for b in canmap.inputs.values():
            if b.name not in arrays:
                raise DataError(f"{source}: no signal {b.name!r} for sensor input {b.name!r} (it has: {', '.join(arrays)})")
            a = np.asarray(arrays[b.name], dtype=np.float64)
            if a.ndim == 0 or int(np.prod(a.shape[1:])) != b.width:
                raise DataError(f"{source}: signal {b.name!r} has shape {a.shape}; the map binds {b.width} signal(s) per sample")
            columns.append(a.reshape(a.shape[0], b.width))
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                src = sources.setdefault(m, [None] * len(c.signals))
                src[c.index[s]] = (None, width + j, 1.0 / float(b.scale[j]), -float(b.offset[j]) / float(b.scale[j]))
            width += b.width
        lengths = {c.shape[0] for c in columns}
        if len(lengths) > 1 or not columns or 0 in lengths:
            raise DataError("recording signals for the sensor inputs must be non-empty and of equal length")
        self.samples = np.ascontiguousarray(np.concatenate(columns, axis=1))
        self.n = self.samples.shape[0]
        self.vals = np.zeros(width)
        self.tx: list[tuple[str, can.Message, Any]] = []
        for m in canmap.sensor_messages():
            c = codecs[m]
            src = [None if t is None else (self.vals, t[1], t[2], t[3]) for t in sources[m]]
            msg = can.Message(arbitration_id=c.frame_id, is_extended_id=c.is_extended, is_fd=c.is_fd, data=bytearray(c.length))
            self.tx.append((m, msg, c.encoder(src)))
        self.drop = dict(drop or {})
        unknown = [m for m in self.drop if m not in {t[0] for t in self.tx}]
        if unknown:
            raise FlowtexError(f"drop: {', '.join(unknown)} is not a sensor message of the map ({', '.join(t[0] for t in self.tx)})")
        # actuator side: decode into graph units
        out_width = sum(b.width for b in canmap.outputs.values())
        self.actuators = np.zeros(out_width)
        per_msg: dict[str, list[Any]] = {}
        start = 0
        for b in canmap.outputs.values():
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                t = per_msg.setdefault(m, [None] * len(c.signals))
                t[c.index[s]] = (self.actuators, start + j, 1.0 / float(b.scale[j]), -float(b.offset[j]) / float(b.scale[j]))
            start += b.width
        self.decoders = {codecs[m].frame_id: codecs[m].decoder(t) for m, t in per_msg.items()}
        self.frames_sent = 0
        self.frames_received = 0
        self.history = np.full((history, out_width), np.nan) if history else None
        self.frames_per_collect = np.zeros(history, dtype=np.int64) if history else None
        self.publish_time = 0.0
        self._pending_tick = -1
        """Tick of the oldest published sensor sample without an actuator answer yet (-1: none)."""
        self.latency_s = np.zeros(1 << 17)
        """Publish -> first actuator frame after it, in s (ring; ``latency_count`` is the total)."""
        self.latency_ticks = np.zeros(1 << 17, dtype=np.int64)
        """Publish tick -> tick of the collect that saw the answer (ring, same slots as ``latency_s``)."""
        self.latency_count = 0
        self._recv_available = getattr(bus, "recv_available", None)
        self._send_many = getattr(bus, "send_many", None)
        self._batch: list[can.Message] = []

    def publish(self, k: int) -> None:
        """Send sensor frames for tick ``k`` (sample ``k`` modulo the recording length)."""
        self.vals[:] = self.samples[k % self.n]
        batch = self._batch
        batch.clear()
        for name, msg, enc in self.tx:
            d = self.drop.get(name)
            if d is not None and k >= d[0] and (d[1] is None or k < d[1]):
                continue
            enc(msg.data)
            batch.append(msg)
        if self._pending_tick < 0:
            self._pending_tick = k
            self.publish_time = time.time()
        if self._send_many is not None:
            self._send_many(batch)
        else:
            send = self.bus.send
            for msg in batch:
                send(msg)
        self.frames_sent += len(batch)

    def _received(self) -> list[can.Message]:
        if self._recv_available is not None:
            return self._recv_available()
        out = []
        msg = self.bus.recv(0.0)
        while msg is not None:
            out.append(msg)
            msg = self.bus.recv(0.0)
        return out

    def collect(self, k: int) -> int:
        """Receive every pending actuator frame (sent during tick ``k``); returns how many arrived."""
        count = 0
        first_ts = None
        for msg in self._received():
            dec = self.decoders.get(msg.arbitration_id)
            if dec is not None and dec(msg.data):
                count += 1
                if first_ts is None:
                    first_ts = msg.timestamp
        if count and self._pending_tick >= 0:
            i = self.latency_count % self.latency_s.shape[0]
            self.latency_s[i] = first_ts - self.publish_time
            self.latency_ticks[i] = k - self._pending_tick
            self.latency_count += 1
            self._pending_tick = -1
        self.frames_received += count
        if self.history is not None and 0 <= k < self.history.shape[0]:
            self.history[k] = self.actuators
            self.frames_per_collect[k] = count
        return count


def in_process_device(bus_spec: str | None, canmap: CanMap, codecs: Mapping[str, MessageCodec], recording: Any, rate_hz: float,
                      drop: Mapping[str, tuple[int, int | None]] | None = None, graph_name: str = "graph",
                      units: Mapping[str, str] | None = None) -> tuple[can.BusABC, can.BusABC, SimulatedDevice]:
    """``flowtex live --simulate``: a private ``virtual`` bus pair and a :class:`SimulatedDevice` on one end of it.

    ``recording``: a path or :class:`~flowtex.io.recordings.Recording` whose stated
    rate (if any) must equal ``rate_hz`` and whose stated units (if any) must be ``units``, the graph inputs' units by
    name (:func:`~flowtex.io.recording_rules.check_stated_unit`, as ``flowtex run`` checks them); ``bus_spec`` must be
    None or ``virtual[:CHANNEL]``.
    Returns (the runtime's bus, the device's bus, the device); the caller shuts both buses down.
    """
    rec = recording if isinstance(recording, Recording) else load_recording(recording)
    if rec.rate is not None and abs(rec.rate - rate_hz) > 1e-9 * rate_hz:
        raise DataError(f"{recording}: the recording states rate {rec.rate:g} Hz but graph {graph_name!r} runs at {rate_hz:g} Hz")
    for name, unit in (units or {}).items():
        check_stated_unit(rec.units, name, unit, recording, f"graph {graph_name!r} input {name!r}")
    interface, channel, _ = parse_bus_spec(bus_spec or "virtual")
    if interface != "virtual":  # a user's --bus is checked by LiveConfig; this is a caller's mistake
        raise ValueError(f"in_process_device: bus_spec must be None or virtual[:CHANNEL], got {bus_spec!r}")
    channel = channel or f"flowtex-sim-{id(rec):x}"
    runtime_bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    device_bus = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        return runtime_bus, device_bus, SimulatedDevice(device_bus, canmap, codecs, rec.arrays, rate_hz=rate_hz, drop=drop,
                                                         source=str(rec.path or recording))
    except Exception:
        runtime_bus.shutdown()
        device_bus.shutdown()
        raise


def run_device(bus_spec: str | None, dbc_path: str, map_path: str, recording: str, rate_hz: float | None = None,
               duration_s: float | None = None, bitrate: int | None = None, status: TextIO | None = sys.stderr,
               pty: bool = False, exit_on_close: bool = False, announce: TextIO | None = sys.stdout) -> int:
    """Run the simulated device as its own process on ``bus_spec`` until ``duration_s`` or Ctrl-C/SIGTERM.

    Returns the number of ticks run. Each tick: collect actuator frames, publish
    the next sensor sample. The rate is ``rate_hz``, else the recording's stated
    rate, else 1000 Hz.

    ``pty=True`` (``bus_spec`` None): serve the slcan protocol on a new
    pseudo-terminal as the adapter would (:class:`~flowtex.io.slcan_fast.FastSlcanBus`
    in the device role) and print ``--bus flowtex_slcan:/dev/pts/N`` on ``announce``
    for the runtime; frames are only sent while the host has the channel open.
    ``exit_on_close``: stop once a host that had opened the channel closes it (the
    end of a runtime session), after collecting its last frames.
    """
    import signal

    if pty == (bus_spec is not None):
        raise FlowtexError("simulate-device: give either --bus INTERFACE[:CHANNEL] or --pty")
    db = load_dbc(dbc_path)
    canmap = load_map(map_path, db, dbc_path)
    used = set(canmap.sensor_messages()) | set(canmap.actuator_messages())
    codecs = {m.name: MessageCodec(m) for m in db.messages if m.name in used}
    rec = load_recording(recording)
    check_units(canmap, codecs, rec.units, str(recording))  # before the bus or pty opens
    check_finite(canmap, rec.arrays, str(recording))
    check_range(canmap, codecs, rec.arrays, str(recording))
    rate = float(rate_hz or rec.rate or 1000.0)
    needs_fd = fd_needed(codecs, canmap.sensor_messages(), canmap.actuator_messages())  # the device sends the sensors'
    pty_pair = None
    if pty:
        from ..io.slcan_fast import FastSlcanBus
        from ..io.slcan_pty import open_pty

        pty_pair = open_pty()
        bus = FastSlcanBus(pty_pair.master_fd, role="device")
        try:
            check_fd(bus, "--pty (an slcan adapter)", needs_fd)
        except BusError:
            pty_pair.close()
            raise
    else:
        bus = open_bus(bus_spec, bitrate, any(c.is_fd for c in codecs.values()), needs_fd)
    stop: list[bool] = [False]

    def handler(signum: int, frame: Any) -> None:
        stop[0] = True

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        dev = SimulatedDevice(bus, canmap, codecs, rec.arrays, rate_hz=rate, source=str(recording))
        if pty_pair is not None and announce is not None:  # ready to serve: a runtime started now is answered at once
            print(f"simulated device on {pty_pair.slave_path}: run the runtime with --bus flowtex_slcan:{pty_pair.slave_path}",
                  file=announce, flush=True)
        clock = DeadlineClock(rate)
        n = int(round(duration_s * rate)) if duration_s else None
        was_open = False
        clock.start()
        k = 0
        while not stop[0] and (n is None or k < n):
            dev.collect(k)
            if exit_on_close:  # a whole session (open ... close) may have come and gone within one tick
                is_open = bool(getattr(bus, "is_open", True))
                was_open = was_open or is_open or getattr(bus, "times_opened", 0) > 0
                if was_open and not is_open:
                    break
            dev.publish(k)
            k += 1
            clock.wait()
        dev.collect(k)
        dropped = int(getattr(bus, "tx_dropped", 0))
        if status is not None:
            print(f"simulated device: {k} ticks at {rate:g} Hz, sent {dev.frames_sent - dropped} sensor frames"
                  + (f" ({dropped} dropped while the channel was closed)" if dropped else "")
                  + f", received {dev.frames_received} actuator frames", file=status, flush=True)
        return k
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        bus.shutdown()
        if pty_pair is not None:
            pty_pair.close()
