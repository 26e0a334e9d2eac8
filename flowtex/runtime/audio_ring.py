"""The hand-over between the tick loop and the audio callback: a ring of rendered samples, filled per tick, read per callback.

Frames are addressed by their stream position ``q`` (frames handed to PortAudio
since the stream started). Tick ``k`` writes its samples (``up / down`` per tick on average, see
:func:`flowtex.dsp.audio_interp.frames_before`) at positions ``base + frames_before(k)`` on
(:meth:`AudioRing.put`), stamping each frame with its
position (or ``-(q + 2)``: computed, but to be played as silence because the
watchdog holds the outputs safe). ``base`` starts at ``lead`` frames (the silence
at stream start) and only moves forward when the tick loop fell behind the
callback (a *resync*, after a stall): the live stream then inserts silence there.
So what live plays is the offline render (``lead`` zero frames, then every
tick's samples), shifted by the silence of each resync, wherever live had the
samples in time.

:func:`fill` is the whole callback body, compiled and allocation-free, so the
callback's time is bounded by its frame count: a frame whose stamp is its
position plays; any other plays *safe silence*: a linear fade from the last
sample to zero over ``fade`` frames, then zeros. A frame at or after ``lead``
that is not stamped at all is late (counted in ``MISSING``/``UNDERRUNS``).

Beside each frame handed over, :func:`fill` records why it sounds as it does (``CLASS_*``:
a tick's sample, or safe silence for the lead, a held tick, a late tick or the stop):
the runs of silence are the session's audio timeline, which the session log keeps
(:mod:`flowtex.runtime.audio_timeline`) so that the replay can rebuild the live stream exactly.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from ..dsp.audio_interp import frames_before

# istate slots
MISSING = 0
"""Frames that should have played a tick's samples but the tick was late."""
UNDERRUNS = 1
"""Callbacks with at least one late frame."""
LATENCIES = 2
"""Latency samples stored so far."""
STOPPING = 3
"""Set by the tick loop: fade out and play silence from now on."""
FADED = 4
"""Consecutive frames of safe silence played (fade included)."""
RECORDED = 5
"""Frames handed to PortAudio so far (also the next recording position)."""
PLAYED = 6
"""Frames that played a tick's sample."""
N_ISTATE = 7

# why a frame sounds as it does (``AudioRing.klass``, parallel to the recording)
CLASS_PLAYED = 0
"""A tick's sample."""
CLASS_LEAD = 1
"""Safe silence before tick 0's first frame (the lead)."""
CLASS_HELD = 2
"""Safe silence: the tick was computed while the input watchdog held the outputs safe (a stale sensor)."""
CLASS_LATE = 3
"""Safe silence: the tick's samples were not there in time (a stall longer than the margin: an underrun)."""
CLASS_END = 4
"""Safe silence: the session is stopping (duration, Ctrl-C, SIGTERM, an error)."""


@njit(cache=True, nogil=True)
def fill(out, ring, stamps, lead, last, istate, fade, arrival, latency, dac_ns, rate, record, klass):
    """Fill ``out`` (frames, channels) float32 for positions ``istate[RECORDED]`` on; copy them to ``record``
    and why each sounds as it does (``CLASS_*``) to ``klass``.

    ``dac_ns``: the DAC time of ``out[0]`` in the clock of ``arrival`` (ns); for each
    frame that starts a tick with a new sensor frame, ``latency[...]`` gets DAC time minus arrival.
    Returns the number of late frames in this call.
    """
    n = out.shape[0]
    w = out.shape[1]
    cap = ring.shape[0]
    rcap = record.shape[0]
    pos = istate[RECORDED]
    late = 0
    stopping = istate[STOPPING] != 0
    for i in range(n):
        q = pos + i
        slot = q % cap
        st = stamps[slot]
        play = st == q and not stopping
        r = q % rcap
        if play:
            klass[r] = CLASS_PLAYED
            for c in range(w):
                v = ring[slot, c]
                out[i, c] = v
                last[c] = v
            istate[FADED] = 0
            istate[PLAYED] += 1
            if arrival[slot] != 0 and istate[LATENCIES] < latency.shape[0]:
                latency[istate[LATENCIES]] = dac_ns + (i * 1_000_000_000) // rate - arrival[slot]
                istate[LATENCIES] += 1
        else:
            if stopping:
                klass[r] = CLASS_END
            elif st == -(q + 2):
                klass[r] = CLASS_HELD
            elif q < lead:
                klass[r] = CLASS_LEAD
            else:
                klass[r] = CLASS_LATE
                late += 1
            f = istate[FADED]
            g = 1.0 - (f + 1) / fade if f + 1 < fade else 0.0
            for c in range(w):
                out[i, c] = np.float32(last[c] * g)
            istate[FADED] = f + 1
        for c in range(w):
            record[r, c] = out[i, c]
    istate[RECORDED] = pos + n
    istate[MISSING] += late
    if late:
        istate[UNDERRUNS] += 1
    return late


@njit(cache=True, nogil=True)
def put(ring, stamps, arrival, q, block, silent, arrival_ns):
    """Write ``block`` (frames, channels) at positions ``q ..``, then stamp them (``-(p + 2)`` when ``silent``)."""
    cap = ring.shape[0]
    for r in range(block.shape[0]):
        slot = (q + r) % cap
        for c in range(block.shape[1]):
            ring[slot, c] = block[r, c]
        arrival[slot] = arrival_ns if r == 0 else 0
    for r in range(block.shape[0]):
        p = q + r
        stamps[p % cap] = -(p + 2) if silent else p


class AudioRing:
    """Buffers shared by the tick loop (writer) and the callback (reader), sized for ``seconds`` of audio.

    ``up / down`` audio frames per tick, ``width`` channels, ``lead`` frames of silence before tick 0 plays.
    """

    def __init__(self, up: int, width: int, lead: int, rate: float, fade_s: float = 0.002, seconds: float = 1.0,
                 record_s: float = 8.0, latency_capacity: int = 1 << 20, down: int = 1) -> None:
        self.up, self.down, self.width, self.lead, self.rate = int(up), int(down), int(width), int(lead), int(rate)
        cap = int(seconds * rate)
        self.stamps = np.full(cap, -1, dtype=np.int64)
        self.ring = np.zeros((cap, width), dtype=np.float32)
        self.arrival = np.zeros(cap, dtype=np.int64)
        self.latency = np.zeros(latency_capacity, dtype=np.int64)
        self.last = np.zeros(width)
        self.istate = np.zeros(N_ISTATE, dtype=np.int64)
        self.fade = max(1, int(round(fade_s * rate)))
        self.record = np.zeros((int(2 ** np.ceil(np.log2(record_s * rate))), width), dtype=np.float32)
        self.klass = np.zeros(self.record.shape[0], dtype=np.uint8)
        """Per recorded frame, why it sounds as it does (``CLASS_*``)."""
        self.drained = 0
        self.base = self.lead
        """Position of tick 0's first frame; moved forward by :meth:`resync`."""
        self.resyncs: list[tuple[int, int]] = []
        """(tick, frames of silence inserted before it) per resync."""
        self.margin = 0
        """Frames between the callback's position and the first frame of the tick the latest :meth:`resync` placed."""

    def position(self, k: int) -> int:
        """Stream position of tick ``k``'s first frame."""
        return self.base + frames_before(k, self.up, self.down)

    def fill(self, out: np.ndarray, dac_ns: int) -> int:
        """The callback's body (:func:`fill`): ``out`` (frames, channels) float32, ``dac_ns`` the DAC time of ``out[0]``."""
        return fill(out, self.ring, self.stamps, self.lead, self.last, self.istate, self.fade, self.arrival, self.latency,
                    dac_ns, self.rate, self.record, self.klass)

    def put(self, k: int, block: np.ndarray, arrival_ns: int, silent: bool) -> None:
        """Tick ``k``'s samples ``block`` (frames, channels): let the callback play them (or play silence if ``silent``).

        ``arrival_ns``: when the newest sensor frame the tick used arrived (0: no new frame, no latency sample).
        """
        put(self.ring, self.stamps, self.arrival, self.position(k), block, silent, arrival_ns)

    def resync(self, k: int, ahead: int, most: int = 0) -> int:
        """If the callback already passed tick ``k``'s position, move ``base`` forward so that tick ``k`` plays
        ``ahead`` frames after the callback's position; returns the frames of silence inserted (0: in time).

        ``most`` > ``ahead`` lets the margin grow: tick ``k`` then plays ``ahead`` plus the frames it was behind
        after the callback's position, at most ``most`` (a stall as long as this one would be absorbed next time).
        :attr:`margin` keeps the frames it was placed after the callback's position."""
        done = int(self.istate[RECORDED])
        behind = done - self.position(k)
        if behind <= 0:
            return 0
        self.margin = max(ahead, min(most, ahead + behind))
        gap = behind + self.margin
        self.base += gap
        self.resyncs.append((int(k), gap))
        return gap

    def drain(self) -> tuple[int, np.ndarray, np.ndarray]:
        """``(position, frames, classes)``: the frames handed to PortAudio since the last drain from stream position
        ``position`` on, and why each sounds as it does (copies; call often enough: the record ring holds ``record_s``,
        and ``position`` is later than the previous drain's end when frames were lost)."""
        end = int(self.istate[RECORDED])
        cap = self.record.shape[0]
        start = max(self.drained, end - cap)
        idx = np.arange(start, end) % cap
        self.drained = end
        return start, self.record[idx].copy(), self.klass[idx].copy()

    def latencies_ms(self) -> np.ndarray:
        """Sensor-to-DAC latency of every tick played so far, ms."""
        return self.latency[:int(self.istate[LATENCIES])] / 1e6


ARRIVAL_WINDOW_NS = (-1_000_000_000, 60_000_000_000)
"""How far before (a clock adjusted since the session started) and after a sensor frame's bus timestamp the tick that
used it may be, ns. A timestamp outside is in another clock than the host's wall clock (an adapter's own, counted from
its start), or jumped: it gives no latency sample (it gave latencies of decades, or a negative one)."""


def sensor_arrival_ns(rx: list[Any], wall_minus_perf: int, sensors: dict[int, tuple[Any, Any, bool]], now_ns: int) -> int:
    """perf_counter time (ns) at which the newest sensor frame of ``rx`` arrived (its bus timestamp), for the audio
    latency; 0 (no latency sample) without one, or when that timestamp does not lie within :data:`ARRIVAL_WINDOW_NS`
    before ``now_ns`` (perf_counter ns), or is not finite (an infinite one ended the session with an OverflowError).
    ``sensors``: :attr:`flowtex.runtime.canio.CanIO.decoders` (frame id -> (decoder, entries, extended)); other
    frames (another node's, error and remote frames) say nothing of when the sensor's value arrived: the newest of
    them made the latency look shorter than it was."""
    newest = 0.0
    for m in rx:
        entry = sensors.get(m.arbitration_id)
        if (entry is not None and entry[2] == m.is_extended_id and not m.is_error_frame and not m.is_remote_frame
                and m.timestamp > newest and math.isfinite(m.timestamp)):
            newest = m.timestamp
    age_s = (now_ns + wall_minus_perf) * 1e-9 - newest
    if newest <= 0.0 or not ARRIVAL_WINDOW_NS[0] * 1e-9 - 1.0 <= age_s <= ARRIVAL_WINDOW_NS[1] * 1e-9 + 1.0:
        return 0  # far outside the window (in float seconds first: 1e300 s is no integer of nanoseconds either)
    arrival = int(newest * 1e9) - wall_minus_perf
    return arrival if ARRIVAL_WINDOW_NS[0] <= now_ns - arrival <= ARRIVAL_WINDOW_NS[1] else 0
