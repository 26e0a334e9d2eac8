"""The audio timeline of a live session, kept in its CAN session log (docs/live.md, "What was played").

What the sound card played is the ticks' samples, placed on the stream, with safe
silence wherever live had no sample to play. The samples the replay computes from the
logged CAN frames; where they were placed and where silence played instead only the
live run knows. So ``--record`` writes those events into the session log, as frames of
their own that no device sends:

- ``START`` (lead frames, fade frames, margin frames): written before tick 0;
- ``RESYNC`` (tick, silence frames inserted before it, its stream position): a stall
  longer than the margin, after which the tick plays later;
- ``SILENCE`` (first frame, end frame, reason): a run of frames that played safe
  silence (reason: :data:`~flowtex.runtime.audio_ring.CLASS_LEAD`, ``_HELD``, ``_LATE``
  or ``_END``), from what the callback itself recorded;
- ``END`` (frames handed to the sound card, frames that played a tick's sample, 0).

Each is a CAN FD frame (24 bytes: three little-endian int64) on the extended ID
``AUDIO_EVENT_BASE + kind``, marked as written by the runtime (``is_rx=False``) and
never sent on the bus. A live session refuses a map that sends on these IDs
(:func:`check_event_ids`), so a written frame on one of them is always an event.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass, field

import can
import numpy as np

from ..errors import FlowtexError
from .audio_ring import CLASS_PLAYED

AUDIO_EVENT_BASE = 0x1FFFFA00
"""Extended CAN ID of the first audio timeline event (kinds 1-4 follow)."""
START, RESYNC, SILENCE, END = 1, 2, 3, 4
_PACK = struct.Struct("<3q")


def event_frame(kind: int, a: int, b: int = 0, c: int = 0) -> can.Message:
    """One timeline event as a log frame (see the module docstring)."""
    return can.Message(arbitration_id=AUDIO_EVENT_BASE + kind, is_extended_id=True, is_fd=True, is_rx=False,
                       data=_PACK.pack(int(a), int(b), int(c)))


def is_event(msg: can.Message) -> bool:
    """True for a timeline event frame (a written frame on one of the event IDs)."""
    return (not msg.is_rx and msg.is_extended_id and START <= msg.arbitration_id - AUDIO_EVENT_BASE <= END
            and len(msg.data) == _PACK.size)


def check_event_ids(tx_ids: Iterable[tuple[int, bool]], where: str) -> None:
    """Refuse a map that sends on the timeline's IDs (its frames could not be told from the events)."""
    for frame_id, extended in tx_ids:
        if extended and 0 <= frame_id - AUDIO_EVENT_BASE <= END:
            raise FlowtexError(f"{where}: an output is sent on CAN ID {frame_id:#x}, which the session log reserves for the "
                               f"audio timeline ({AUDIO_EVENT_BASE + START:#x}-{AUDIO_EVENT_BASE + END:#x}); use another message")


@dataclass
class AudioTimeline:
    """The timeline events of one session log."""

    lead: int
    fade: int
    margin: int
    resyncs: list[tuple[int, int]] = field(default_factory=list)
    """(tick, frames of silence inserted before it)."""
    silences: list[tuple[int, int, int]] = field(default_factory=list)
    """(first frame, end frame, reason) of each run of safe silence."""
    total: int | None = None
    """Frames handed to the sound card (None: the log has no END event; the session did not end cleanly)."""
    played: int | None = None

    def problem(self, most: int) -> str | None:
        """The first event whose values no live session writes (negative, or more than ``most`` frames: the stream
        the replay rebuilds from them would be longer than a recording may be), as a phrase; None if there is none."""
        if not 0 <= self.lead <= most:
            return f"START event: a lead of {self.lead:,} frames"
        if not 1 <= self.fade <= most:
            return f"START event: a fade of {self.fade:,} frames"
        if not 0 <= self.margin <= most:
            return f"START event: a margin of {self.margin:,} frames"
        inserted = 0
        for tick, gap in self.resyncs:
            inserted += gap
            if tick < 0 or not 0 <= gap <= most or self.lead + inserted > most:
                return f"RESYNC event: {gap:,} frames of silence before tick {tick:,}"
        for a, b, _ in self.silences:
            if not 0 <= a <= b <= most:
                return f"SILENCE event: frames {a:,} to {b:,}"
        if self.total is not None and not 0 <= self.total <= most:
            return f"END event: {self.total:,} frames handed to the sound card"
        if self.played is not None and not 0 <= self.played <= most:
            return f"END event: {self.played:,} frames that played a tick's sample"
        return None


class TimelineEvents:
    """Collects the timeline events of a session log's frames fed in order, one at a time (the replay streams the log).

    :meth:`take` says whether a frame is an event (then kept here, else left to the caller); :attr:`timeline` is the
    timeline found so far (None until a START event). Its lists grow with the events (a few per stall), not the frames."""

    def __init__(self) -> None:
        self.timeline: AudioTimeline | None = None

    def take(self, m: can.Message) -> bool:
        """True when ``m`` is a timeline event (an event before START is taken and ignored: not a timeline flowtex wrote)."""
        if not is_event(m):
            return False
        kind = m.arbitration_id - AUDIO_EVENT_BASE
        a, b, c = _PACK.unpack(bytes(m.data))
        timeline = self.timeline
        if kind == START:
            self.timeline = AudioTimeline(lead=a, fade=b, margin=c)
        elif timeline is None:
            pass
        elif kind == RESYNC:
            timeline.resyncs.append((a, b))
        elif kind == SILENCE:
            timeline.silences.append((a, b, c))
        else:
            timeline.total, timeline.played = a, b
        return True


class SilenceRuns:
    """Turns the per-frame classes the callback recorded (:meth:`~flowtex.runtime.audio_ring.AudioRing.drain`,
    in order) into runs of safe silence ``(first frame, end frame, reason)``."""

    def __init__(self) -> None:
        self.open: list[int] | None = None
        """The run still going at the end of the last chunk: [first, end, reason]."""

    def feed(self, position: int, classes: np.ndarray) -> list[tuple[int, int, int]]:
        """The runs closed by ``classes`` (frames ``position ..``)."""
        done: list[tuple[int, int, int]] = []
        n = classes.shape[0]
        if not n:
            return done
        cuts = np.flatnonzero(np.diff(classes)) + 1
        starts = np.concatenate(([0], cuts))
        ends = np.concatenate((cuts, [n]))
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            reason = int(classes[a])
            run = self.open
            if run is not None and run[2] == reason and run[1] == position + a:
                run[1] = position + b
                continue
            if run is not None:
                done.append((run[0], run[1], run[2]))
            self.open = [position + a, position + b, reason] if reason != CLASS_PLAYED else None
        return done

    def close(self) -> list[tuple[int, int, int]]:
        """The run still open (at the end of the session)."""
        run, self.open = self.open, None
        return [(run[0], run[1], run[2])] if run is not None else []
