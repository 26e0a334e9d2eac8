"""Replay a recorded live session (.blf/.log) offline through the same graph.

Tick boundaries come from the runtime's own frames. The live loop sends exactly
one frame per actuator message every tick, in the map's order, after decoding the
frames it received in that tick, and logs them in that order. So a session log is

    [received frames of tick 0] [actuator block of tick 0] [received of tick 1] [block 1] ... [exit block]

where a *block* is the map's actuator messages, once each, in map order. Rule:
every complete block closes one tick; the frames received (``is_rx=True``) since
the previous block are that tick's inputs. The **last** block is the safe values
sent at exit and is not a graph tick; received frames after the last regular
block (a tick that failed) are ignored. A log cut short (a truncated file, a BLF
whose header was never written; :func:`~flowtex.io.canlog.read_session_checked`)
has no exit block: every complete block is a tick, and the report says how many
ticks the session had (from the BLF header's frame count) and how many were found. Frames with ids the map does not read are
skipped, as the live loop skips them.

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
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from ..errors import DataError
from ..graph.program import TickProgram
from ..io.atomic import atomic_output
from ..io.canlog import LogCompleteness, SessionWriter, read_session_checked
from ..io.codec_tables import decode_packed
from ..io.formats import AUDIO, CAN_LOG, RECORDING, format_of
from .audio_timeline import split_events
from .canio import CanIO, load_io
from .safety import Watchdog
from .tick import rx_decoder


@dataclass
class ReplayReport:
    """Outcome of :func:`replay_session`; ``str(report)`` is :meth:`summary`, what ``flowtex run --input SESSION`` prints.

    Every tick whose live actuator frames differ from the replayed ones is in
    ``mismatched_ticks`` and in exactly one of ``watchdog_ticks`` (a stale sensor),
    ``overrun_ticks`` (the overrun watchdog) or ``unexplained_ticks`` (neither).
    """

    ticks: int
    frames_in: int
    frames_out: int
    exit_block: bool
    """True when the log ends with the exit block of safe values (a clean live exit)."""
    mismatched_ticks: list[int] = field(default_factory=list)
    watchdog_ticks: list[int] = field(default_factory=list)
    """Mismatched ticks at which the replay's input watchdog finds a stale sensor: live sent the safe values."""
    overrun_ticks: list[int] = field(default_factory=list)
    """Mismatched ticks with every sensor fresh at which live sent exactly the safe values: the overrun watchdog
    (a tick that started more than ``overrun_limit_ms`` late, skipped deadlines included, and the ticks after it
    until every sensor had sent a fresh frame). The live run logged each such event; the log of frames cannot
    show the lateness, so the replay recognises them by the safe values."""
    unexplained_ticks: list[int] = field(default_factory=list)
    """Mismatched ticks no watchdog explains: live sent values other than the safe ones. A real difference: was the
    session run with another graph, parameters, ``--seed``, DBC or map?"""
    output_path: Path | None = None
    session_path: Path | None = None
    audio_lines: list[str] = field(default_factory=list)
    """With ``expect_audio``: one line per class of audio frames (:func:`~flowtex.runtime.audio_check.check_audio`)."""
    audio_unexplained: int = 0
    """Audio frames that differ from the live WAV and that the session's audio timeline does not explain."""
    truncated: str | None = None
    """Why the log does not hold the whole session (:func:`~flowtex.io.canlog.read_session_checked`), or None.
    A truncated log has no exit block: its last complete block is replayed as a tick."""
    expected_ticks: float | None = None
    """Ticks the whole session had, from the frames the BLF header counts (None: the log does not say)."""

    @property
    def identical(self) -> bool:
        return not self.mismatched_ticks

    def summary(self) -> str:
        """A few lines for the terminal: what was replayed, which ticks match, and why the others differ."""
        source = f" of {self.session_path}" if self.session_path is not None else ""
        ending = "ends with the exit block of safe values" if self.exit_block else "has no exit block (was the session killed?)"
        if self.truncated:
            ending = f"is TRUNCATED: {self.truncated}"
        lines = [f"replayed {self.ticks} ticks{source} ({self.frames_in} frames received, {self.frames_out} sent live; the log {ending})"]
        if self.truncated:
            said = (f"expected {_expected(self.expected_ticks)} ticks, found {self.ticks}" if self.expected_ticks is not None
                    else f"found {self.ticks} ticks; the log does not say how many the session had")
            lines.append(f"{said}: the rest of the session is not in the log, so nothing can be said about it")
        same = self.ticks - len(self.mismatched_ticks)
        lines.append(f"{_count(same)}: actuator frames equal to the live ones byte for byte"
                     + (" (all of them)" if self.identical and self.ticks and not self.truncated else ""))
        if self.watchdog_ticks:
            lines.append(f"{_count(len(self.watchdog_ticks))} ({_ranges(self.watchdog_ticks)}): live sent the safe values because a sensor "
                         "was stale (input watchdog, recomputed by the replay)")
        if self.overrun_ticks:
            lines.append(f"{_count(len(self.overrun_ticks))} ({_ranges(self.overrun_ticks)}): live sent the safe values with every sensor "
                         "fresh: the overrun watchdog (a tick started more than overrun_limit_ms late, or the ticks after it until "
                         "every sensor sent a fresh frame; the live run logged it)")
        if self.unexplained_ticks:
            lines.append(f"{_count(len(self.unexplained_ticks))} ({_ranges(self.unexplained_ticks)}): DIFFER from the live frames and no "
                         "watchdog explains it: was the session run with another graph, parameters, --seed, DBC or map?")
        lines.extend(self.audio_lines)
        if self.output_path is not None:
            lines.append(f"wrote {self.output_path}")
        return "\n".join(lines)

    __str__ = summary


def _expected(ticks: float) -> str:
    """``2000``, or ``about 1999`` when the frames per tick were not constant."""
    n = round(ticks)
    return f"{n}" if abs(ticks - n) < 1e-9 else f"about {n}"


def expected_ticks(expected_frames: int, ticks: list[tuple[list, list]], block: int) -> float | None:
    """Ticks a whole session had, from the frame count of its log's header: each tick is its received frames
    and one block of ``block`` actuator frames, plus one exit block; received frames a tick as in the ``ticks`` found."""
    if not ticks:
        return None
    per_tick = block + sum(len(rx) for rx, _ in ticks) / len(ticks)
    return max(float(len(ticks)), (expected_frames - block) / per_tick)


def _count(n: int) -> str:
    return f"{n} tick" + ("" if n == 1 else "s")


def _ranges(ticks: list[int], n: int = 6) -> str:
    """``[3, 4, 5, 9]`` -> ``"3-5, 9"`` (the first ``n`` runs, then ``...``)."""
    runs: list[list[int]] = []
    for t in ticks:
        if runs and t == runs[-1][1] + 1:
            runs[-1][1] = t
        else:
            runs.append([t, t])
    text = ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs[:n])
    return text + (", ..." if len(runs) > n else "")


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
                   expect_audio: str | Path | None = None,
                   log: tuple[list[can.Message], LogCompleteness] | None = None) -> ReplayReport:
    """Run ``graph`` over the frames a live session received, and compare with what it sent.

    ``output_path``: ``.npz`` writes the graph outputs (time first, plus ``rate``);
    ``.blf``/``.log``/``.asc`` writes the actuator frames the graph would have sent
    (timestamps copied from the live frames); None writes nothing.
    ``seed`` must be the live session's (``--seed``; default the graph's).
    ``expect_audio``: the session's ``--record-audio`` WAV, checked frame by frame against the stream rebuilt from the
    replay and the log's audio timeline (``report.audio_lines``, ``report.audio_unexplained``).
    ``log``: the session log already read (:func:`~flowtex.io.canlog.read_session_checked`; the command line reads it
    before the compile), so a long log is not read twice.
    """
    session_path = Path(session_path)
    io = load_io(graph, dbc_path, map_path)
    if not io.tx:
        raise DataError(f"{map_path}: the map binds no outputs, so the session has no actuator blocks to mark ticks")
    frames, completeness = log if log is not None else read_session_checked(session_path)
    place = _frame_places(session_path, frames, completeness.lines)
    timeline, frames = split_events(frames)
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
    if out_kind == AUDIO and io.map.audio is None:
        raise DataError(f"{output_path}: {map_path} has no 'audio' section, so the session played no audio")
    live_audio = None
    if expect_audio is not None:
        live_audio = _live_wav(expect_audio, io.map.audio, map_path)
    audio = out_kind == AUDIO or live_audio is not None
    with contextlib.ExitStack() as stack:  # outputs go through the one writer: atomic, the old file kept on failure
        target = stack.enter_context(atomic_output(output_path)) if output_path is not None and out_kind != AUDIO else None
        writer = SessionWriter(target) if out_kind == CAN_LOG else None
        outputs = ({name: np.zeros((len(ticks), *spec.shape)) for name, spec in graph.outputs.items()}
                   if out_kind == RECORDING or audio else None)
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
        if outputs is not None and audio:
            _replay_audio(graph, io.map.audio, outputs, timeline, output_path if out_kind == AUDIO else None,
                          live_audio, report)
        if outputs is not None and out_kind == RECORDING:
            with open(target, "wb") as fh:
                np.savez(fh, rate=np.float64(graph.rate), **outputs)
    if output_path is not None:
        report.output_path = Path(output_path)
    return report


def _live_wav(path: str | Path, amap: Any, map_path: str | Path) -> tuple[np.ndarray, str]:
    """The live ``--record-audio`` WAV to check the replay against, as (frames, channels) float32."""
    from ..io.wav import read_wav

    if amap is None:
        raise DataError(f"--expect-audio {path}: {map_path} has no 'audio' section, so the session played no audio")
    rate, channels = read_wav(path)
    data = np.stack(list(channels.values()), axis=1)  # float32 samples, exact in float64
    if rate != amap.rate or data.shape[1] != len(amap.channels):
        raise DataError(f"--expect-audio {path}: {data.shape[1]} channel(s) at {rate:g} Hz, but {map_path}'s audio section "
                        f"plays {len(amap.channels)} at {amap.rate:g} Hz: is this the session's --record-audio?")
    return data, str(path)


def _replay_audio(graph: TickProgram, amap: Any, outputs: dict[str, np.ndarray], timeline: Any, path: str | Path | None,
                  live: tuple[np.ndarray, str] | None, report: ReplayReport) -> None:
    """The stream the session handed to the sound card, rebuilt from the replayed ticks and the log's audio timeline
    (:func:`~flowtex.runtime.audio_check.rebuild_live`): written to ``path`` (a WAV equal to the live ``--record-audio``
    sample for sample over its whole length) and checked against ``live``. A log without a timeline gives the lead of
    silence and every tick's samples, and the older check (:func:`~flowtex.runtime.audio_check.compare_audio`)."""
    from ..io.wav import write_wav
    from .audio_check import check_audio, compare_audio, rebuild_live
    from .audio_render import lead_frames, render_outputs, samples_per_tick

    rate = float(graph.rate)
    up, down = samples_per_tick(amap, rate)
    n_ticks = next(iter(outputs.values())).shape[0]
    if timeline is not None:
        stream, klass = rebuild_live(render_outputs(outputs, amap, rate), n_ticks, up, down, timeline)
    else:
        stream = render_outputs(outputs, amap, rate, lead=lead_frames(amap))
    if path is not None:
        write_wav(path, stream, amap.rate)  # atomic itself (flowtex.io.wav.write_wav)
    if live is None:
        return
    data, name = live
    if timeline is not None:
        check = check_audio(data, stream, klass, timeline, name, amap.rate)
        report.audio_lines, report.audio_unexplained = check.lines, check.unexplained
        return
    fade = max(1, int(round(0.002 * amap.rate)))
    cmp = compare_audio(data, stream, lead_frames(amap), up, [], fade, down)
    report.audio_unexplained = cmp.unexplained
    report.audio_lines = [f"audio: the session log holds no audio timeline (recorded before flowtex logged it): {name} checked "
                          "where live played a tick",
                          f"{cmp.equal} frames: the ticks' samples, equal to {name} sample for sample",
                          f"{cmp.silence} frames: the callback's fade to silence (where live had no tick to play)"]
    if cmp.unexplained:
        report.audio_lines.append(f"{cmp.unexplained} frames DIFFER, first at frame {cmp.first_unexplained}: unexplained")
