"""The live audio sink: graph outputs -> PortAudio (``sounddevice``) output stream, any host API.

The tick loop renders each tick's samples (:mod:`flowtex.runtime.audio_render`)
into an :class:`~flowtex.runtime.audio_ring.AudioRing`; PortAudio's callback
thread copies them out with one compiled call (:func:`~flowtex.runtime.audio_ring.fill`)
and never waits for the tick loop: a tick that is not there in time is played as
safe silence and counted as an underrun. Safety (docs/live.md, "Audio output"):
the stream starts with silence (``lead`` frames, PortAudio's own priming is
zeros); every sample is clipped per channel; on exit, a fault, a stale sensor (the
input watchdog) or a tick later than the margin the output fades to zero in 2 ms (the
overrun watchdog holds the CAN outputs only: a stall the margin absorbs plays on); a device that stops calling
back ends the session with :class:`AudioDeviceError`.
"""

from __future__ import annotations

import contextlib
import math
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FlowtexError
from ..graph.program import TickProgram
from ..io.audiomap import AudioMap
from .audio_render import interpolator, margin_frames, samples_per_tick
from .audio_ring import FADED, LATENCIES, MISSING, PLAYED, RECORDED, STOPPING, UNDERRUNS, AudioRing
from .audio_timeline import END, RESYNC, SILENCE, START, SilenceRuns, event_frame

PACE_SMOOTHING = 0.02
"""Weight of the newest tick in the smoothed pacing error (the callback's timing jitters by a block)."""
PACE_GAIN = 0.05
"""Fraction of the smoothed pacing error corrected per tick."""
PACE_MAX_NS = 100_000
"""Largest shift of one tick's deadline, ns (10 % of a 1 ms period: sound-card clocks are within 0.1 %, JACK's dummy
1.5 %, but a sound server starved of CPU on a loaded machine falls further behind, and a loop that cannot follow it
runs ahead without bound: measured, 1 s ahead at 2 %)."""
PACE_FAR_BLOCKS = 2
"""A loop further ahead of where the sound card needs it than the margin and this many blocks waits for the card at
once (a sound server that stopped or fell behind; the callback's own jitter stays within a block or two)."""
STALL_S = 0.5
"""A running stream whose callback has not run for this long (and at least 8 blocks) has lost its device."""
SETTLE_CALLBACKS = 4
"""Callbacks the stream plays silence for before tick 0 is placed (:meth:`AudioOutput.start`): the sound server's start
(JACK connects the new ports and reorders its graph) comes with irregular first callbacks, and a tick placed by the first
of them could already be late."""
NOT_STARTED = 1 << 62
"""The ring's lead until :meth:`AudioOutput.start` places tick 0: every frame before it is lead silence, never late."""


SWITCH_INTERVAL_S = 0.0005
"""Python's GIL switch interval during an audio session, s (default 5 ms): the callback runs Python code, and a tick
loop catching up after a stall holds the GIL between ticks; 0.5 ms keeps the callback's wait within a fifth of the
shortest period in use (2.7 ms at 48 kHz / 128)."""


@contextlib.contextmanager
def prompt_callbacks(on: bool = True) -> Iterator[None]:
    """Lower Python's GIL switch interval to :data:`SWITCH_INTERVAL_S` for the block (when ``on``), then restore it."""
    if not on:
        yield
        return
    old = sys.getswitchinterval()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    try:
        yield
    finally:
        sys.setswitchinterval(old)


class AudioDeviceError(FlowtexError):
    """The audio device could not be opened, or stopped during the session."""


def _sd() -> Any:
    try:
        import sounddevice
    except OSError as exc:  # the PortAudio library itself is missing
        raise AudioDeviceError(f"cannot load PortAudio ({exc}); on Debian/Ubuntu: apt-get install libportaudio2") from None
    return sounddevice


def _rate_hint(sd: Any, amap: AudioMap) -> str:
    """The device's own rate when the map asks another: a sound server (JACK, a USB card) runs at one rate and refuses
    a stream at any other, so the fix is the map's ``audio.rate`` (the interpolator renders any p/q of the graph's rate)."""
    try:
        native = float(sd.query_devices(amap.device, "output")["default_samplerate"])
    except Exception:  # noqa: BLE001 - no device to ask (absent, unplugged): the open error says enough
        return ""
    if not native > 0 or native == amap.rate:
        return ""
    return f"; the device runs at {native:g} Hz: set audio.rate: {native:g} ({amap.rate_at or 'the map'})"


def list_audio_devices() -> str:
    """PortAudio's host APIs and devices, one per line (``flowtex live --list-audio``); ``>`` marks the default output."""
    sd = _sd()
    apis = sd.query_hostapis()
    default_out = sd.default.device[1]
    lines = []
    for i, d in enumerate(sd.query_devices()):
        mark = ">" if i == default_out else " "
        lines.append(f"{mark} {i:3d} {d['name']} ({apis[d['hostapi']]['name']}, {d['max_output_channels']} out, "
                     f"{d['default_samplerate']:g} Hz)")
    if not lines:
        names = ", ".join(a["name"] for a in apis) or "none"
        lines.append(f"no audio devices (host APIs: {names}); is the sound server (e.g. jackd, PipeWire) running?")
    return "\n".join(lines)


class AudioOutput:
    """One live session's audio output for ``amap``'s channels, fed from ``graph`` at the graph's rate."""

    def __init__(self, graph: TickProgram, amap: AudioMap, record: str | Path | None = None, where: str = "map") -> None:
        self.amap = amap
        self.ratio = samples_per_tick(amap, float(graph.rate), where)
        self.lead = NOT_STARTED
        """Frames of silence before tick 0's first frame; set by :meth:`start` once the stream has settled."""
        self.interp = interpolator(amap, self.ratio)
        self.views = [graph.output_view(c.output).reshape(-1) for c in amap.channels]
        self.x = np.zeros((1, len(amap.channels)))
        self.ring = AudioRing(self.ratio[0], len(amap.channels), self.lead, amap.rate, down=self.ratio[1])
        self.ahead = margin_frames(amap)
        """Frames between the callback's position and a tick's first frame at the tick's deadline (tick 0 included);
        raised by a resync, up to :attr:`most` (:meth:`push`)."""
        self.most = max(self.ahead, math.ceil(amap.margin_max_ms * amap.rate / 1000.0 - 1e-9))
        """Largest margin, frames (the map's ``margin_max_ms``)."""
        self.block_buf = np.zeros((self.interp.max_frames, len(amap.channels)), dtype=np.float32)
        self.cb_end = 0
        self.cb_ns = 0
        self._pace_err = 0.0
        self.record_path = Path(record) if record is not None else None
        self._wav: Any = None
        """The ``--record-audio`` file being written (:class:`~flowtex.io.wav.WavWriter`), opened at the first drain: the
        frames go to disk as they are drained, so a session of any length records in bounded memory."""
        self._wav_error: FlowtexError | None = None
        self.log_timeline = False
        """Set by the live loop when the session is recorded: keep the timeline events (:meth:`take_events`)."""
        self._runs = SilenceRuns()
        self._events: list[Any] = []
        self.stream: Any = None
        self.device_name = "default output" if amap.device is None else repr(amap.device)
        self.pa_underflows = 0
        """PortAudio's output underflows after the stream played its first tick sample could (clicks)."""
        self.lead_underflows = 0
        """PortAudio's output underflows while every frame handed over was the lead's silence (a sound server's start;
        not clicks: the server played zeros in place of zeros)."""
        self.callbacks = 0
        self.last_callback_ns = 0
        self.error: str | None = None
        self.lost = False
        """The device vanished: PortAudio's stop and terminate calls may then block forever (JACK host API)."""
        self.first_callback = threading.Event()
        self._started_ns = 0
        # compile/load the kernels now, not in the callback or on the first live tick
        self.interp.render(self.x, self.block_buf)
        self.interp.reset()
        self.ring.put(0, self.block_buf, 0, True)
        self.ring.stamps[:] = -1
        self.ring.fill(np.zeros((amap.block, len(amap.channels)), dtype=np.float32), 0)
        self.ring.istate[:] = 0
        self.ring.last[:] = 0.0
        self.ring.record[:] = 0.0

    def _callback(self, outdata: np.ndarray, frames: int, time_info: Any, status: Any) -> None:
        now = time.perf_counter_ns()
        try:
            if status.output_underflow:  # the server played zeros since the last callback
                if self.ring.istate[RECORDED] <= self.lead:
                    self.lead_underflows += 1  # everything handed over so far was lead silence: zeros for zeros
                else:
                    self.pa_underflows += 1
            ahead = time_info.outputBufferDacTime - time_info.currentTime
            dac_ns = now + int(ahead * 1e9) if 0.0 <= ahead < 10.0 else now
            self.ring.fill(outdata, dac_ns)
            self.cb_end = int(self.ring.istate[RECORDED])
            self.cb_ns = now
        except Exception as exc:  # never let an exception through PortAudio's thread: silence, then report
            outdata.fill(0.0)
            self.error = f"audio callback failed: {type(exc).__name__}: {exc}"
        self.callbacks += 1
        self.last_callback_ns = now
        self.first_callback.set()

    def start(self, timeout_s: float = 2.0) -> None:
        """Open the device, start the stream and place tick 0: returns after :data:`SETTLE_CALLBACKS` callbacks of
        silence, with tick 0's first frame ``ahead`` frames after the frames handed over by then (the lead), so the
        clock started next has the whole margin from tick 0 on (the stream's start-up costs silence, not a late tick)."""
        sd = _sd()
        a = self.amap
        try:
            self.stream = sd.OutputStream(samplerate=a.rate, blocksize=a.block, device=a.device, channels=len(a.channels),
                                          dtype="float32", latency="low", callback=self._callback, dither_off=True,
                                          prime_output_buffers_using_stream_callback=False)
            self.stream.start()
        except (sd.PortAudioError, ValueError) as exc:
            self.close()
            raise AudioDeviceError(f"audio device {self.device_name}: cannot open {len(a.channels)} channel(s) at {a.rate:g} Hz, "
                                   f"block {a.block}: {' '.join(str(exc).split())}"
                                   f"{_rate_hint(sd, a) or ' (flowtex live --list-audio lists the devices)'}") from None
        self._started_ns = time.perf_counter_ns()
        if not self.first_callback.wait(timeout_s):
            self.close()
            raise AudioDeviceError(f"audio device {self.device_name}: the stream started but PortAudio never asked for samples "
                                   f"within {timeout_s:g} s")
        end = time.monotonic() + timeout_s
        while self.callbacks < SETTLE_CALLBACKS and time.monotonic() < end:
            time.sleep(self.amap.block / self.amap.rate / 4)
        self.place_tick0()

    def place_tick0(self) -> None:
        """Set the lead: tick 0's first frame goes ``ahead`` frames after the frames handed over so far."""
        self.lead = int(self.ring.istate[RECORDED]) + self.ahead
        self.ring.lead = self.ring.base = self.lead

    def push(self, k: int, arrival_ns: int, silent: bool) -> bool:
        """Render tick ``k`` from the graph's current outputs and hand it to the callback (``silent``: play safe silence).

        A tick the callback has already passed (after a stall longer than the margin) resyncs the stream: silence is
        inserted so that this tick plays after the callback's position by the margin plus the frames it was late, at
        most ``margin_max_ms``: the margin grows to absorb as long a stall next time. Returns True when it grew
        (the loop then lets its clock catch up as far: :meth:`catch_up_s`)."""
        x = self.x
        for c, v in enumerate(self.views):
            x[0, c] = v[0]
        n = self.interp.render(x, self.block_buf)
        gap = self.ring.resync(k, self.ahead, self.most)
        grew = False
        if gap:
            grew, self.ahead = self.ring.margin > self.ahead, self.ring.margin
            if self.log_timeline:
                self._events.append(event_frame(RESYNC, k, gap, self.ring.position(k)))
        self.ring.put(k, self.block_buf[:n], arrival_ns, silent)
        return grew

    def catch_up_s(self) -> float:
        """The current margin, s: a stall of the tick loop shorter than this is caught up (the clock's ``catch_up_s``)."""
        return self.ahead / self.amap.rate

    def pace(self, k: int, next_deadline_ns: int) -> int:
        """How far (ns) to move the next tick's deadline so that the ticks follow the sound card's clock.

        The deadline of tick ``k + 1`` should come ``ahead`` frames before the callback reaches its position
        (extrapolated from the latest callback at the nominal rate); the error is smoothed over ~50 ticks and
        corrected by :data:`PACE_GAIN` per tick, at most :data:`PACE_MAX_NS`."""
        if not self.cb_ns:
            return 0
        want = self.cb_ns + (self.ring.position(k + 1) - self.ahead - self.cb_end) * 1e9 / self.amap.rate
        err = want - next_deadline_ns
        if err > (self.ahead + PACE_FAR_BLOCKS * self.amap.block) * 1e9 / self.amap.rate:  # far ahead of a stalled card
            self._pace_err = 0.0
            return int(err)
        self._pace_err += PACE_SMOOTHING * (err - self._pace_err)
        return int(max(-PACE_MAX_NS, min(PACE_MAX_NS, PACE_GAIN * self._pace_err)))

    def check(self) -> None:
        """In the loop's slack: raise :class:`AudioDeviceError` when the device stopped; keep the recording drained."""
        if self.error is not None:
            raise AudioDeviceError(self.error)
        stream = self.stream
        now = time.perf_counter_ns()
        stall = max(STALL_S, 8 * self.amap.block / self.amap.rate) * 1e9
        if stream is not None and (now - self.last_callback_ns > stall or not stream.active):
            self.lost = True
            why = (f"no callback for {(now - self.last_callback_ns) / 1e9:.2f} s" if stream.active
                   else "PortAudio stopped the stream")
            raise AudioDeviceError(f"audio device {self.device_name} stopped: {why} (device unplugged or sound server gone)")
        if ((self.record_path is not None or self.log_timeline)
                and self.ring.istate[RECORDED] - self.ring.drained > self.ring.record.shape[0] // 4):
            self._drain()

    def _drain(self) -> None:
        """Move the frames handed over since the last drain to the recording, and their runs of silence to the events."""
        position, frames, classes = self.ring.drain()
        if self.record_path is not None and self._wav_error is None:
            if self._wav is None:
                from ..io.wav import WavWriter

                try:
                    self._wav = WavWriter(self.record_path, self.amap.rate, len(self.amap.channels))
                except FlowtexError as exc:  # said when the session ends (this runs in the live loop)
                    self._wav_error = exc
            if self._wav is not None:
                self._wav.write(frames)
        if self.log_timeline:
            self._events.extend(event_frame(SILENCE, *run) for run in self._runs.feed(position, classes))

    def start_event(self) -> Any:
        """The timeline's ``START`` event (lead, fade and margin frames) for the session log."""
        return event_frame(START, self.lead, self.ring.fade, self.ahead)

    def take_events(self) -> list[Any]:
        """Timeline events (:mod:`flowtex.runtime.audio_timeline`) since the last call, for the session log."""
        events, self._events = self._events, []
        return events

    @property
    def underruns(self) -> int:
        """Callbacks that found a tick late (``late_callbacks``: the tick loop's stall outlasted the margin), plus
        PortAudio's own output underflows (``device_underflows``: the sound server's xruns, e.g. JACK's)."""
        return int(self.ring.istate[UNDERRUNS]) + self.pa_underflows

    def status_text(self) -> str:
        return f"audio underruns {self.underruns}"

    def nonfinite_counts(self) -> dict[str, int]:
        """Per audio channel, the ticks whose graph value was NaN or inf (played as 0), keyed ``audio channel N (OUTPUT)``:
        the audio side of the guard's ``nonfinite`` counts (:func:`~flowtex.runtime.status.guard_counts`). Every tick
        the loop rendered counts, those played as safe silence while the input watchdog held the outputs too."""
        return {f"audio channel {i} ({c.output})": int(n) for i, (c, n) in enumerate(zip(self.amap.channels, self.interp.nonfinite,
                                                                                          strict=True))}

    def stop(self, timeout_s: float = 0.5) -> str | None:
        """Fade to zero, let the fade play, stop and close the stream, write the recording; returns an error text or None."""
        problem = None
        ring = self.ring
        ring.istate[STOPPING] = 1
        if self.stream is not None and self.error is None and not self.lost:
            end = time.monotonic() + timeout_s
            target = ring.fade + self.amap.block
            while ring.istate[FADED] < target and time.monotonic() < end and self.stream.active:
                time.sleep(self.amap.block / self.amap.rate / 4)
            if ring.istate[FADED] < target:
                problem = f"audio device {self.device_name}: the fade to silence was not played"
        try:
            self.close()
            self._drain()
        except BaseException:  # the recording is incomplete: its temporary file goes, an older file stays
            if self._wav is not None:
                with contextlib.suppress(FlowtexError):
                    self._wav.close(keep=False)
            raise
        if self.log_timeline:
            self._events.extend(event_frame(SILENCE, *run) for run in self._runs.close())
            self._events.append(event_frame(END, int(ring.istate[RECORDED]), int(ring.istate[PLAYED])))
        if self.record_path is not None:
            try:
                if self._wav_error is not None:
                    raise self._wav_error
                if self._wav is not None:
                    self._wav.close()
            except FlowtexError as exc:  # a full disk: the session's line names the option and the file
                problem = "; ".join(p for p in (problem, f"--record-audio {exc}") if p)
        return problem

    def close(self) -> None:
        """Stop and close the stream (idempotent). After the device vanished the stream is left alone: PortAudio's
        JACK host API blocks forever in Pa_StopStream, Pa_AbortStream and Pa_Terminate once the server is gone,
        so sounddevice's exit handler (which calls them) is unregistered too."""
        stream, self.stream = self.stream, None
        if stream is not None and self.lost:
            import atexit

            self._abandoned = stream  # keep it referenced; the process ends without PortAudio's cleanup
            handler = getattr(_sd(), "_exit_handler", None)
            if handler is not None:
                atexit.unregister(handler)
        elif stream is not None:
            try:
                stream.stop()
                stream.close()
            except Exception:  # a vanished device: nothing left to stop
                pass

    def summary(self) -> dict:
        """The ``"audio"`` entry of ``--stats``: rate, frames handed to PortAudio, underruns, latency_ms p50/p99/max."""
        lat = self.ring.latencies_ms()
        dist = ({"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)), "max": float(lat.max())}
                if lat.size else {"p50": None, "p99": None, "max": None})
        return {"rate": float(self.amap.rate), "frames": int(self.ring.istate[RECORDED]), "underruns": self.underruns,
                "latency_ms": dist, "played_frames": int(self.ring.istate[PLAYED]),
                "lead_frames": int(self.lead) if self.lead != NOT_STARTED else None,
                "samples_per_tick": self.ratio[0] / self.ratio[1], "ratio": list(self.ratio),
                "latency_samples": int(self.ring.istate[LATENCIES]),
                "late_callbacks": int(self.ring.istate[UNDERRUNS]), "device_underflows": self.pa_underflows,
                "lead_underflows": self.lead_underflows,
                "margin_ms": self.amap.margin_ms, "margin_max_ms": self.amap.margin_max_ms,
                "margin_end_ms": round(self.ahead * 1000.0 / self.amap.rate, 3),
                "late_frames": int(self.ring.istate[MISSING]), "fade_frames": int(self.ring.fade),
                "resyncs": [list(r) for r in self.ring.resyncs]}
