"""The runtime side of a CAN map: sensor frames into the graph's inputs, guarded graph outputs into actuator frames.

:class:`CanIO` is shared by the live loop and the replay so that both compute frames
the same way: decoders from DBC payloads into graph inputs (with one watchdog entry
per graph input and sensor message), the :class:`~flowtex.runtime.safety.OutputGuard`
of the map's clamps and peak rules, and encoders into reusable ``can.Message`` frames.
The compiled output calls (:func:`tick_out`, :func:`out_packed`) gather the bound graph
outputs from the graph's float64 arena, guard and encode them in one call; the live
loop calls them directly or inside its fused tick (:mod:`flowtex.runtime.fused`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import numpy as np
from numba import njit

from ..cache import configure_numba_cache
from ..errors import DataError
from ..graph.program import TickProgram
from ..io.canmap import CanMap, map_for_ports
from ..io.codec import MessageCodec
from ..io.codec_tables import _NF, _NI, TableDecoder, TableEncoder, _encode_tables, fast_ok, pack_int64
from ..io.dbc import load_dbc
from ..node_decl import PortSpec
from .safety import OutputGuard, Watchdog, budget_units, first_stale, guard_kernel

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)


PythonEncoder = Callable[[bytearray], None]
"""A generated per-message encoder (:meth:`~flowtex.io.codec.MessageCodec.encoder`): packs its message into a frame's data."""


@dataclass(frozen=True)
class CompiledCodec:
    """Everything the compiled live tick reads or writes of a :class:`CanIO`: its public seam to the runtime.

    Built once by :class:`CanIO`; the arrays are the CanIO's own tables (the compiled
    calls write through them), not copies. :mod:`flowtex.runtime.tick` and
    :mod:`flowtex.runtime.fused` take every table from here.
    """

    arena: np.ndarray
    """The graph's float64 arena every bound port lives in (:attr:`TickProgram.f`)."""
    decoder: TableDecoder | None
    """Compiled decoder of the sensor messages it can take; None: Python decoders only."""
    encoder: TableEncoder | None
    """Compiled encoder of the actuator messages it can take (its ``payload`` holds their bytes); None: Python encoders only."""
    out_ints: np.ndarray | None
    """int64 tables of the compiled output call (:func:`out_packed`, :func:`tick_out`; header in :func:`out_packed`).
    None exactly when :attr:`encoder` is None: then :meth:`CanIO.guard_and_encode` guards and encodes in separate steps."""
    out_floats: np.ndarray
    """float64 tables of the output call: raw outputs | guarded outputs | guard parameters (5 x n) | encoder table."""
    guard_ints: np.ndarray | None
    """The output guard's int64 state (peak budgets, event counts, :attr:`OutputGuard.tables`); None: no bound output."""
    fast_frames: tuple[tuple[bytearray, memoryview], ...]
    """Per compiled actuator message, in :attr:`encoder` order: (its frame's data, its bytes in the encoder's payload);
    ``data[:] = src`` copies without allocating."""
    python_frames: tuple[tuple[PythonEncoder, bytearray], ...]
    """Per other actuator message: (its generated Python encoder, its frame's data)."""

    @property
    def payload(self) -> np.ndarray | None:
        """The encoder's payload bytes as a uint8 array (what the compiled output call writes), None without an encoder."""
        return self.encoder.payload_view if self.encoder is not None else None


class CanIO:
    """Decoders into graph inputs, the output guard and encoders into reusable frames.

    Watchdog entries are one per (graph input, sensor message) pair, so a vector input
    assembled from several messages goes stale when any of them stops.

    Two equivalent paths: the generated Python codecs (:meth:`decode`, always
    available) and table-driven compiled codecs on the graph's float64 arena
    (:class:`~flowtex.io.codec_tables.TableDecoder`/:class:`~flowtex.io.codec_tables.TableEncoder`):
    one call decodes every sensor payload of a tick straight into the arena, one call
    gathers the outputs, applies the guard and encodes every actuator payload. Both give
    identical values and bytes (tested against cantools). The compiled path is kept because
    it pays: ``benchmarks/bench_live_paths.py`` (section ``codec``) measures both side by side.
    The Python path stays as the general one: messages the tables cannot take exactly
    (:func:`~flowtex.io.codec_tables.fast_ok`), frames of an unexpected length, the replay's decode.
    What the compiled tick needs is :attr:`codec`.
    """

    def __init__(self, graph: TickProgram, canmap: CanMap, codecs: Mapping[str, MessageCodec], rate_hz: float):
        self.graph = graph
        self.map = canmap
        self.codecs = codecs
        arena = _arena(graph, canmap)
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
                per_msg_idx.setdefault(m, [None] * len(c.signals))[c.index[s]] = (base + j, float(b.scale[j]), float(b.offset[j]))
                if (b.name, m) not in wd_keys:
                    wd_keys.append((b.name, m))
                    wd_timeouts.append(ticks_at_least(b.timeout_ms, rate_hz))
        self.watchdog_keys = wd_keys
        self.timeouts_ticks = np.array(wd_timeouts, dtype=np.int64)
        self.decoders: dict[int, tuple[Callable[[Any], bool], tuple[int, ...], bool]] = {}
        """Frame id -> (Python decoder, watchdog entries it stamps, whether the message is an extended frame)."""
        fast_in = []
        for m, targets in per_msg.items():
            c = codecs[m]
            if c.frame_id in self.decoders:
                raise DataError(f"two sensor messages share frame id {c.frame_id:#x}")
            entries = tuple(i for i, (_, mm) in enumerate(wd_keys) if mm == m)
            self.decoders[c.frame_id] = (c.decoder(targets), entries, bool(c.is_extended))
            if fast_ok(c) and len(fast_in) < 62:
                fast_in.append((c, per_msg_idx[m], entries))
        table_decoder = TableDecoder(fast_in) if fast_in else None
        # outputs -> guard -> encoders
        self.out_names = list(canmap.outputs)
        self.out_widths = widths = [canmap.outputs[n].width for n in self.out_names]
        total = int(sum(widths))
        rows = sum(len(codecs[m].signals) for m in canmap.actuator_messages() if fast_ok(codecs[m]))
        fbuf = np.zeros(7 * total + _NF * rows)
        self.raw = fbuf[:total]
        self.out = fbuf[total:2 * total]
        gather: list[int] = []
        lo, hi, safe, plo, phi, pmax, prec = [], [], [], [], [], [], []
        start = 0
        sources: dict[str, list[Any]] = {}
        for name, w in zip(self.out_names, widths, strict=True):
            b = canmap.outputs[name]
            view = graph.output_view(name)
            base = _offset(arena, view)
            gather.extend(range(base, base + w))
            bounds = b.guard  # the map's clamp and peak range snapped onto the DBC's grid (flowtex.io.mapsafety)
            if bounds is None:
                raise DataError(f"{b.loc}: output {name!r} has no guard bounds: load the map with flowtex.io.canmap.load_map")
            lo.extend(bounds.lo)
            hi.extend(bounds.hi)
            safe.extend(b.safe)
            phi.extend(bounds.peak_hi)
            plo.extend(bounds.peak_lo)
            p_ticks, r_ticks = ticks_at_most(b.peak_ms, rate_hz) if b.peak_limit is not None else 0, ticks_at_least(b.recover_ms, rate_hz)
            try:
                budget_units(p_ticks, r_ticks)
            except ValueError:
                raise DataError(f"{b.loc}: output {name!r}: peak max_ms {b.peak_ms:.12g} and recover_ms {b.recover_ms:.12g} are "
                                f"{p_ticks} and {r_ticks} ticks at {rate_hz:g} Hz, an allowance the guard cannot count in 64-bit "
                                "integers; shorten max_ms or recover_ms, or make one a multiple of the other") from None
            pmax.extend([p_ticks] * w)
            prec.extend([r_ticks] * w)
            for j, (m, s) in enumerate(b.signals):
                c = codecs[m]
                src = sources.setdefault(m, [None] * len(c.signals))
                src[c.index[s]] = (self.out, start + j, float(b.scale[j]), float(b.offset[j]))
            start += w
        self.guard = OutputGuard(np.array(lo), np.array(hi), np.array(safe), peak_hi=np.array(phi), peak_lo=np.array(plo),
                                 peak_max_ticks=np.array(pmax, dtype=np.int64), peak_recover_ticks=np.array(prec, dtype=np.int64)
                                 ) if total else None
        # where the bound outputs are in the arena, in map order (None: no bound output)
        self._gather = np.array(gather, dtype=np.int64) if total else None
        self._gfp, gip = self.guard.tables if self.guard is not None else (None, None)
        self.tx: list[can.Message] = []
        self.encoders: list[PythonEncoder] = []
        fast_out = []
        tx_fast: list[tuple[bytearray, memoryview]] = []
        tx_slow: list[tuple[PythonEncoder, bytearray]] = []
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
                tx_slow.append((enc, msg.data))
        te = TableEncoder([(c, src) for c, src, _ in fast_out]) if fast_out else None
        ibuf = None
        if te is not None:
            offs = te.offsets
            whole = memoryview(te.payload)
            tx_fast = [(msg.data, whole[int(offs[i]):int(offs[i + 1])]) for i, (_, _, msg) in enumerate(fast_out)]
            nm, r = len(fast_out), te.itab.shape[0]  # an encoder implies a bound output, hence a guard and gather indices
            ibuf, (self._gather, *tables, _), o = pack_int64([self._gather, *te.int_tables(), self.timeouts_ticks], header=16)
            ibuf[:10] = [total, o[0], nm, o[1], o[2], o[3], r, o[4], self.timeouts_ticks.shape[0], o[5]]
            fbuf[2 * total:7 * total] = self._gfp.reshape(-1)
            fbuf[7 * total:] = te.ftab.reshape(-1)
            te.rebind(tables, fbuf[7 * total:].reshape(r, _NF))
        self.codec = CompiledCodec(arena=arena, decoder=table_decoder, encoder=te, out_ints=ibuf, out_floats=fbuf, guard_ints=gip,
                                   fast_frames=tuple(tx_fast), python_frames=tuple(tx_slow))
        """The compiled codec: every table and frame the compiled live tick uses (:class:`CompiledCodec`)."""
        self.tx_ids = [(m.arbitration_id, m.is_extended_id) for m in self.tx]
        self._warm_up()

    @property
    def arena(self) -> np.ndarray:
        """The graph's float64 arena every bound port lives in (:attr:`CompiledCodec.arena`)."""
        return self.codec.arena

    @property
    def table_decoder(self) -> TableDecoder | None:
        """Compiled decoder of the sensor messages it can take, or None (:attr:`CompiledCodec.decoder`)."""
        return self.codec.decoder

    @property
    def table_encoder(self) -> TableEncoder | None:
        """Compiled encoder of the actuator messages it can take, or None (:attr:`CompiledCodec.encoder`)."""
        return self.codec.encoder

    def _warm_up(self) -> None:
        """Compile (or load from numba's disk cache) the compiled codec calls now, not on the first live tick.

        Nothing observable changes: mask 0 decodes nothing, the finiteness test only reads, and forced-safe guarding counts
        nothing and refills peak budgets that start full; the frames are re-encoded before any send.
        """
        if self.table_decoder is not None:
            self.table_decoder.run(0, 0, self.arena, np.zeros(1, dtype=np.int64))
            self.table_decoder.finite(self.table_decoder.words, 0)  # a second frame of a message in a tick (tick.rx_decoder)
        if self.guard is not None:
            self.guard_and_encode(True)
            c = self.codec
            if c.out_ints is not None:
                tick_out(c.arena, c.out_ints, c.out_floats, c.guard_ints, np.zeros(1, dtype=np.int64), c.payload, 0, 0, 0, True)
            self.guard_outputs(True)
            self.encode()

    def new_watchdog(self, overrun_limit_ns: int, emit_log: bool = True) -> Watchdog:
        return Watchdog(self.timeouts_ticks, overrun_limit_ns, emit_log=emit_log)

    def decode(self, msg: can.Message, tick: int, watchdog: Watchdog) -> bool:
        """Decode one received frame into the graph inputs; True if it was a mapped sensor frame (its ID in its frame
        format: an extended frame with a standard message's number is another message, and the reverse)."""
        entry = self.decoders.get(msg.arbitration_id)
        if entry is None or msg.is_extended_id != entry[2] or not entry[0](msg.data):
            return False
        for w in entry[1]:
            watchdog.fresh(w, tick)
        return True

    def guard_outputs(self, force_safe: bool) -> int:
        """Copy bound graph outputs, guard them into ``self.out``; returns the guard's event count."""
        if self.guard is None:
            return 0
        return _gather_guard(self.arena, self._gather, self.raw, self.out, self._gfp, self.codec.guard_ints, force_safe)

    def encode(self) -> None:
        """Encode ``self.out`` into the reusable actuator frames ``self.tx``."""
        if self.table_encoder is not None:
            self.table_encoder.run(self.out)
        self.fill_frames()

    def fill_frames(self) -> None:
        """Copy the encoded payloads into the actuator frames ``self.tx``; run the Python encoders of the others."""
        for data, src in self.codec.fast_frames:
            data[:] = src
        for enc, data in self.codec.python_frames:
            enc(data)

    def guard_and_encode(self, force_safe: bool) -> int:
        """:meth:`guard_outputs` then :meth:`encode` (one compiled call when possible); returns the guard's event count."""
        c = self.codec
        if c.out_ints is None:
            events = self.guard_outputs(force_safe)
            self.encode()
            return events
        events = out_packed(c.arena, c.out_ints, c.out_floats, c.guard_ints, c.payload, force_safe)
        self.fill_frames()
        return events

    def guard_counts(self) -> dict[str, dict[str, int]]:
        """Output guard events so far per bound graph output (a vector output sums its components).

        ``clamped``: held to the map's ``clamp``; ``peak_limited``: held to the ``peak`` limit within the
        allowance; ``nonfinite``: NaN/inf replaced by the safe value (rules in :mod:`flowtex.runtime.safety`).
        """
        rows = {"clamped": "clamp_counts", "peak_limited": "peak_counts", "nonfinite": "nonfinite_counts"}
        counts: dict[str, dict[str, int]] = {key: {} for key in rows}
        start = 0
        for name, w in zip(self.out_names, self.out_widths, strict=True):
            for key, attr in rows.items():
                counts[key][name] = int(getattr(self.guard, attr)[start:start + w].sum()) if self.guard is not None else 0
            start += w
        return counts

    def limited_ticks(self) -> dict[str, int]:
        """Per bound graph output, the ticks its busiest component was clamped or peak-limited (a lower bound on the
        ticks any component was)."""
        out: dict[str, int] = {}
        start = 0
        for name, w in zip(self.out_names, self.out_widths, strict=True):
            g = self.guard
            out[name] = int((g.clamp_counts[start:start + w] + g.peak_counts[start:start + w]).max()) if g is not None and w else 0
            start += w
        return out

    def encode_safe(self) -> None:
        """Encode every output's safe value into ``self.tx``."""
        if self.guard is not None:
            self.guard.safe_values(self.out)
        self.encode()


def _arena(graph: TickProgram, canmap: CanMap) -> np.ndarray:
    """The graph's float arena :attr:`TickProgram.f`, checked to be what the protocol promises: C-contiguous 1-D float64,
    holding every bound port view as a contiguous slice (the compiled codecs index it)."""
    arena = graph.f
    if arena.dtype != np.float64 or arena.ndim != 1 or not arena.flags.c_contiguous:
        raise ValueError(f"CanIO: graph {graph.name!r}: its arena f must be a C-contiguous 1-D float64 array (TickProgram)")
    views = [(n, graph.input_view(n)) for n in canmap.inputs] + [(n, graph.output_view(n)) for n in canmap.outputs]
    for name, v in views:
        if v.base is not arena or v.dtype != np.float64 or v.ndim != 1 or not v.flags.c_contiguous:
            raise ValueError(f"CanIO: graph {graph.name!r}: port {name!r} is not a contiguous float64 slice of its arena f (TickProgram)")
    return arena


def _offset(arena: np.ndarray, view: np.ndarray) -> int:
    """Index of ``view[0]`` in ``arena``."""
    delta = view.__array_interface__["data"][0] - arena.__array_interface__["data"][0]
    return delta // arena.itemsize


@njit(cache=True)
def _gather_guard(arena, gather, raw, out, gfp, gip, force_safe):  # pragma: no cover - compiled
    for i in range(gather.shape[0]):
        raw[i] = arena[gather[i]]
    return guard_kernel(gfp, gip, raw, out, force_safe)


@njit(cache=True)
def out_packed(arena, ib, fb, gip, payload, force_safe):  # pragma: no cover - compiled
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


@njit(cache=True)
def tick_out(arena, ib, fb, gip, wd_last, payload, tick, overrun_ns, overrun_limit_ns, tripped):  # pragma: no cover - compiled
    """The quiet tick's watchdog test, then :func:`out_packed`; -1 (nothing done) when the watchdog needs its own check.

    Quiet means: not tripped, no input older than its timeout, no overrun; then
    :meth:`Watchdog.check` would return False and change nothing, so the outputs are
    guarded unforced. Otherwise the caller runs ``Watchdog.check`` and ``CanIO.guard_and_encode``.
    """
    if tripped or overrun_ns > overrun_limit_ns:
        return -1
    nw, ot = ib[8], ib[9]
    if first_stale(wd_last, ib[ot:ot + nw], tick) >= 0:
        return -1
    return out_packed(arena, ib, fb, gip, payload, False)


def load_io(graph: TickProgram, dbc_path: str | Path, map_path: str | Path) -> CanIO:
    """Load the DBC and map (checked against ``graph`` by :func:`map_for_ports`) and build the :class:`CanIO`."""
    db = load_dbc(dbc_path)
    canmap = map_for_ports(map_path, db, dbc_path, graph.inputs, graph.outputs)
    used = set(canmap.sensor_messages()) | set(canmap.actuator_messages())
    codecs = {m.name: MessageCodec(m) for m in db.messages if m.name in used}
    return CanIO(graph, canmap, codecs, float(graph.rate))


def ticks_at_least(ms: float, rate_hz: float) -> int:
    """``ms`` milliseconds as whole ticks at ``rate_hz``, rounded up and at least 1: a timeout or a peak refill never
    shorter than the map says (a duration within 1e-9 tick of a whole number of ticks is that number)."""
    return max(1, math.ceil(ms * rate_hz / 1000.0 - 1e-9))


def ticks_at_most(ms: float, rate_hz: float) -> int:
    """``ms`` milliseconds as whole ticks at ``rate_hz``, rounded down: a peak allowance never longer than the map says."""
    return max(0, math.floor(ms * rate_hz / 1000.0 + 1e-9))


def port_widths(ports: Mapping[str, PortSpec]) -> dict[str, int]:
    """Graph port name -> number of scalars (product of its shape)."""
    return {name: int(np.prod(spec.shape)) if spec.shape else 1 for name, spec in ports.items()}
