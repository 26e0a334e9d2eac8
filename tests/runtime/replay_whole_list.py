"""The replay as it was before it streamed the log: every frame read into a list, split into ticks, then replayed.

Kept verbatim (less the audio outputs) as the oracle of tests/runtime/test_replay_stream.py and the baseline of
benchmarks/bench_replay.py: the streamed replay (flowtex.runtime.replay) must report the same ticks and write the same
outputs. It reuses the per-tick decoder and the report of flowtex.runtime.replay, which the streaming did not change.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from pathlib import Path

import can
import numpy as np

from flowtex.errors import DataError
from flowtex.graph.program import TickProgram
from flowtex.io.atomic import atomic_output
from flowtex.io.canlog import SessionWriter, read_session_checked
from flowtex.io.formats import AUDIO, CAN_LOG, RECORDING, format_of
from flowtex.runtime.audio_timeline import TimelineEvents
from flowtex.runtime.canio import load_io
from flowtex.runtime.replay import ReplayReport, _tick_decoder


def split_events(frames: list[can.Message]) -> tuple[object, list[can.Message]]:
    """The log's audio timeline and its other frames."""
    events = TimelineEvents()
    rest = [m for m in frames if not events.take(m)]
    return events.timeline, rest


def expected_ticks(expected_frames: int, ticks: list[tuple[list, list]], block: int) -> float | None:
    if not ticks:
        return None
    per_tick = block + sum(len(rx) for rx, _ in ticks) / len(ticks)
    return max(float(len(ticks)), (expected_frames - block) / per_tick)


def _frame_places(path: Path, frames: list[can.Message], lines: tuple[int, ...]) -> Callable[[can.Message], str]:
    """``place(frame)``: where a frame of the log is, for errors: ``s.log:17`` (its line in a text log) or
    ``s.blf (frame 17)`` (its 1-based position in a BLF)."""
    at = {id(m): (lines[i] if lines else i + 1) for i, m in enumerate(frames)}
    if lines:
        return lambda m: f"{path}:{at[id(m)]}"
    return lambda m: f"{path} (frame {at[id(m)]})"


def _split_ticks(frames: list[can.Message], tx_ids: list[tuple[int, bool]], place: Callable[[can.Message], str],
                 complete: bool = True) -> tuple[list[tuple[list, list]], bool]:
    """Group frames into ``(received, sent block)`` per tick, following the module's rule (the last block is the
    exit block only in a ``complete`` log); ``place`` locates a frame for an error (:func:`_frame_places`)."""
    ticks: list[tuple[list, list]] = []
    rx: list[can.Message] = []
    block: list[can.Message] = []
    k = len(tx_ids)
    for msg in frames:
        if msg.is_error_frame:
            continue
        if msg.is_rx:
            if block:
                raise DataError(f"{place(msg)}: frame {msg.arbitration_id:#x} received in the middle of an actuator block; "
                                "not a flowtex live session log")
            rx.append(msg)
            continue
        expect = tx_ids[len(block)]
        if (msg.arbitration_id, bool(msg.is_extended_id)) != expect:
            raise DataError(f"{place(msg)}: sent frame {msg.arbitration_id:#x} where the map's actuator message {expect[0]:#x} was expected; "
                            "was this session recorded with the same map?")
        block.append(msg)
        if len(block) == k:
            ticks.append((rx, block))
            rx, block = [], []
    exit_block = bool(ticks) and complete
    if exit_block:
        ticks.pop()
    return ticks, exit_block


def replay_whole_list(graph: TickProgram, session_path: str | Path, dbc_path: str | Path, map_path: str | Path,
                      output_path: str | Path | None = None, seed: int | None = None) -> ReplayReport:
    """The old ``replay_session`` without its audio outputs: every frame held, then replayed."""
    session_path = Path(session_path)
    io = load_io(graph, dbc_path, map_path)
    if not io.tx:
        raise DataError(f"{map_path}: the map binds no outputs, so the session has no actuator blocks to mark ticks")
    frames, completeness = read_session_checked(session_path)
    place = _frame_places(session_path, frames, completeness.lines)
    _, frames = split_events(frames)
    ticks, exit_block = _split_ticks(frames, io.tx_ids, place, completeness.problem is None)
    if not ticks:
        ids = ", ".join(f"{fid:#x}" for fid, _ in io.tx_ids)
        what = "no frame at all" if not frames else f"{len(frames)} frame(s) but no complete tick"
        raise DataError(f"{session_path}: nothing to replay: the log holds {what} (a tick ends with one frame of each actuator "
                        f"message of {map_path}: {ids}); is it a session recorded with this map and DBC?")
    fmt = format_of(output_path) if output_path is not None else None
    out_kind = fmt.kind if fmt is not None and (fmt.name in ("npz", "wav") or fmt.kind == CAN_LOG) else None
    if output_path is not None and out_kind is None:
        raise DataError(f"{output_path}: replay output must end in .npz (graph outputs), .blf/.log/.asc (actuator frames) "
                        "or .wav (what the map's audio section plays)")
    if out_kind == AUDIO:
        raise DataError(f"{output_path}: the oracle writes no audio")
    with contextlib.ExitStack() as stack:  # outputs go through the one writer: atomic, the old file kept on failure
        target = stack.enter_context(atomic_output(output_path)) if output_path is not None else None
        writer = SessionWriter(target) if out_kind == CAN_LOG else None
        outputs = ({name: np.zeros((len(ticks), *spec.shape)) for name, spec in graph.outputs.items()}
                   if out_kind == RECORDING else None)
        io.encode_safe()
        safe = [bytes(m.data) for m in io.tx]
        """The actuator payloads of the safe values: what live sends while the watchdog holds the outputs."""
        graph.reset(seed)
        watchdog = io.new_watchdog(1 << 62, emit_log=False)
        report = ReplayReport(ticks=len(ticks), frames_in=sum(1 for m in frames if m.is_rx and not m.is_error_frame),
                              frames_out=sum(1 for m in frames if not m.is_rx and not m.is_error_frame), exit_block=exit_block,
                              session_path=session_path, truncated=completeness.problem)
        if completeness.problem and completeness.expected_frames is not None:
            report.expected_ticks = expected_ticks(completeness.expected_frames, ticks, len(io.tx))
        guard_state = io.codec.guard_ints
        before = guard_state.copy() if guard_state is not None else None
        try:
            decode_tick = _tick_decoder(io, watchdog)
            for k, (rx, live_block) in enumerate(ticks):
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
                    for name, arr in outputs.items():
                        arr[k] = graph.output_view(name).reshape(arr.shape[1:])
                if writer is not None:
                    for m, live in zip(io.tx, live_block, strict=True):
                        m.timestamp = live.timestamp
                        writer.write(m, False)
        finally:
            if writer is not None:
                writer.close()
        if outputs is not None and out_kind == RECORDING:
            with open(target, "wb") as fh:
                np.savez(fh, rate=np.float64(graph.rate), **outputs)
    if output_path is not None:
        report.output_path = Path(output_path)
    return report


