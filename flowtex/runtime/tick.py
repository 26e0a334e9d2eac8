"""The compute of one live tick as one Python callable, and its warming pass.

:func:`tick_compute` hides how a tick is computed from the loop: the Python loop
over the received frames (:func:`rx_decoder`), then either the fused compiled call
(:mod:`flowtex.runtime.fused`: decode, graph block, watchdog's quiet case, guard,
encode, frame copies; any watchdog case other than the quiet one goes through
:meth:`~flowtex.runtime.safety.Watchdog.check` and
:meth:`~flowtex.runtime.canio.CanIO.guard_and_encode`) or, for maps the runtime cannot
fuse (no actuator message the compiled codec takes), the general steps one by one:
compiled decode, graph block, ``Watchdog.check``, ``CanIO.guard_and_encode``. Both ways
send the same bytes (tests/runtime/test_fused.py). :func:`warmer` is the effect-free
pass the clock makes shortly before each deadline.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import can
import numpy as np

from ..graph.program import TickProgram
from ..io.codec_tables import decode_packed
from .buses import CAN_ERR_BUSOFF, BusError
from .canio import CanIO
from .fused import FusedTick
from .safety import Watchdog


def entry_point(fn: Any) -> Callable[..., Any]:
    """The compiled entry point of a numba function compiled for exactly one signature
    (by the warm-up before the loop): calling it skips numba's per-call type dispatch,
    about 0.1-0.2 us per array argument. Otherwise the function itself."""
    sigs = getattr(fn, "signatures", ())
    return fn.overloads[sigs[0]].entry_point if len(sigs) == 1 else fn


class RefusedFrames:
    """Frames with a sensor message's ID number that the decoder did not take as that message, counted per ID number
    on the refusing branches only (the frames it takes cost nothing more): in the other frame format (extended or
    standard), shorter than the DBC's length (a remote frame has no data), or with a bound float signal NaN or inf.
    When a sensor message seems silent at the session's end, they say what came instead: a device that sends another
    length than the DBC states, or its messages in the other frame format, is a common mismatch, and "no frame
    received" sent its user looking for a cable."""

    def __init__(self) -> None:
        self.counts: dict[int, list[int]] = {}
        """ID number -> [frames of the other format, frames too short, frames not finite, the last short one's length]."""
        self.foreign: dict[int, int] = {}
        """Actuator message's ID number -> frames of it (its format, received: not an echo of our own, not remote)
        that arrived: another node sending the commands this session sends (:meth:`foreign_warnings`)."""

    def note(self, msg: Any, length: int, extended: bool) -> None:
        """Count ``msg``, which the decoder did not take as the message of ``length`` bytes and frame format ``extended``."""
        c = self.counts.setdefault(msg.arbitration_id, [0, 0, 0, 0])
        if msg.is_extended_id != extended:
            c[0] += 1
        elif len(msg.data) < length:
            c[1] += 1
            c[3] = len(msg.data)
        else:
            c[2] += 1

    def describe(self, io: CanIO, message: str) -> str:
        """What arrived with sensor ``message``'s ID number without being taken as it (``""``: nothing), for a message
        no frame of which was decoded. The compiled decoder drops a frame of the DBC's length that is not finite
        without a count; a payload word it kept for the message says that such frames came."""
        codec = io.codecs[message]
        other, short, nonfinite, short_len = self.counts.get(codec.frame_id, [0, 0, 0, 0])
        td = io.codec.decoder
        slot = td.slot_of.get(codec.frame_id) if td is not None else None
        parts = []
        if other:
            parts.append(f"{other} frame(s) of its ID number as {'standard' if codec.is_extended else 'extended'} frames")
        if short:
            parts.append(f"{short} frame(s) shorter than the DBC's {codec.length} data bytes (the last of {short_len}"
                         f"{'; a remote frame carries none' if short_len == 0 else ''})")
        if nonfinite or (slot is not None and td.words[slot] != 0):
            parts.append(f"{nonfinite or 'some'} frame(s) with a float signal NaN or inf (no measurement)")
        return f"; {' and '.join(parts)} arrived, which the DBC does not describe as {message}" if parts else ""


    def foreign_warnings(self, io: CanIO, where: str) -> list[str]:
        """One line per actuator message of which frames arrived from another node."""
        names = {m.arbitration_id: name for name, m in zip(io.map.actuator_messages(), io.tx, strict=True)}
        return [f"{n} frame(s) of actuator message {names[fid]} (id {fid:#x}) arrived from another node on {where}: the "
                "device also took commands that were not this session's, which none of its clamps or safe values govern "
                "(its exit frames included); find and stop the other sender (another flowtex live, a test tool, an ECU)"
                for fid, n in self.foreign.items()]


def rx_decoder(io: CanIO, watchdog: Watchdog, refused: RefusedFrames | None = None) -> Callable[[list[Any], int, Any], int]:
    """``decode_rx(rx, tick, words) -> mask``: step 2 of a tick for the received frames ``rx``.

    A frame the compiled decoder takes has its payload stored as one integer in
    ``words[slot]`` and its bit set in the returned mask (for :func:`decode_packed`);
    any other mapped frame goes through its generated Python decoder into the graph
    inputs and marks its watchdog entries fresh at ``tick``. Of a message's frames in one
    tick the latest finite one stands: a frame with a NaN or inf float signal is ignored
    (the compiled decoder drops a slot whose stored payload is one; a later frame replaces
    an earlier one only if finite; the Python codec writes nothing for one). A frame of the
    other format (extended or standard) than its ID number's message is another message:
    skipped. An error frame reporting bus-off raises :class:`BusError`. ``refused`` counts the
    frames of a sensor message's ID number not taken as it (:class:`RefusedFrames`).
    """
    refused = refused if refused is not None else RefusedFrames()
    note, foreign = refused.note, refused.foreign
    actuator = dict(io.tx_ids)  # ID number -> extended
    td = io.codec.decoder
    slot_get = td.slot_of.get if td is not None else {}.get
    slot_len = td.lengths if td is not None else []
    slot_ext = td.extended if td is not None else []
    slot_float = td.has_float if td is not None else []
    finite = td.finite if td is not None else None
    from_bytes = int.from_bytes
    decoders = io.decoders
    length_of = {c.frame_id: c.length for c in io.codecs.values() if c.frame_id in decoders and c.is_extended == decoders[c.frame_id][2]}
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
                if msg.is_extended_id != slot_ext[j]:
                    note(msg, slot_len[j], slot_ext[j])
                    continue
                data = msg.data
                if len(data) == slot_len[j]:
                    if mask >> j & 1 and slot_float[j]:  # a later frame of the tick replaces the earlier one if finite
                        earlier = words[j]
                        words[j] = from_bytes(data, "little", signed=True)
                        if not finite(words, j):
                            words[j] = earlier
                        continue
                    words[j] = from_bytes(data, "little", signed=True)
                    mask |= 1 << j
                    continue
                entry = decoders[msg.arbitration_id]
                if entry[0](data):  # a longer finite frame the Python codec takes (CAN FD padding): the later frame wins
                    mask &= ~(1 << j)
                    for w in entry[1]:
                        fresh(w, tick)
                else:  # a shorter one (a remote frame has no data) decodes nothing and leaves an earlier frame be
                    note(msg, slot_len[j], slot_ext[j])
                continue
            entry = decoders.get(msg.arbitration_id)
            if entry is not None:
                if msg.is_extended_id == entry[2] and entry[0](msg.data):
                    for w in entry[1]:
                        fresh(w, tick)
                else:
                    note(msg, length_of[msg.arbitration_id], entry[2])
            elif actuator.get(msg.arbitration_id) == msg.is_extended_id and msg.is_rx and not msg.is_remote_frame:
                # another sender of our commands (an adapter's echo of our own frame, as neoVI's by default, is not rx)
                foreign[msg.arbitration_id] = foreign.get(msg.arbitration_id, 0) + 1
        return mask

    return decode_rx


def tick_compute(graph: TickProgram, io: CanIO, watchdog: Watchdog, fused: FusedTick | None,
                 decode_rx: Callable[[list[Any], int, Any], int]) -> Callable[[list[Any], int, int], int]:
    """``compute(rx, tick, overrun_ns) -> guard events``: steps 2-5 of a live tick (docs/live.md) for the received frames ``rx``.

    Decodes ``rx`` into the graph inputs, steps the graph once, runs the watchdog
    (``overrun_ns``: how late the tick started, skipped deadlines included), guards
    the outputs and encodes every actuator frame of ``io.tx``. ``fused``: the fused
    call of :func:`~flowtex.runtime.fused.fuse_tick`, or None for separate calls.
    """
    codec = io.codec
    td = codec.decoder
    words = td.words if td is not None else None
    check = watchdog.check
    guard_and_encode = io.guard_and_encode
    if fused is not None:
        # The whole tick in one compiled call, which also fills the compiled messages' frames. Kept beside the separate
        # calls below because it pays: benchmarks/bench_live_paths.py (section "tick") times both side by side.
        live_tick, ptrs = fused.call, fused.ptrs
        overrun_limit = watchdog.overrun_limit_ns
        tx_slow = codec.python_frames

        def compute_fused(rx: list[Any], k: int, overrun: int) -> int:
            ev = live_tick(ptrs, decode_rx(rx, k, words), k, overrun, overrun_limit, watchdog.tripped)
            if ev < 0:
                return guard_and_encode(check(k, overrun))
            for enc, data in tx_slow:
                enc(data)
            return ev

        return compute_fused
    # The general steps one by one: the only way for maps without a compiled output call (fuse_tick gives None).
    arena, wd_last, step = codec.arena, watchdog.last, graph.step_block
    d_ib, d_fb = (td.ibuf, td.fbuf) if td is not None else (None, None)
    decode_packed_ = entry_point(decode_packed)

    def compute_separately(rx: list[Any], k: int, overrun: int) -> int:
        mask = decode_rx(rx, k, words)
        if mask:
            decode_packed_(d_ib, d_fb, mask, k, arena, wd_last)
        step(1)
        return guard_and_encode(check(k, overrun))

    return compute_separately


def warmer(io: CanIO, watchdog: Watchdog, fused: FusedTick | None, decode_rx: Callable[[list[Any], int, Any], int]) -> Callable[[], None]:
    """One effect-free pass through a tick's code, for the clock to call shortly before each deadline.

    After the clock's sleep the tick's first run was 2-4x slower than in a tight loop
    (see :mod:`flowtex.runtime.clock`); this re-runs its Python and compiled parts
    with nothing observable changing: the Python decode on one template frame per
    compiled slot into scratch words, then the fused tick on scratch copies of the
    arenas and watchdog stamps with ``tripped=True`` (the output call returns before
    touching anything). Without a fused tick: the decoder with mask 0 and
    :meth:`~flowtex.graph.program.TickProgram.warm`.
    """
    td = io.codec.decoder
    calls: list[Callable[[], Any]] = []
    if td is not None:
        templates = [can.Message(arbitration_id=fid, is_extended_id=td.extended[j], data=bytearray(int(td.lengths[j])))
                     for fid, j in td.slot_of.items()]
        scratch_words = np.zeros_like(td.words)
        calls.append(lambda: decode_rx(templates, 0, scratch_words))
    if fused is not None:
        every_slot = (1 << len(td.slot_of)) - 1 if td is not None else 0
        calls.append(lambda: fused.warm(every_slot))
    else:
        if td is not None:
            args = (td.ibuf, td.fbuf, 0, 0, io.codec.arena, watchdog.last)
            calls.append(lambda: decode_packed(*args))
        calls.append(io.graph.warm)

    def warm() -> None:
        for c in calls:
            c()

    return warm
