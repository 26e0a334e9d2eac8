"""The live loop: CAN frames in, one graph tick, guarded CAN frames out, at the graph's rate.

Per tick (the order is the contract replay relies on, see docs/live.md):

1. wait for the tick's deadline (:class:`~flowtex.runtime.clock.DeadlineClock`); 50 us
   before it, receive the frames already there and make one effect-free warming
   pass through the tick's code (:func:`~flowtex.runtime.tick.warmer`);
2. receive every frame that arrived since (:func:`~flowtex.runtime.buses.receiver`):
   the tick's inputs are every frame received before its compute starts;
3. to 5. one call (:func:`~flowtex.runtime.tick.tick_compute`): decode the frames into
   the graph inputs (inputs hold their last value between frames), one graph tick,
   watchdog, output guard, encode every actuator frame (:mod:`flowtex.runtime.canio`,
   fused into one compiled call by :mod:`flowtex.runtime.fused` when the map allows);
6. send exactly one frame per actuator message, in map order;
7. in the slack: hand the tick's audio samples to the sound card's callback (when the
   map has an ``audio`` section, :mod:`flowtex.runtime.audio`), write the tick's received
   and sent frames to the ``--record`` log, step the simulated device, statistics and the
   status line.

On every exit path (duration reached, Ctrl-C, SIGTERM, exception in the graph,
bus error) the safe values are encoded and sent once more, as the last frames
(and logged). Steps 2-5 allocate nothing beyond python-can's own message objects
and small ints; the garbage collector is frozen during the loop. Compute time in
the statistics is steps 2-5 without the bus receive.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

import can
import numpy as np

from ..errors import FlowtexError
from ..graph.program import TickProgram
from ..interrupts import signals_handled, signals_named
from ..io.canlog import RecordError, SessionWriter
from ..io.dbc import one_line
from ..io.mapsafety import shrunk_bounds
from .audio import AudioOutput, prompt_callbacks
from .audio_ring import sensor_arrival_ns
from .audio_timeline import check_event_ids
from .buses import SEND_TIMEOUT_S, BusError, fd_needed, open_bus, receiver, send_when_queued, sender
from .canio import CanIO, load_io, tick_out
from .clock import DeadlineClock
from .fused import fuse_tick
from .liveconfig import LiveConfig
from .preflight import preflight_live
from .realtime import RealtimeStatus, enter_realtime, freeze_gc, leave_realtime
from .safety import all_updated_after, first_stale
from .simdevice import SimulatedDevice, in_process_device
from .stats import TickStats
from .status import Shown, StatusDisplay, clamp_warnings, guard_counts, resolve_shown
from .tick import RefusedFrames, rx_decoder, tick_compute, warmer

__all__ = ["BusError", "CanIO", "LiveConfig", "LiveReport", "load_io", "run_live"]


@dataclass
class LiveReport:
    """What a live session did."""

    ticks: int
    frames_in: int
    frames_out: int
    watchdog_events: int
    guard_events: int
    exit_reason: str
    """``duration``, ``SIGINT``, ``SIGTERM``, ``SIGHUP`` or ``error``."""
    error: str | None = None
    summary: dict = field(default_factory=dict)
    rt_message: str = ""
    send_offset_ns: np.ndarray | None = None
    """Per tick (first ``ticks``, up to capacity): time from the tick's deadline until its last frame was sent."""
    device: SimulatedDevice | None = None
    """The in-process :class:`~flowtex.runtime.simdevice.SimulatedDevice`, if any."""
    silent_messages: list[str] = field(default_factory=list)
    """Sensor messages of the map of which not one frame arrived during the session."""
    silence: str | None = None
    """One line naming the silent sensor messages (frame ids) and the bus, or None when every sensor message arrived."""
    no_sensor_frames: bool = False
    """Not one sensor frame arrived (outputs were safe throughout): ``flowtex live`` then exits with code 3."""
    audio: dict | None = None
    """The audio output's summary (:meth:`~flowtex.runtime.audio.AudioOutput.summary`) when the map has an ``audio`` section."""
    safe_sent: bool = True
    """Every actuator message's safe frame went out at exit (False: the bus refused at least one, see ``error``)."""
    warnings: list[str] = field(default_factory=list)
    """One line per output whose clamp the DBC's grid narrows noticeably (:func:`~flowtex.io.mapsafety.shrunk_bounds`),
    one per pass-through binding whose DBC unit differs from its graph port's by no known factor
    (:attr:`~flowtex.io.canmap.CanMap.warnings`), both also printed on the status stream before the session; then one
    per actuator message another node sent too (:meth:`~flowtex.runtime.tick.RefusedFrames.foreign_warnings`), and one
    per output clamped or peak-limited on more than 1 % of the ticks (:func:`~flowtex.runtime.status.clamp_warnings`)."""

    @property
    def ok(self) -> bool:
        return self.error is None


def run_live(graph: TickProgram, config: LiveConfig) -> LiveReport:
    """Run ``graph`` live against a CAN bus with the options of ``config`` (:class:`~flowtex.runtime.liveconfig.LiveConfig`).

    The session runs until ``config.duration_s`` or ``config.max_ticks`` (neither: until Ctrl-C/SIGTERM) on
    ``graph.with_block_rows(1)`` (same code, parameters and seed, one-row port buffers), so ``graph`` itself is not
    stepped. The output paths are checked before the session (:func:`~flowtex.runtime.preflight.preflight_live`).
    Raises :class:`FlowtexError` for bad files or a bus that cannot be opened; failures during the loop end the session
    with safe values and are returned in ``LiveReport.error``.
    """
    if not isinstance(config, LiveConfig):
        raise TypeError(f"run_live takes a LiveConfig, got {type(config).__name__}")
    graph = graph.with_block_rows(1)  # one tick per call: port buffers of one row keep the tick's data in a few KB
    n_ticks = config.tick_limit(graph.rate)
    shown = resolve_shown(graph, config.show)
    record, stats_path, record_audio = preflight_live(graph, config)
    dbc_path, map_path, bus = config.dbc_path, config.map_path, config.bus
    io = load_io(graph, dbc_path, map_path)
    shrunk = shrunk_bounds(io.map.outputs.values()) + io.map.warnings
    if shrunk and config.status is not None:  # before the session: what the actuator gets may differ from what the map says
        for line in shrunk:
            print(f"flowtex live: warning: {line}", file=config.status)
    if io.map.audio is not None and record is not None:
        check_event_ids(io.tx_ids, str(map_path))
    if record_audio is not None and io.map.audio is None:
        raise FlowtexError(f"--record-audio: {map_path} has no 'audio' section, so nothing is played (docs/live.md, \"Audio output\")")
    audio = AudioOutput(graph, io.map.audio, record_audio, str(map_path)) if io.map.audio is not None else None
    device = dev_bus = None
    if config.simulate is not None:
        bus_obj, dev_bus, device = in_process_device(bus, io.map, io.codecs, config.simulate, float(graph.rate), config.drop,
                                                     graph.name, {n: spec.unit for n, spec in graph.inputs.items()})
    else:
        bus_obj = open_bus(bus, config.bitrate, any(c.is_fd for c in io.codecs.values()),
                           fd_needed(io.codecs, io.map.actuator_messages(), io.map.sensor_messages()))
    writer = None
    try:
        writer = SessionWriter(record, "--record") if record is not None else None
        where = "the simulated device's virtual bus" if device is not None else f"bus {bus!r}"
        report = _loop(graph, io, bus_obj, device, writer, n_ticks, config, stats_path, where, shown, audio)
        report.warnings[:0] = shrunk
        return report
    except BaseException:
        if writer is not None:  # the loop never ran or did not end (an interrupt during the compile): no log replaces the old
            with contextlib.suppress(RecordError):
                writer.close(keep=False)
        raise
    finally:
        if audio is not None:
            audio.close()
        for b in (bus_obj, dev_bus):
            if b is not None:
                with contextlib.suppress(Exception):
                    b.shutdown()


def _loop(graph: TickProgram, io: CanIO, bus: can.BusABC, device: SimulatedDevice | None, writer: SessionWriter | None,
          n_ticks: int | None, config: LiveConfig, stats_path: Path | None, where: str, shown: list[Shown],
          audio: AudioOutput | None = None) -> LiveReport:
    status = config.status
    rate = float(graph.rate)
    capacity = int(min(n_ticks if n_ticks else 600 * rate, 3600 * rate)) + 1
    stats = TickStats(capacity)
    send_offset = np.zeros(capacity, dtype=np.int64)
    # with a status line, events are printed on their own lines with names, not through logging
    watchdog = io.new_watchdog(int(round(io.map.overrun_limit_ms * 1e6)), emit_log=status is None)
    # Load the watchdog's compiled checks now (pure functions), not on the first live tick.
    first_stale(watchdog.last, watchdog.timeouts, 0)
    all_updated_after(watchdog.last, 0)
    fused = fuse_tick(graph, io, tick_out, watchdog.last)  # compiled (or loaded) now, before the first deadline
    if fused is None:
        graph.warm()  # the separate calls' block: compiled (or loaded) and run once on scratch arenas now
    refused = RefusedFrames()  # frames of a sensor's ID number not taken as it: named if that sensor seems silent
    decode_rx = rx_decoder(io, watchdog, refused)
    compute = tick_compute(graph, io, watchdog, fused, decode_rx)
    receive, send_frames = receiver(bus), sender(bus)
    rx: list[Any] = []
    """Frames received for the current tick: those already there shortly before its deadline, then the rest."""
    warm_pass = warmer(io, watchdog, fused, decode_rx) if config.warm else None

    def prepare() -> None:  # shortly before each deadline (bus time and warming, not compute)
        receive(rx)
        if warm_pass is not None:
            warm_pass()

    # with a sound card, a stall shorter than the audio margin is caught up rather than skipped (docs/live.md, "Audio output")
    clock = DeadlineClock(rate, prepare=prepare, catch_up_s=audio.catch_up_s() if audio is not None else 0.0)
    period = clock.period_ns
    display = StatusDisplay(status, io, watchdog, stats, int(rate / 2), shown) if status is not None else None
    if display is not None and audio is not None:
        display.extra = audio.status_text
        display.audio = audio
    wall_minus_perf = time.time_ns() - time.perf_counter_ns()  # python-can timestamps are wall-clock seconds
    graph.reset(config.seed)
    rt_status, rt_message = _enter_rt(config.rt, config.rt_priority, config.rt_cpu, status)
    stop: list[str | None] = [None]
    error: str | None = None
    guard_events = k = lateness = overrun = 0
    tx, now = io.tx, time.perf_counter_ns
    # the stop handlers stay until the session's files are written: a second Ctrl-C, SIGTERM or SIGHUP while they are
    # (the first ended the loop) raised in the middle of them, and the log was discarded, --stats not written
    with _stop_signals(stop, config.install_signals):
        with freeze_gc(), prompt_callbacks(audio is not None):
            try:
                if audio is not None:
                    audio.start()  # plays silence until the stream has settled, then places tick 0 a margin ahead of it
                    if writer is not None:
                        audio.log_timeline = True
                        writer.write(audio.start_event(), False)
                if device is not None:  # tick 0's sensor frames, just before tick 0 (their arrival starts its latency)
                    device.publish(0)
                clock.start()
                while True:
                    receive(rx)  # 2. whatever arrived since prepare() (bus time, not compute)
                    t0 = now()
                    guard_events += compute(rx, k, overrun)  # 3.-5. decode, graph tick, watchdog, guard, encode
                    t1 = now()
                    send_frames(tx)  # 6.
                    t2 = now()
                    stats.record(lateness, t1 - t0)  # 7. the slack
                    send_offset[k % capacity] = t2 - clock.deadline_ns
                    stats.frames_in += len(rx)
                    stats.frames_out += len(tx)
                    if audio is not None and audio.push(k, sensor_arrival_ns(rx, wall_minus_perf, io.decoders, t2), _audio_held(watchdog, k)):
                        clock.catch_up_ns = int(audio.catch_up_s() * 1e9)  # the margin grew after a stall: catch up as far
                    if writer is not None:
                        writer.write_tick(rx, tx)
                        if audio is not None:
                            for m in audio.take_events():
                                writer.write(m, False)
                        if writer.error is not None:  # a full disk: the log would miss this session's rest, so it ends here
                            raise RecordError(writer.error)
                    rx.clear()
                    k += 1
                    if device is not None:
                        device.collect(k - 1)
                        device.publish(k)
                    if stop[0] is not None or (n_ticks is not None and k >= n_ticks):
                        break
                    if display is not None:
                        display.tick(k)
                    if audio is not None:
                        audio.check()
                        clock.shift(audio.pace(k - 1, clock.deadline_ns + period))
                    lateness = overrun = clock.wait()  # 1. the next deadline
                    if clock.skipped:  # a stall: the skipped deadlines count as late, until now
                        stats.record_skipped(clock.skipped, lateness, period)
                        overrun = lateness + clock.skipped * period
            except (can.CanError, BusError, OSError) as exc:
                error = f"CAN bus error at tick {k}: {one_line(exc)}"
            except FlowtexError as exc:
                error = f"tick {k}: {one_line(exc)}"
            except Exception as exc:  # an exception inside the graph or a codec must still end in safe values
                error = f"tick {k}: {type(exc).__name__}: {one_line(exc)}"
            finally:
                safe_error = _send_safe(io, bus, writer)
                if audio is not None:
                    try:  # fade, stop, write --record-audio; a failure here must not skip what follows
                        audio_error = audio.stop()
                    except Exception as exc:
                        audio_error = f"audio output: {type(exc).__name__}: {one_line(exc)}"
                    safe_error = "; ".join(e for e in (safe_error, audio_error) if e) or None
                    if writer is not None:
                        for m in audio.take_events():  # the last runs of silence and the END event
                            writer.write(m, False)
                if device is not None:
                    device.collect(k)
                if rt_status is not None:
                    leave_realtime(rt_status)
        if writer is not None:  # renamed into place now that the exit block is in; a failed write discards it
            try:
                writer.close()
            except RecordError as exc:
                if error is None or str(exc) not in error:
                    error = f"{error}; {exc}" if error else str(exc)
        safe_sent = safe_error is None or not safe_error.startswith(SAFE_NOT_SENT)
        if safe_error:
            error = f"{error}; {safe_error}" if error else safe_error
        stats.watchdog_events = watchdog.events
        stats.timeouts = watchdog.stale_events
        stats.guard = guard_counts(io, audio)
        rt_granted = rt_status is not None and bool(rt_status.granted)
        if display is not None:
            display.finish(rt_granted)
        audio_summary = audio.summary() if audio is not None else None
        if stats_path is not None:
            try:
                stats.write_json(stats_path, rt_granted, extra={"audio": audio_summary} if audio_summary is not None else None)
            except FlowtexError as exc:  # a full disk: the session is over and its safe values went out; say so in the line
                error = f"{error}; --stats {one_line(exc)}" if error else f"--stats {one_line(exc)}"
    silent, silence = _silent_sensors(io, watchdog.last, k, stats.frames_in, where, refused)
    return LiveReport(ticks=k, frames_in=stats.frames_in, frames_out=stats.frames_out, watchdog_events=watchdog.events,
                      guard_events=guard_events, exit_reason="error" if error else (stop[0] or "duration"), error=error,
                      summary=stats.summary(rt_granted), rt_message=rt_message, send_offset_ns=send_offset[:min(k, capacity)],
                      device=device, silent_messages=silent, silence=silence,
                      no_sensor_frames=bool(k) and len(silent) == len(io.map.sensor_messages()) > 0,
                      warnings=refused.foreign_warnings(io, where) + clamp_warnings(io, k), audio=audio_summary, safe_sent=safe_sent)


def _audio_held(watchdog: Any, k: int) -> bool:
    """Whether tick ``k`` plays safe silence: while the input watchdog holds the outputs (a stale sensor, or no frame
    yet). The overrun watchdog holds the CAN outputs only: a late tick whose samples are still in time plays."""
    return watchdog.tripped and (watchdog.reason != "overrun" or first_stale(watchdog.last, watchdog.timeouts, k) >= 0)


def _silent_sensors(io: CanIO, last: np.ndarray, ticks: int, frames_in: int, where: str,
                    refused: RefusedFrames) -> tuple[list[str], str | None]:
    """The map's sensor messages of which no frame arrived (watchdog stamps never set), and one line saying so, with
    what arrived under each one's ID number that the DBC does not describe as it (``refused``)."""
    heard = {m for (_, m), t in zip(io.watchdog_keys, last, strict=True) if t >= 0}
    silent = [m for m in io.map.sensor_messages() if m not in heard]
    if not silent or not ticks:
        return silent, None
    # an extended message says so: a device sending it as a standard frame (or the reverse) sends another message
    names = ", ".join(f"{m} ({'extended ' if io.codecs[m].is_extended else ''}id {io.codecs[m].frame_id:#x}{refused.describe(io, m)})"
                      for m in silent)
    if len(silent) == len(io.map.sensor_messages()):
        other = f"; the {frames_in} frame(s) that arrived were none of them" if frames_in else ""
        return silent, (f"no sensor frame received in {ticks} ticks on {where}: expected {names}{other}. Outputs stayed at their "
                        "safe values. Check that the device is connected and powered, the --bus channel and --bitrate, and that "
                        "--dbc describes the device's messages")
    return silent, f"no frame of {names} received in {ticks} ticks on {where}; outputs stayed at their safe values"


def _enter_rt(rt: bool, priority: int, cpu: int | None, status: TextIO | None) -> tuple[RealtimeStatus | None, str]:
    """With ``rt``: ask for SCHED_FIFO at ``priority`` pinned to ``cpu`` and say what was granted; returns the status to restore.

    What was granted goes to ``status`` (none with ``--quiet``); what was refused goes to ``status`` or else stderr."""
    if not rt:
        return None, ""
    rt_status = enter_realtime(priority, cpu)
    message = str(rt_status.message)
    if rt_status.granted and not message:
        message = f"--rt: SCHED_FIFO priority {rt_status.priority}, pinned to CPU {rt_status.cpu}"
    elif message:  # a warning: what was asked for was not (all) granted; printed with --quiet too
        status = status if status is not None else sys.stderr
    if status is not None and message:
        print(message, file=status)
    return rt_status, message


STOP_SIGNALS = signals_named("SIGINT", "SIGTERM", "SIGHUP")
"""Signals that end a running session cleanly: safe values last, exit code 0 (SIGHUP does not exist on Windows)."""


@contextlib.contextmanager
def _stop_signals(flag: list[str | None], install: bool) -> Iterator[None]:
    """SIGINT, SIGTERM and SIGHUP set ``flag[0]`` instead of interrupting the loop (main thread only).

    SIGHUP (the terminal or ssh session closed) would otherwise end the process at once, without the safe values."""
    def handler(signum: int, frame: Any) -> None:
        flag[0] = signal.Signals(signum).name

    with signals_handled(STOP_SIGNALS, handler, install):
        yield


SAFE_NOT_SENT = "could not send the safe values"


def _send_safe(io: CanIO, bus: can.BusABC, writer: SessionWriter | None) -> str | None:
    """Encode and send every output's safe value (and log it); returns an error text, starting with
    :data:`SAFE_NOT_SENT` and naming the messages the bus refused, if any did not go out."""
    io.encode_safe()
    failed: list[str] = []
    reason = ""
    for m in io.tx:
        try:
            try:
                bus.send(m, SEND_TIMEOUT_S)
            except can.CanOperationError as exc:  # a full transmit queue gets SEND_TIMEOUT_S to take the frame
                send_when_queued(bus.send, m, SEND_TIMEOUT_S, exc)
        except Exception as exc:  # keep trying the other messages
            failed.append(f"{m.arbitration_id:#x}")
            reason = one_line(exc)
    problem = None
    if failed:
        problem = (f"{SAFE_NOT_SENT} (frame id {', '.join(failed)}): {reason}; the device did not receive them: "
                   "make it safe by hand")
    if writer is not None:
        writer.write_tick((), io.tx)
    return problem
