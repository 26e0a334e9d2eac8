"""The live loop: CAN frames in, one graph tick, guarded CAN frames out, at the graph's rate.

Per tick (the order is the contract replay relies on, see docs/live.md):

1. wait for the tick's deadline (:class:`~flowtex.runtime.clock.DeadlineClock`); 50 us
   before it, receive the frames already there and make one effect-free warming
   pass through the tick's code (:func:`_warmer`);
2. receive every frame that arrived since (``bus.recv_available()`` if the bus has
   it, else ``bus.recv(timeout=0)`` until None): the tick's inputs are every frame
   received before its compute starts; store each payload the compiled
   decoder takes as one integer (:func:`_rx_decoder`), decode the others with the
   generated Python codecs; inputs hold their last value between frames;
3. one compiled call (:mod:`flowtex.runtime.fused`): decode the stored payloads
   straight into the graph's input arena and mark their watchdog entries fresh,
   one graph tick, the watchdog's quiet case, gather the bound graph outputs, the
   :class:`OutputGuard` kernel (clamp, NaN/inf -> safe, peak allowance), encode every
   actuator payload into its reused frame. Any other watchdog case goes through
   :meth:`Watchdog.check` (stale input or overrun -> safe values) and
   :meth:`CanIO.guard_and_encode`. Graphs that cannot be fused make the same steps
   as three compiled calls (decoder, ``graph.step_block(1)``, :func:`_tick_out`);
4. send exactly one frame per actuator message, in map order (``send_many`` if
   the bus has it);
5. in the slack: write the tick's received and sent frames to the ``--record``
   log, step the simulated device, statistics and the status line.

On every exit path (duration reached, Ctrl-C, SIGTERM, exception in the graph,
bus error) the safe values are encoded and sent once more, as the last frames
(and logged). Steps 2-3 allocate nothing beyond python-can's own message objects
and small ints; the garbage collector is frozen during the loop. Compute time in
the statistics is steps 2-3 without the bus receive.
"""

from __future__ import annotations

import contextlib
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
from numba import njit

from ..errors import DataError, FlowtexError
from ..io.canlog import SessionWriter
from ..io.canmap import CanMap, load_map
from ..io.codec import _NF, _NI, MessageCodec, TableDecoder, TableEncoder, _encode_tables, decode_packed, fast_ok, pack_int64
from ..io.dbc import load_dbc
from .clock import DeadlineClock
from .fused import FusedTick, fuse_tick
from .realtime import enter_realtime, freeze_gc, leave_realtime
from .safety import OutputGuard, Watchdog, all_updated_after, first_stale, guard_kernel
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

    Two equivalent paths: the generated Python codecs (:meth:`decode`, always
    available) and, when the graph's ports live in one float64 arena (the compiled
    :class:`~flowtex.graph.compiled.Graph`), table-driven compiled codecs
    (:class:`~flowtex.io.codec.TableDecoder`/:class:`~flowtex.io.codec.TableEncoder`):
    one call decodes every sensor payload of a tick straight into the arena, one call
    gathers the outputs, applies the guard and encodes every actuator payload. Both give
    identical values and bytes (tested against cantools).
    """

    def __init__(self, graph: Any, canmap: CanMap, codecs: Mapping[str, MessageCodec], rate_hz: float):
        self.graph = graph
        self.map = canmap
        self.codecs = codecs
        arena = _arena(graph, canmap)
        self.arena = arena
        # inputs -> decoders
        wd_keys: list[tuple[str, str]] = []
        wd_timeouts: list[int] = []
        per_msg: dict[str, list[Any]] = {}
        per_msg_idx: dict[str, list[Any]] = {}
        for b in canmap.inputs.values():
            view = graph.input_view(b.name)
            base = _offset(arena, view)
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                targets = per_msg.setdefault(m, [None] * len(c.signals))
                targets[c.index[s]] = (view, j, float(b.scale[j]), float(b.offset[j]))
                if base is not None:
                    per_msg_idx.setdefault(m, [None] * len(c.signals))[c.index[s]] = (base + j, float(b.scale[j]), float(b.offset[j]))
                if (b.name, m) not in wd_keys:
                    wd_keys.append((b.name, m))
                    wd_timeouts.append(max(1, math.ceil(b.timeout_ms * rate_hz / 1000.0 - 1e-9)))
        self.watchdog_keys = wd_keys
        self.timeouts_ticks = np.array(wd_timeouts, dtype=np.int64)
        self.decoders: dict[int, tuple[Callable[[Any], bool], tuple[int, ...]]] = {}
        fast_in = []
        for m, targets in per_msg.items():
            c = codecs[m]
            if c.frame_id in self.decoders:
                raise DataError(f"two sensor messages share frame id {c.frame_id:#x}")
            entries = tuple(i for i, (_, mm) in enumerate(wd_keys) if mm == m)
            self.decoders[c.frame_id] = (c.decoder(targets), entries)
            if arena is not None and fast_ok(c) and len(fast_in) < 62:
                fast_in.append((c, per_msg_idx[m], entries))
        self.table_decoder = TableDecoder(fast_in) if fast_in else None
        """Compiled decoder of the sensor messages it can take (None: Python decoders only)."""
        # outputs -> guard -> encoders
        self.out_names = list(canmap.outputs)
        widths = [canmap.outputs[n].width for n in self.out_names]
        total = int(sum(widths))
        rows = sum(len(codecs[m].signals) for m in canmap.actuator_messages() if fast_ok(codecs[m]))
        self._fbuf = np.zeros(7 * total + _NF * rows)
        """Float tables of the compiled output call: raw outputs | guarded outputs | guard parameters (5 x n) | encoder table."""
        self.raw = self._fbuf[:total]
        self.out = self._fbuf[total:2 * total]
        self._copies: list[tuple[np.ndarray, np.ndarray]] = []
        gather: list[int] = []
        lo, hi, safe, plo, phi, pmax = [], [], [], [], [], []
        start = 0
        sources: dict[str, list[Any]] = {}
        for name, w in zip(self.out_names, widths, strict=True):
            b = canmap.outputs[name]
            view = graph.output_view(name)
            self._copies.append((view, self.raw[start:start + w]))
            base = _offset(arena, view)
            gather.extend(range(base, base + w) if base is not None else [])
            lo.extend(b.lo)
            hi.extend(b.hi)
            safe.extend(b.safe)
            lim = b.peak_limit if b.peak_limit is not None else b.hi
            phi.extend(lim)
            plo.extend(peak_low(b.lo, b.hi, lim))
            pmax.extend([int(round(b.peak_ms * rate_hz / 1000.0)) if b.peak_limit is not None else 0] * w)
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                src = sources.setdefault(m, [None] * len(c.signals))
                src[c.index[s]] = (self.out, start + j, float(b.scale[j]), float(b.offset[j]))
            start += w
        self.guard = OutputGuard(np.array(lo), np.array(hi), np.array(safe), peak_hi=np.array(phi), peak_lo=np.array(plo),
                                 peak_max_ticks=np.array(pmax, dtype=np.int64)) if total else None
        # gather indices into the arena (the compiled path), or None: copy through the views
        self._gather = np.array(gather, dtype=np.int64) if arena is not None and total else None
        self._gfp, self._gip = self.guard.tables if self.guard is not None else (None, None)
        self.tx: list[can.Message] = []
        self.encoders: list[Callable[[bytearray], None]] = []
        fast_out = []
        self._tx_fast: list[tuple[bytearray, memoryview]] = []
        """(frame data, its bytes in the table encoder's payload) for the compiled actuator messages: ``data[:] = src``
        copies without allocating."""
        self._tx_slow: list[tuple[Callable[[bytearray], None], bytearray]] = []
        for m in canmap.actuator_messages():
            c = codecs[m]
            msg = can.Message(arbitration_id=c.frame_id, is_extended_id=c.is_extended, is_fd=c.is_fd,
                              data=bytearray(c.length), is_rx=False)
            self.tx.append(msg)
            enc = c.encoder(sources[m])
            self.encoders.append(enc)
            if fast_ok(c) and self.guard is not None:
                fast_out.append((c, [None if t is None else (t[1], t[2], t[3]) for t in sources[m]], msg))
            else:
                self._tx_slow.append((enc, msg.data))
        te = self.table_encoder = TableEncoder([(c, src) for c, src, _ in fast_out]) if fast_out else None
        self._ibuf = None
        """Integer tables of the compiled output call (None: no compiled output path), see :func:`_out_packed`."""
        if te is not None:
            offs = te.offsets
            whole = memoryview(te.payload)
            self._tx_fast = [(msg.data, whole[int(offs[i]):int(offs[i + 1])]) for i, (_, _, msg) in enumerate(fast_out)]
            if self._gather is not None:
                nm, r = len(fast_out), te.itab.shape[0]
                self._ibuf, (self._gather, te.offsets, te._words, te._scratch, te.itab, _), o = pack_int64(
                    [self._gather, te.offsets, te._words, te._scratch, te.itab, self.timeouts_ticks], header=16)
                self._ibuf[:10] = [total, o[0], nm, o[1], o[2], o[3], r, o[4], self.timeouts_ticks.shape[0], o[5]]
                self._fbuf[2 * total:7 * total] = self._gfp.reshape(-1)
                self._fbuf[7 * total:] = te.ftab.reshape(-1)
                te.ftab = self._fbuf[7 * total:].reshape(r, _NF)
        self.tx_ids = [(m.arbitration_id, m.is_extended_id) for m in self.tx]
        self._warm_up()

    def _warm_up(self) -> None:
        """Compile (or load from numba's disk cache) the compiled codec calls now, not on the first live tick.

        Nothing observable changes: mask 0 decodes nothing, and forced-safe guarding
        leaves the peak counters alone; the frames are re-encoded before any send.
        """
        if self.table_decoder is not None:
            self.table_decoder.run(0, 0, self.arena, np.zeros(1, dtype=np.int64))
        if self.guard is not None:
            self.guard_and_encode(True)
            if self._ibuf is not None:
                _tick_out(self.arena, self._ibuf, self._fbuf, self._gip, np.zeros(1, dtype=np.int64), self.table_encoder.payload_view,
                          0, 0, 0, True)
            self.guard_outputs(True)
            self.encode()

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
        if self.guard is None:
            return 0
        if self._gather is not None:
            return _gather_guard(self.arena, self._gather, self.raw, self.out, self._gfp, self._gip, force_safe)
        for src, dst in self._copies:
            dst[:] = src
        return self.guard.apply(self.raw, self.out, force_safe)

    def encode(self) -> None:
        """Encode ``self.out`` into the reusable actuator frames ``self.tx``."""
        if self.table_encoder is not None:
            self.table_encoder.run(self.out)
        self.fill_frames()

    def fill_frames(self) -> None:
        """Copy the encoded payloads into the actuator frames ``self.tx``; run the Python encoders of the others."""
        for data, src in self._tx_fast:
            data[:] = src
        for enc, data in self._tx_slow:
            enc(data)

    def guard_and_encode(self, force_safe: bool) -> int:
        """:meth:`guard_outputs` then :meth:`encode` (one compiled call when possible); returns the guard's event count."""
        if self._ibuf is None:
            events = self.guard_outputs(force_safe)
            self.encode()
            return events
        events = _out_packed(self.arena, self._ibuf, self._fbuf, self._gip, self.table_encoder.payload_view, force_safe)
        self.fill_frames()
        return events

    def encode_safe(self) -> None:
        """Encode every output's safe value into ``self.tx``."""
        if self.guard is not None:
            self.guard.safe_values(self.out)
        self.encode()


def peak_low(lo: np.ndarray, hi: np.ndarray, limit: np.ndarray) -> np.ndarray:
    """Lower peak bound for a map's ``peak: {limit: L}``: the margin above HIGH mirrored below LOW, ``LOW - (L - HIGH)``.

    The map's ``limit`` is the largest value a transient may reach above the clamp
    (``|value| up to L`` for a symmetric clamp ``[-H, H]``, where this gives ``-L``);
    for an asymmetric clamp the same margin ``L - HIGH`` is allowed below ``LOW``.
    """
    return np.asarray(lo, dtype=np.float64) - (np.asarray(limit, dtype=np.float64) - np.asarray(hi, dtype=np.float64))


def _arena(graph: Any, canmap: CanMap) -> np.ndarray | None:
    """The one C-contiguous float64 array every bound port view lives in, else None (then the Python path is used)."""
    views = [graph.input_view(n) for n in canmap.inputs] + [graph.output_view(n) for n in canmap.outputs]
    if not views:
        return None
    base = views[0].base
    if not isinstance(base, np.ndarray) or base.dtype != np.float64 or base.ndim != 1 or not base.flags.c_contiguous:
        return None
    for v in views:
        if v.base is not base or v.dtype != np.float64 or v.ndim != 1 or not v.flags.c_contiguous:
            return None
    return base


def _offset(arena: np.ndarray | None, view: np.ndarray) -> int | None:
    """Index of ``view[0]`` in ``arena``."""
    if arena is None:
        return None
    delta = view.__array_interface__["data"][0] - arena.__array_interface__["data"][0]
    return delta // arena.itemsize


@njit(cache=True)
def _gather_guard(arena, gather, raw, out, gfp, gip, force_safe):  # pragma: no cover - compiled
    for i in range(gather.shape[0]):
        raw[i] = arena[gather[i]]
    return guard_kernel(gfp, gip, raw, out, force_safe)


@njit(cache=True)
def _out_packed(arena, ib, fb, gip, payload, force_safe):  # pragma: no cover - compiled
    """Gather the bound graph outputs from the arena, guard them, encode every compiled actuator payload; returns guard events.

    ``ib`` (int64) header: outputs n, gather offset, messages, payload offsets offset, words offset,
    scratch offset, encoder rows, encoder table offset, watchdog entries, timeouts offset; ``fb``
    (float64): raw n | guarded n | guard parameters 5 x n | encoder table (see ``CanIO.__init__``).
    """
    n, og, nm, oo, ow, osc, r, oi = ib[0], ib[1], ib[2], ib[3], ib[4], ib[5], ib[6], ib[7]
    gather = ib[og:og + n]
    raw = fb[:n]
    out = fb[n:2 * n]
    for i in range(n):
        raw[i] = arena[gather[i]]
    events = guard_kernel(fb[2 * n:7 * n].reshape((5, n)), gip, raw, out, force_safe)
    _encode_tables(out, ib[oi:oi + r * _NI].reshape((r, _NI)), fb[7 * n:7 * n + r * _NF].reshape((r, _NF)), ib[oo:oo + nm + 1],
                   ib[ow:ow + 2 * nm].reshape((nm, 2)), payload, ib[osc:osc + 1])
    return events


def _entry_point(fn: Any) -> Callable[..., Any]:
    """The compiled entry point of a numba function compiled for exactly one signature
    (by the warm-up before the loop): calling it skips numba's per-call type dispatch,
    about 0.1-0.2 us per array argument. Otherwise the function itself."""
    sigs = getattr(fn, "signatures", ())
    return fn.overloads[sigs[0]].entry_point if len(sigs) == 1 else fn


@njit(cache=True)
def _tick_out(arena, ib, fb, gip, wd_last, payload, tick, overrun_ns, overrun_limit_ns, tripped):  # pragma: no cover - compiled
    """The quiet tick's watchdog test, then :func:`_out_packed`; -1 (nothing done) when the watchdog needs its own check.

    Quiet means: not tripped, no input older than its timeout, no overrun; then
    :meth:`Watchdog.check` would return False and change nothing, so the outputs are
    guarded unforced. Otherwise the caller runs ``Watchdog.check`` and ``CanIO.guard_and_encode``.
    """
    if tripped or overrun_ns > overrun_limit_ns:
        return -1
    nw, ot = ib[8], ib[9]
    if first_stale(wd_last, ib[ot:ot + nw], tick) >= 0:
        return -1
    return _out_packed(arena, ib, fb, gip, payload, False)


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


def _receiver(bus: can.BusABC) -> Callable[[list[Any]], None]:
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


def _rx_decoder(io: CanIO, watchdog: Watchdog) -> Callable[[list[Any], int, Any], int]:
    """``decode_rx(rx, tick, words) -> mask``: step 2 of a tick for the received frames ``rx``.

    A frame the compiled decoder takes has its payload stored as one integer in
    ``words[slot]`` and its bit set in the returned mask (for :func:`decode_packed`);
    any other mapped frame goes through its generated Python decoder into the graph
    inputs and marks its watchdog entries fresh at ``tick``. An error frame reporting
    bus-off raises :class:`BusError`.
    """
    td = io.table_decoder
    slot_get = td.slot_of.get if td is not None else {}.get
    slot_len = td.lengths if td is not None else []
    from_bytes = int.from_bytes
    decoders = io.decoders
    fresh = watchdog.fresh

    def decode_rx(rx: list[Any], tick: int, words: Any) -> int:
        mask = 0
        for msg in rx:
            if msg.is_error_frame:
                if msg.arbitration_id & CAN_ERR_BUSOFF:
                    raise BusError("CAN bus went bus-off (error frame with CAN_ERR_BUSOFF)")
                continue
            j = slot_get(msg.arbitration_id)
            if j is not None:
                data = msg.data
                if len(data) == slot_len[j]:
                    words[j] = from_bytes(data, "little", signed=True)
                    mask |= 1 << j
                    continue
                mask &= ~(1 << j)  # an odd-length frame after a regular one: the later frame wins
            entry = decoders.get(msg.arbitration_id)
            if entry is not None and entry[0](msg.data):
                for w in entry[1]:
                    fresh(w, tick)
        return mask

    return decode_rx


def _warmer(io: CanIO, watchdog: Watchdog, fused: FusedTick | None, decode_rx: Callable[[list[Any], int, Any], int]) -> Callable[[], None]:
    """One effect-free pass through a tick's code, for the clock to call shortly before each deadline.

    After the clock's sleep the tick's first run was 2-4x slower than in a tight loop
    (see :mod:`flowtex.runtime.clock`); this re-runs its Python and compiled parts
    with nothing observable changing: the Python decode on one template frame per
    compiled slot into scratch words, then the fused tick on scratch copies of the
    arenas and watchdog stamps with ``tripped=True`` (the output call returns before
    touching anything). Without a fused tick: the decoder with mask 0, the output call
    tripped, and :meth:`Graph.warm`.
    """
    td, te = io.table_decoder, io.table_encoder
    calls: list[Callable[[], Any]] = []
    if td is not None:
        templates = [can.Message(arbitration_id=fid, is_extended_id=fid > 0x7FF, data=bytearray(int(td.lengths[j])))
                     for fid, j in td.slot_of.items()]
        scratch_words = np.zeros_like(td.words)
        calls.append(lambda: decode_rx(templates, 0, scratch_words))
    if fused is not None:
        every_slot = (1 << len(td.slot_of)) - 1 if td is not None else 0
        calls.append(lambda: fused.warm(every_slot))
    else:
        if td is not None:
            args = (td.ibuf, td.fbuf, 0, 0, io.arena, watchdog.last)
            calls.append(lambda: decode_packed(*args))
        if io._ibuf is not None:
            out_args = (io.arena, io._ibuf, io._fbuf, io._gip, watchdog.last, te.payload_view, 0, 0, 0, True)
            calls.append(lambda: _tick_out(*out_args))
        calls.append(io.graph.warm)

    def warm() -> None:
        for c in calls:
            c()

    return warm


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
             max_ticks: int | None = None, warm: bool = True) -> LiveReport:
    """Run ``graph`` live against a CAN bus until ``duration_s`` (None: until Ctrl-C/SIGTERM).

    ``simulate``: a recording path (or :class:`~flowtex.io.recordings.Recording`);
    a :class:`SimulatedDevice` then runs in this process on a private ``virtual``
    bus, stepped once per executed tick, and ``bus`` must be None or ``virtual``.
    ``drop`` (simulation only) silences sensor messages: name -> (first tick, stop tick or None).
    ``max_ticks`` ends the session after that many executed ticks (deterministic
    length for tests). The session runs on ``graph.with_block_rows(1)`` (same code,
    parameters and seed, one-row port buffers), so ``graph`` itself is not stepped.
    ``warm``: cache warming before each deadline (see :func:`_warmer`). Raises :class:`FlowtexError` for bad files or a bus that cannot
    be opened; failures during the loop end the session with safe values and are
    returned in ``LiveReport.error``.
    """
    relayout = getattr(graph, "with_block_rows", None)
    if relayout is not None:  # one tick per call: port buffers of one row keep the tick's data in a few KB
        graph = relayout(1)
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
                     stats_path, seed, status, install_signals, warm)
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
          stats_path: str | Path | None, seed: int | None, status: TextIO | None, install_signals: bool, warm: bool) -> LiveReport:
    n_ticks = max_ticks
    if duration_s is not None:
        if not duration_s > 0:
            raise FlowtexError(f"--duration must be a positive number of seconds, got {duration_s!r}")
        n_ticks = min(n_ticks or 1 << 62, int(round(duration_s * rate)))
    capacity = int(min(n_ticks if n_ticks else 600 * rate, 3600 * rate)) + 1
    stats = TickStats(capacity)
    send_offset = np.zeros(capacity, dtype=np.int64)
    # with a status line, events are printed on their own lines with names (below), not through logging
    watchdog = io.new_watchdog(int(round(io.map.overrun_limit_ms * 1e6)), emit_log=status is None)
    wd_log = watchdog.log
    events_shown = 0
    status_len = 0
    # Load the watchdog's compiled checks now (pure functions), not on the first live tick.
    first_stale(watchdog.last, watchdog.timeouts, 0)
    all_updated_after(watchdog.last, 0)
    graph.warm()
    fused = fuse_tick(graph, io, _tick_out, watchdog.last)
    decode_rx = _rx_decoder(io, watchdog)
    receive = _receiver(bus)
    rx: list[Any] = []
    """Frames received for the current tick: those already there shortly before its deadline, then the rest."""
    warm_pass = _warmer(io, watchdog, fused, decode_rx) if warm else None

    def prepare() -> None:  # shortly before each deadline (bus time and warming, not compute)
        receive(rx)
        if warm_pass is not None:
            warm_pass()

    clock = DeadlineClock(rate, prepare=prepare)
    period = clock.period_ns
    graph.reset(seed)
    rt_granted = False
    rt_message = ""
    rt_status = None
    if rt:
        rt_status = enter_realtime(rt_priority, rt_cpu)
        rt_granted, rt_message = bool(rt_status.granted), str(rt_status.message)
        if rt_granted and not rt_message:
            rt_message = f"--rt: SCHED_FIFO priority {rt_status.priority}, pinned to CPU {rt_status.cpu}"
        if status is not None and rt_message:
            print(rt_message, file=status)
    stop: list[str | None] = [None]
    error: str | None = None
    guard_events = 0
    status_every = max(1, int(rate / 2))
    send = bus.send
    send_many = getattr(bus, "send_many", None)
    # compiled codecs: sensor payload words by slot, decoded in one call per tick
    td = io.table_decoder
    words = td.words if td is not None else None
    arena = io.arena
    wd_last = watchdog.last
    check = watchdog.check
    step = graph.step_block
    guard_and_encode = io.guard_and_encode
    out_fused = io._ibuf is not None
    tick_out = _entry_point(_tick_out)
    decode_packed_ = _entry_point(decode_packed)
    overrun_limit = watchdog.overrun_limit_ns
    tx_fast, tx_slow = io._tx_fast, io._tx_slow
    if fused is not None:  # the whole tick in one compiled call
        live_tick, ptrs = fused.call, fused.ptrs
    d_ib, d_fb = (td.ibuf, td.fbuf) if td is not None else (None, None)
    o_ib, o_fb, gip = io._ibuf, io._fbuf, io._gip
    e_payload = io.table_encoder.payload_view if out_fused else None
    tx = io.tx
    n_tx = len(tx)
    now = time.perf_counter_ns
    k = 0
    if device is not None:
        device.publish(0)
    with _stop_signals(stop, install_signals), freeze_gc():
        clock.start()
        lateness = 0
        overrun = 0
        try:
            while True:
                # 2. receive whatever arrived since prepare() (bus time, not compute)
                receive(rx)
                t0 = now()
                # 2. decode: payload words for the compiled decoder, Python codecs for the rest
                mask = decode_rx(rx, k, words)
                # 3. compiled decode, one graph tick, watchdog, guard, encode. The watchdog counts executed ticks
                # (replay recomputes it exactly); its quiet case is tested in compiled code, anything else goes
                # through Watchdog.check.
                if fused is not None:  # also fills the compiled messages' frames
                    ev = live_tick(ptrs, mask, k, overrun, overrun_limit, watchdog.tripped)
                    if ev >= 0:
                        for enc, data in tx_slow:
                            enc(data)
                else:
                    if mask:
                        decode_packed_(d_ib, d_fb, mask, k, arena, wd_last)
                    step(1)
                    ev = tick_out(arena, o_ib, o_fb, gip, wd_last, e_payload, k, overrun, overrun_limit, watchdog.tripped) if out_fused else -1
                    if ev >= 0:
                        for data, src in tx_fast:
                            data[:] = src
                        for enc, data in tx_slow:
                            enc(data)
                if ev < 0:
                    ev = guard_and_encode(check(k, overrun))
                guard_events += ev
                t1 = now()
                # 4. send
                if send_many is not None:
                    send_many(tx)
                else:
                    for m in tx:
                        send(m)
                t2 = now()
                # 5. slack
                n_in = len(rx)
                stats.record(lateness, t1 - t0)
                send_offset[k % capacity] = t2 - clock.deadline_ns
                stats.frames_in += n_in
                stats.frames_out += n_tx
                if writer is not None:
                    ts = time.time()
                    for m in rx:
                        writer.write(m, True)
                    for m in tx:
                        m.timestamp = ts
                        writer.write(m, False)
                rx.clear()
                k += 1
                if device is not None:
                    device.collect(k - 1)
                    device.publish(k)
                if stop[0] is not None or (n_ticks is not None and k >= n_ticks):
                    break
                if status is not None:
                    if len(wd_log) != events_shown:
                        events_shown = _print_events(io, watchdog, events_shown, status, status_len)
                    if k % status_every == 0:
                        stats.watchdog_events = watchdog.events
                        stats.timeouts = watchdog.stale_events
                        line = stats.status_line()
                        status_len = len(line)
                        print("\r" + line, end="", file=status, flush=True)
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
            if rt_status is not None:
                leave_realtime(rt_status)
    if safe_error and error is None:
        error = safe_error
    elif safe_error:
        error += f"; {safe_error}"
    stats.watchdog_events = watchdog.events
    stats.timeouts = watchdog.stale_events
    if status is not None:
        _print_events(io, watchdog, events_shown, status, status_len)
        print("\r" + stats.status_line(), file=status)
        print(stats.format_summary(rt_granted), file=status)
    if stats_path is not None:
        stats.write_json(stats_path, rt_granted)
    reason = "error" if error else (stop[0] or "duration")
    return LiveReport(ticks=k, frames_in=stats.frames_in, frames_out=stats.frames_out, watchdog_events=watchdog.events,
                      guard_events=guard_events, exit_reason=reason, error=error, summary=stats.summary(rt_granted),
                      rt_message=rt_message, send_offset_ns=send_offset[:min(k, capacity)], device=device)


def describe_event(io: CanIO, watchdog: Watchdog, tick: int, reason: str, detail: int) -> str:
    """One line for a watchdog event of ``watchdog.log`` (``reason`` "stale": ``detail`` is the watchdog entry;
    "overrun": how late the tick started, in ns), naming the graph input and sensor message."""
    if reason == "stale":
        name, message = io.watchdog_keys[detail]
        what = f"no {message} frame for input {name!r} in {int(watchdog.timeouts[detail])} ticks"
    else:
        what = f"the tick started {detail / 1e6:.2f} ms late (limit {watchdog.overrun_limit_ns / 1e6:g} ms)"
    return f"watchdog: tick {tick}: {what}; outputs safe until every sensor has sent a fresh frame"


def _print_events(io: CanIO, watchdog: Watchdog, shown: int, status: TextIO, status_len: int) -> int:
    """Print the watchdog events after the first ``shown`` on their own lines, over the status line; returns how many are shown."""
    for tick, reason, detail in watchdog.log[shown:]:
        line = describe_event(io, watchdog, tick, reason, detail)
        print("\r" + line.ljust(status_len), file=status, flush=True)
    return len(watchdog.log)


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
