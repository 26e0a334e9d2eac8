"""Replay a recorded live session (.blf/.log/.asc) offline through the same graph.

Tick boundaries come from the runtime's own frames. The live loop sends exactly
one frame per actuator message every tick, in the map's order, after decoding the
frames it received in that tick, and logs them in that order. So a session log is

    [received frames of tick 0] [actuator block of tick 0] [received of tick 1] [block 1] ... [exit block]

where a *block* is the map's actuator messages, once each, in map order. Rule:
every complete block closes one tick; the frames received (``is_rx=True``) since
the previous block are that tick's inputs. The **last** block is the safe values
sent at exit and is not a graph tick; received frames after the last regular
block (a tick that failed) are ignored. A log cut short (a truncated file, a BLF
whose header was never written; :attr:`~flowtex.io.canlog.SessionFrames.completeness`)
has no exit block: every complete block is a tick, and the report says how many
ticks the session had (from the BLF header's frame count) and how many were found. Frames with ids the map does not read are
skipped, as the live loop skips them.

The log is streamed (:class:`~flowtex.io.canlog.SessionFrames`): a tick is replayed once the block after it is read
(the last block may be the exit block, which only the end of the log tells), so the frames held are those of two ticks,
whatever the session's length. What grows with the session: the ``.npz``/audio outputs (8 bytes a value a tick, in
arrays that double when full) and the lists of mismatched ticks (one int each).

For every tick the replay decodes the same frames with the same decoder as the live tick into the
graph inputs, steps the graph (reset with the same seed), guards the outputs with
the same clamps/peak allowance (never forcing safe values) and encodes them. On a tick
where live held the outputs safe (the replay's watchdog finds a sensor stale, or live sent
the safe values the replay did not: the overrun watchdog) the guard's state (peak budgets,
counts) is then moved as live's forced tick moved it, so the peak budget of the ticks after
a watchdog trip is live's. If a
live block differs from the replayed one, the tick is reported: as ``watchdog``
when the replay's own input watchdog (same timeouts, tick-counted) says a sensor
was stale then, as ``overrun`` when live sent exactly the safe values with every
sensor fresh (the overrun watchdog, which the frames alone cannot show otherwise),
else as ``unexplained`` (a real mismatch).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np

from .. import limits
from ..errors import DataError
from ..graph.program import TickProgram
from ..io.atomic import atomic_output, kept_on_success
from ..io.canlog import SessionFrames, SessionWriter
from ..io.codec_tables import decode_packed
from ..io.formats import AUDIO, CAN_LOG, RECORDING, format_of
from ..io.recordings import save_recording
from .audio_timeline import TimelineEvents
from .canio import CanIO, load_io
from .replay_report import ReplayReport, expected_ticks
from .safety import Watchdog
from .tick import rx_decoder

__all__ = ["ReplayReport", "replay_session"]

Tick = tuple[list[can.Message], list[can.Message]]
"""One tick of a session log: the frames received, then the actuator block sent."""


class _Counts:
    """Frames of the log seen by :func:`_ticks`: all but the timeline events, received and sent (error frames aside)."""

    def __init__(self) -> None:
        self.frames = self.received = self.sent = 0

    def none_sent(self) -> str:
        """A sentence for errors when frames were received but none was sent (a log without directions), else ""."""
        if self.sent or not self.received:
            return ""
        return (f" (the {self.received:,} frames read are all marked received and none is marked sent: a log without "
                "directions, as candump -L writes? The replay needs the frames live sent: record the session with flowtex "
                "live --record)")


def _ticks(frames: SessionFrames, tx_ids: list[tuple[int, bool]], events: TimelineEvents, counts: _Counts) -> Iterator[Tick]:
    """Every complete ``(received, sent block)`` of the log in order, yielded as its block completes (the module's rule;
    which block is the exit block the caller decides at the end). Timeline events go to ``events``; ``counts`` counts
    the other frames. A frame out of place is a DataError naming it (:meth:`~flowtex.io.canlog.SessionFrames.place`)."""
    rx: list[can.Message] = []
    block: list[can.Message] = []
    k = len(tx_ids)
    for msg in frames:
        if events.take(msg):
            continue
        counts.frames += 1
        if msg.is_error_frame:
            continue
        if msg.is_rx:
            counts.received += 1
            if block:
                raise DataError(f"{frames.place()}: frame {msg.arbitration_id:#x} received in the middle of an actuator block; "
                                "not a flowtex live session log")
            if len(rx) >= limits.MAX_TICK_FRAMES:
                raise DataError(f"{frames.place()}: more than {limits.MAX_TICK_FRAMES:,} frames received in one tick (since the "
                                "last actuator block); flowtex replays up to that many (flowtex.limits.MAX_TICK_FRAMES): is "
                                f"this a flowtex live session log?{counts.none_sent()}")
            rx.append(msg)
            continue
        counts.sent += 1
        expect = tx_ids[len(block)]
        got = (msg.arbitration_id, bool(msg.is_extended_id))
        if got != expect:
            raise DataError(f"{frames.place()}: sent frame {_frame_id(*got, expect)} where the map's actuator message "
                            f"{_frame_id(*expect, got)} was expected; was this session recorded with the same map?")
        block.append(msg)
        if len(block) == k:
            yield rx, block
            rx, block = [], []


def _frame_id(number: int, extended: bool, other: tuple[int, bool]) -> str:
    """``0x200``, or ``0x200 (extended ID)`` when ``other`` has the same number in the other format."""
    if number != other[0] or extended == other[1]:
        return f"{number:#x}"
    return f"{number:#x} ({'extended' if extended else 'standard'} ID)"


class _Rows:
    """One graph output's value at every replayed tick, in a float64 array that doubles when full: 8 bytes a value a
    tick, at most twice that once grown (three times while it is copied)."""

    def __init__(self, shape: tuple[int, ...]):
        self._data = np.zeros((256, *shape))
        self.n = 0

    def append(self, row: np.ndarray) -> None:
        if self.n == self._data.shape[0]:
            grown = np.zeros((2 * self.n, *self._data.shape[1:]))
            grown[:self.n] = self._data
            self._data = grown
        self._data[self.n] = row.reshape(self._data.shape[1:])
        self.n += 1

    @property
    def array(self) -> np.ndarray:
        """The rows appended so far (a view)."""
        return self._data[:self.n]


def _tick_decoder(io: CanIO, watchdog: Watchdog) -> Callable[[list[can.Message], int], None]:
    """``decode_tick(rx, k)``: the frames one live tick received into the graph inputs, as the live tick decodes them
    (:func:`~flowtex.runtime.tick.rx_decoder`, then the compiled decoder): the latest finite frame of each compiled
    message is the one decoded (a frame with a NaN or inf float signal is ignored). The same code as live, so that
    whatever the decoding rule, the replay's inputs are live's by construction."""
    mask_of = rx_decoder(io, watchdog)
    td = io.codec.decoder
    if td is None:  # no compiled message: mask_of decodes every frame with its Python decoder

        def decode_python(rx: list[can.Message], k: int) -> None:
            mask_of(rx, k, None)

        return decode_python
    words, arena, stamps = td.words, io.codec.arena, watchdog.last

    def decode_tick(rx: list[can.Message], k: int) -> None:
        mask = mask_of(rx, k, words)
        if mask:
            decode_packed(td.ibuf, td.fbuf, mask, k, arena, stamps)

    return decode_tick


def replay_session(graph: TickProgram, session_path: str | Path, dbc_path: str | Path, map_path: str | Path,
                   output_path: str | Path | None = None, seed: int | None = None,
                   expect_audio: str | Path | None = None, log: SessionFrames | None = None) -> ReplayReport:
    """Run ``graph`` over the frames a live session received, and compare with what it sent.

    ``output_path``: ``.npz`` writes the graph outputs (time first, plus ``rate``);
    ``.blf``/``.log``/``.asc`` writes the actuator frames the graph would have sent
    (timestamps copied from the live frames); None writes nothing. Written atomically: an error
    found anywhere in the log leaves no partial file (and an older one as it was).
    ``seed`` must be the live session's (``--seed``; default the graph's).
    ``expect_audio``: the session's ``--record-audio`` WAV, checked frame by frame against the stream rebuilt from the
    replay and the log's audio timeline (``report.audio_lines``, ``report.audio_unexplained``).
    ``log``: the session log already opened and checked at its start (:func:`~flowtex.io.canlog.open_session`; the
    command line does so before the compile). The log is read once, streamed (see the module docstring).
    """
    session_path = Path(session_path)
    io = load_io(graph, dbc_path, map_path)
    if not io.tx:
        raise DataError(f"{map_path}: the map binds no outputs, so the session has no actuator blocks to mark ticks")
    frames = log if log is not None else SessionFrames(session_path)
    fmt = format_of(output_path) if output_path is not None else None
    out_kind = fmt.kind if fmt is not None and (fmt.name in ("npz", "wav") or fmt.kind == CAN_LOG) else None
    if output_path is not None and out_kind is None:
        raise DataError(f"{output_path}: replay output must end in .npz (graph outputs), .blf/.log/.asc (actuator frames) "
                        "or .wav (what the map's audio section plays)")
    if out_kind == AUDIO and io.map.audio is None:
        raise DataError(f"{output_path}: {map_path} has no 'audio' section, so the session played no audio")
    live_audio = None
    if expect_audio is not None:
        live_audio = _live_wav(expect_audio, io.map.audio, map_path)
    audio = out_kind == AUDIO or live_audio is not None
    with contextlib.ExitStack() as stack:  # outputs go through the one writer: atomic, the old file kept on failure
        if live_audio is not None:
            stack.callback(live_audio[0].close)
        target = stack.enter_context(atomic_output(output_path)) if out_kind == RECORDING else None
        writer = SessionWriter(output_path, "-o") if out_kind == CAN_LOG else None  # atomic itself; errors name -o PATH
        outputs = ({name: _Rows(spec.shape) for name, spec in graph.outputs.items()}
                   if out_kind == RECORDING or audio else None)
        io.encode_safe()
        safe = [bytes(m.data) for m in io.tx]
        """The actuator payloads of the safe values: what live sends while the watchdog holds the outputs."""
        graph.reset(seed)
        watchdog = io.new_watchdog(1 << 62, emit_log=False)
        report = ReplayReport(ticks=0, frames_in=0, frames_out=0, exit_block=False, session_path=session_path)
        guard_state = io.codec.guard_ints
        before = guard_state.copy() if guard_state is not None else None
        decode_tick = _tick_decoder(io, watchdog)

        def replay_tick(rx: list[can.Message], live_block: list[can.Message]) -> None:
            """Replay the next tick (``report.ticks``) from the frames received in it, and compare with ``live_block``."""
            nonlocal received
            k = report.ticks
            decode_tick(rx, k)
            graph.step_block(1)
            stale = watchdog.check(k, 0)
            if before is not None:
                before[:] = guard_state
            io.guard_outputs(False)
            io.encode()
            forced = stale
            if any(bytes(a.data) != bytes(b.data) for a, b in zip(io.tx, live_block, strict=True)):
                report.mismatched_ticks.append(k)
                if stale:
                    report.watchdog_ticks.append(k)
                elif [bytes(b.data) for b in live_block] == safe:
                    report.overrun_ticks.append(k)
                    forced = True
                else:
                    report.unexplained_ticks.append(k)
            if forced and before is not None:  # live held the outputs safe: its guard state moved as a forced tick's
                guard_state[:] = before
                io.guard_outputs(True)
            if outputs is not None:
                for name, rows in outputs.items():
                    rows.append(graph.output_view(name))
            if writer is not None:
                for m, live in zip(io.tx, live_block, strict=True):
                    m.timestamp = live.timestamp
                    writer.write(m, False)
            report.ticks += 1
            received += len(rx)

        events, counts = TimelineEvents(), _Counts()
        received = 0  # frames received in the ticks replayed
        pending: Tick | None = None  # the last block read: a tick, or the exit block if the log ends after it
        ticks = stack.enter_context(contextlib.closing(_ticks(frames, io.tx_ids, events, counts)))  # the log closed on error
        with kept_on_success(writer):  # the CAN log output: nothing partial left on an error
            for tick in ticks:
                if pending is not None:
                    replay_tick(*pending)
                pending = tick
            completeness = frames.completeness
            assert completeness is not None  # the frames are all read
            report.exit_block = pending is not None and completeness.problem is None
            if pending is not None and not report.exit_block:  # a log cut short: its last complete block is a tick
                replay_tick(*pending)
            if not report.ticks:
                ids = ", ".join(f"{fid:#x}" for fid, _ in io.tx_ids)
                what = "no frame at all" if not counts.frames else f"{counts.frames} frame(s) but no complete tick"
                raise DataError(f"{session_path}: nothing to replay: the log holds {what} (a tick ends with one frame of each "
                                f"actuator message of {map_path}: {ids}); is it a session recorded with this map and DBC?"
                                f"{counts.none_sent()}")
        report.frames_in, report.frames_out, report.truncated = counts.received, counts.sent, completeness.problem
        if completeness.problem and completeness.expected_frames is not None:
            report.expected_ticks = expected_ticks(completeness.expected_frames, report.ticks, received, len(io.tx))
        arrays = {name: rows.array for name, rows in outputs.items()} if outputs is not None else None
        if arrays is not None and audio:
            _replay_audio(graph, io.map.audio, arrays, events.timeline, output_path if out_kind == AUDIO else None,
                          live_audio, report)
        if arrays is not None and out_kind == RECORDING:
            save_recording(target, arrays, rate=float(graph.rate))  # the one recording writer, into the atomic output
    if output_path is not None:
        report.output_path = Path(output_path)
    return report


def _live_wav(path: str | Path, amap: Any, map_path: str | Path) -> tuple[Any, str]:
    """The live ``--record-audio`` WAV to check the replay against, opened to be read block by block
    (:class:`~flowtex.io.wav.WavReader`), and its name."""
    from ..io.wav import WavReader

    if amap is None:
        raise DataError(f"--expect-audio {path}: {map_path} has no 'audio' section, so the session played no audio")
    reader = WavReader(path)
    if reader.rate != amap.rate or reader.channels != len(amap.channels):
        reader.close()
        raise DataError(f"--expect-audio {path}: {reader.channels} channel(s) at {reader.rate:g} Hz, but {map_path}'s audio "
                        f"section plays {len(amap.channels)} at {amap.rate:g} Hz: is this the session's --record-audio?")
    return reader, str(path)


def _replay_audio(graph: TickProgram, amap: Any, outputs: dict[str, np.ndarray], timeline: Any, path: str | Path | None,
                  live: tuple[Any, str] | None, report: ReplayReport) -> None:
    """The stream the session handed to the sound card, rebuilt from the replayed ticks and the log's audio timeline
    (:func:`~flowtex.runtime.audio_check.rebuild_blocks`), block by block: written to ``path`` (a WAV equal to the live
    ``--record-audio`` sample for sample over its whole length) and checked against ``live`` (a
    :class:`~flowtex.io.wav.WavReader`), in memory of a block whatever the session's length. A log without a timeline
    gives the lead of silence and every tick's samples, and the older check
    (:func:`~flowtex.runtime.audio_check.compare_audio`, on whole arrays)."""
    from ..io.wav import WavWriter
    from .audio_check import AudioChecker, rebuild_blocks, stream_frames
    from .audio_render import check_length, lead_frames, render_blocks, samples_per_tick, write_render

    rate = float(graph.rate)
    up, down = samples_per_tick(amap, rate)
    n_ticks = next(iter(outputs.values())).shape[0]
    most = limits.max_audio_frames(amap.rate)
    problem = timeline.problem(most) if timeline is not None else None
    if problem is not None:
        raise DataError(f"{report.session_path}: its audio timeline's {problem} is out of bounds (negative, or more than "
                        f"{most:,}, the frames of {limits.MAX_AUDIO_SECONDS / 3600:g} hours at {amap.rate:g} Hz: "
                        "flowtex.limits.MAX_AUDIO_SECONDS): a damaged log? The replay rebuilds the played stream from it")
    what = str(path) if path is not None else f"--expect-audio {live[1] if live else ''}"  # the file the stream is for
    if timeline is None:
        if live is None:
            if path is not None:
                write_render(path, outputs, amap, rate, lead=lead_frames(amap))
            return
        _check_without_timeline(amap, outputs, rate, path, live, report, what)
        return
    total = stream_frames(n_ticks, up, down, timeline)
    check_length(total, amap, n_ticks, what)
    width = len(amap.channels)
    stream = rebuild_blocks(render_blocks(outputs, amap, rate, what=what), n_ticks, up, down, timeline, width)
    checker = AudioChecker(timeline, live[1], amap.rate) if live is not None else None
    with kept_on_success(WavWriter(path, amap.rate, width) if path is not None else None) as writer:
        for block, klass in stream:
            if writer is not None:
                writer.write(block)
            if checker is not None and live is not None:
                checker.feed(live[0].read(block.shape[0]), block, klass)
    if checker is not None and live is not None:
        check = checker.finish(live[0].frames, total)
        report.audio_lines, report.audio_unexplained = check.lines, check.unexplained


def _check_without_timeline(amap: Any, outputs: dict[str, np.ndarray], rate: float, path: str | Path | None,
                            live: tuple[Any, str], report: ReplayReport, what: str) -> None:
    """``--expect-audio`` of a log without an audio timeline (recorded before flowtex logged it): the older check
    (:class:`~flowtex.runtime.audio_check.AudioComparer`, :func:`~flowtex.runtime.audio_check.compare_audio` block by
    block) of the live WAV against the lead and every tick's samples, which are written to ``path`` as they come."""
    from ..io.wav import WavWriter
    from .audio_check import BLOCK_FRAMES, AudioComparer, known_end
    from .audio_render import lead_frames, render_blocks, samples_per_tick

    reader, name = live
    up, down = samples_per_tick(amap, rate)
    n_ticks, lead = next(iter(outputs.values())).shape[0], lead_frames(amap)
    fade = max(1, int(round(0.002 * amap.rate)))
    cmp = AudioComparer(known_end(reader.frames, n_ticks, lead, up, down), lead, fade, len(amap.channels))
    pending: list[np.ndarray] = []  # replay frames rendered and not yet compared
    with kept_on_success(WavWriter(path, amap.rate, len(amap.channels)) if path is not None else None) as writer:
        for block in render_blocks(outputs, amap, rate, lead=lead, what=what):
            if writer is not None:
                writer.write(block)
            pending.append(block)
            while sum(b.shape[0] for b in pending) >= BLOCK_FRAMES or (pending and reader.position >= reader.frames):
                replay = np.concatenate(pending)
                cmp.feed(reader.read(replay.shape[0]), replay)
                pending = []
        if pending:
            replay = np.concatenate(pending)
            cmp.feed(reader.read(replay.shape[0]), replay)
        while reader.position < reader.frames:  # live frames after the replay's end
            cmp.feed(reader.read(BLOCK_FRAMES), np.zeros((0, len(amap.channels)), dtype=np.float32))
    result = cmp.finish()
    report.audio_unexplained = result.unexplained
    report.audio_lines = [f"audio: the session log holds no audio timeline (recorded before flowtex logged it): {name} checked "
                          "where live played a tick",
                          f"{result.equal} frames: the ticks' samples, equal to {name} sample for sample",
                          f"{result.silence} frames: the callback's fade to silence (where live had no tick to play)"]
    if result.unexplained:
        report.audio_lines.append(f"{result.unexplained} frames DIFFER, first at frame {result.first_unexplained}: unexplained")
