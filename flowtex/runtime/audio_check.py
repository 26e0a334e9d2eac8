"""Prove what a live session played: its ``--record-audio`` against the replay of its ``--record`` log.

With the session's audio timeline (:mod:`flowtex.runtime.audio_timeline`, in every log this
version records), :func:`rebuild_blocks` rebuilds the whole stream live handed to the sound card,
silence included, from the replay's tick samples, block by block; :class:`AudioChecker` compares it with the
live WAV as the blocks come, one line per class of frames (``flowtex run ... --expect-audio LIVE.wav``), so a
session of any length is checked in memory of a block (:func:`rebuild_live` and :func:`check_audio`: the same on
whole arrays).
For a log without a timeline, :func:`compare_audio` is the older, weaker check:

The replay WAV (``flowtex run GRAPH --input SESSION.blf ... --output REPLAY.wav``)
holds the live lead of silence, then every tick's samples back to back. Live
played tick ``k`` at ``lead + frames_before(k)`` (``k * up`` for a whole ratio) plus the silence of every resync before
it (``--stats``: ``audio.resyncs``, pairs of tick and inserted frames). Every
live frame that played a tick must equal the replay's; every other live frame
is safe silence: each run of differing frames is exactly the callback's fade from
the frame before it (``last * (1 - (f + 1) / fade)`` in float32, then zeros).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from ..dsp.audio_interp import frames_before
from .audio_ring import CLASS_END, CLASS_HELD, CLASS_LATE, CLASS_LEAD, CLASS_PLAYED
from .audio_timeline import AudioTimeline


@dataclass
class AudioComparison:
    """Outcome of :func:`compare_audio` (frame counts)."""

    compared: int
    equal: int
    silence: int
    """Differing frames that are safe silence (fade or zeros)."""
    unexplained: int
    """Differing frames that are not: a real difference."""
    first_unexplained: int | None = None

    @property
    def ok(self) -> bool:
        return self.unexplained == 0


def placed_replay(replay: np.ndarray, n_live: int, lead: int, up: int, resyncs: Sequence[Sequence[int]],
                  down: int = 1) -> np.ndarray:
    """The replay's tick samples at the stream positions live gave them (NaN where live played no tick)."""
    replay = replay.reshape(replay.shape[0], -1)
    n_ticks = 0
    while lead + frames_before(n_ticks + 1, up, down) <= replay.shape[0]:
        n_ticks += 1
    shift = np.zeros(n_ticks + 1, dtype=np.int64)
    for k, gap in resyncs:
        shift[min(int(k), n_ticks):] += int(gap)
    placed = np.full((n_live, replay.shape[1]), np.nan)
    for k in range(n_ticks):
        a, b = frames_before(k, up, down), frames_before(k + 1, up, down)
        p = lead + a + shift[k]
        if p + b - a <= n_live:
            placed[p:p + b - a] = replay[lead + a:lead + b]
    return placed


def fade_from(last: np.ndarray, n: int, fade: int, start: int = 0) -> np.ndarray:
    """The ``n`` frames of safe silence the callback plays after ``last`` (as float32 values, in float64), from the
    ``start``-th frame of the silence on (a run continued from an earlier block)."""
    f = np.arange(start + 1, start + n + 1, dtype=np.float64)
    g = np.where(f < fade, 1.0 - f / fade, 0.0)
    return (np.asarray(last, dtype=np.float64)[None, :] * g[:, None]).astype(np.float32).astype(np.float64)


def compare_audio(live: np.ndarray, replay: np.ndarray, lead: int, up: int, resyncs: Sequence[Sequence[int]],
                  fade: int, down: int = 1) -> AudioComparison:
    """Compare a live recording with the replay (see the module docstring); ``fade`` in frames; ``up / down``
    frames per tick (``--stats``: ``audio.ratio``)."""
    live = live.reshape(live.shape[0], -1).astype(np.float64)
    placed = placed_replay(replay, live.shape[0], lead, up, resyncs, down)
    known = ~np.isnan(placed).any(axis=1)
    same = known & (placed == live).all(axis=1)
    differ = ~same
    silence = unexplained = 0
    first = None
    i, n = 0, live.shape[0]
    while i < n:
        if not differ[i]:
            i += 1
            continue
        j = i
        while j < n and differ[j]:
            j += 1
        if np.array_equal(live[i:j], fade_from(live[i - 1] if i else np.zeros(live.shape[1]), j - i, fade)):
            silence += j - i
        else:
            unexplained += j - i
            first = i if first is None else first
        i = j
    return AudioComparison(compared=int(known.sum()), equal=int(same.sum()), silence=silence, unexplained=unexplained,
                           first_unexplained=first)


class AudioComparer:
    """:func:`compare_audio` (no resyncs: a log without an audio timeline) fed block by block: :meth:`feed` the live
    frames in order with the replay's frames at the same positions (lead included; as many as it has), then
    :meth:`finish`. Live frames ``[lead, known_end)`` are those on which live played a replayed tick; each run of
    differing frames (which may span blocks) is safe silence when it is the callback's fade from the frame before it."""

    def __init__(self, known_end: int, lead: int, fade: int, width: int):
        self.lead, self.known_end, self.fade = lead, known_end, fade
        self.position = self.compared = self.equal = self.silence = self.unexplained = 0
        self.first: int | None = None
        self.previous = np.zeros(width)
        """The last live frame fed."""
        self.run: list | None = None
        """The run of differing frames still open at the end of the last block: [first, frames, before it, fade so far]."""

    def feed(self, live: np.ndarray, replay: np.ndarray) -> None:
        """The next live frames (frames, channels) and the replay's at the same positions (fewer where it ends)."""
        m = live.shape[0]
        if not m:
            return
        live = live.astype(np.float64)
        idx = self.position + np.arange(m)
        known = (idx >= self.lead) & (idx < self.known_end)
        known[replay.shape[0]:] = False
        same = known.copy()
        n = min(m, replay.shape[0])
        same[:n] &= (replay[:n] == live[:n]).all(axis=1)
        self.compared += int(known.sum())
        self.equal += int(same.sum())
        differ = np.concatenate(([False], ~same, [False]))
        edges = np.flatnonzero(np.diff(differ.astype(np.int8)))
        for a, b in zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True):
            if a > 0 or self.run is None:
                self._close()
                self.run = [self.position + a, 0, live[a - 1] if a else self.previous, True]
            run = self.run
            run[3] = run[3] and np.array_equal(live[a:b], fade_from(run[2], b - a, self.fade, run[1]))
            run[1] += b - a
            if b < m:
                self._close()
        if same[-1]:
            self._close()
        self.previous = live[-1].copy()
        self.position += m

    def _close(self) -> None:
        run, self.run = self.run, None
        if run is None:
            return
        if run[3]:
            self.silence += run[1]
        else:
            self.unexplained += run[1]
            self.first = run[0] if self.first is None else self.first

    def finish(self) -> AudioComparison:
        self._close()
        return AudioComparison(compared=self.compared, equal=self.equal, silence=self.silence,
                               unexplained=self.unexplained, first_unexplained=self.first)


def known_end(n_live: int, n_ticks: int, lead: int, up: int, down: int = 1) -> int:
    """End of the live frames :func:`compare_audio` checks: the lead, then every whole tick live's WAV holds."""
    room = n_live - lead
    ticks = min(n_ticks, room * down // up) if room >= 0 else 0
    return lead + frames_before(ticks, up, down)


UNKNOWN = 255
"""Class of a rebuilt frame the timeline neither places a tick on nor marks as silence."""
REASONS = {CLASS_LEAD: "the lead before tick 0", CLASS_HELD: "ticks held by the input watchdog (a stale sensor)",
           CLASS_LATE: "ticks later than the margin (underruns)", CLASS_END: "the fade at the session's end",
           UNKNOWN: "frames the session log does not account for"}


BLOCK_FRAMES = 1 << 16
"""Frames of the rebuilt stream in one block of :func:`rebuild_blocks` (and compared at once with the live WAV)."""


def stream_frames(n_ticks: int, up: int, down: int, timeline: AudioTimeline) -> int:
    """Frames of the stream :func:`rebuild_blocks` rebuilds: the log's END count, else up to the last tick's frame or
    the last silence, whichever ends later."""
    if timeline.total is not None:
        return timeline.total
    n_frames = frames_before(n_ticks, up, down)
    inserted = sum(int(gap) for k, gap in timeline.resyncs if int(k) < n_ticks)
    ends = [timeline.lead + n_frames + inserted if n_frames else timeline.lead] + [b for _, b, _ in timeline.silences]
    return max(ends)


def _placed(samples: Iterable[np.ndarray], n_ticks: int, up: int, down: int, timeline: AudioTimeline,
            width: int) -> Iterator[tuple[np.ndarray | int, bool]]:
    """The stream before its silence: pieces in order, each the tick samples live played there (an array, played) or a
    count of frames no tick reaches (an int). Tick ``k`` follows the silence of every resync up to it."""
    gaps: dict[int, int] = {}
    for k, gap in timeline.resyncs:
        if int(k) < n_ticks:
            gaps[int(k)] = gaps.get(int(k), 0) + int(gap)
    cuts = sorted((frames_before(k, up, down), gap) for k, gap in gaps.items())
    yield timeline.lead, False
    j = c = 0  # frames of samples given so far; next cut
    for block in samples:
        block = block.reshape(block.shape[0], width)
        i = 0
        while i < block.shape[0]:
            while c < len(cuts) and cuts[c][0] <= j + i:
                yield cuts[c][1], False
                c += 1
            end = block.shape[0] if c == len(cuts) else min(block.shape[0], cuts[c][0] - j)
            yield block[i:end], True
            i = end
        j += block.shape[0]


def rebuild_blocks(samples: Iterable[np.ndarray], n_ticks: int, up: int, down: int, timeline: AudioTimeline,
                   width: int, block: int | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The stream a live session handed to its sound card, from the replay's tick samples and the session's timeline,
    as consecutive blocks of ``block`` frames (default :data:`BLOCK_FRAMES`; the last shorter): (frames float32, each frame's class: ``CLASS_PLAYED``,
    a silence reason, or :data:`UNKNOWN`). Memory of a block whatever the stream's length.

    ``samples``: the ``n_ticks`` ticks' samples back to back, no lead, in blocks of any size
    (:func:`~flowtex.runtime.audio_render.render_blocks`). Tick ``k`` goes to ``lead + frames_before(k)`` plus the
    silence of every resync up to it; every frame of a silence run, and every frame no tick reaches, plays the
    callback's fade from the sample before it (then zeros)."""
    total = stream_frames(n_ticks, up, down, timeline)
    block = max(1, int(block if block is not None else BLOCK_FRAMES))
    starts = np.array([a for a, _, _ in timeline.silences], dtype=np.int64)
    ends = np.array([b for _, b, _ in timeline.silences], dtype=np.int64)
    pieces = _placed(samples, n_ticks, up, down, timeline, width)
    piece: np.ndarray | int | None = None
    played = False
    last = np.zeros(width, dtype=np.float32)  # the latest played frame before the block
    run = 0  # silent frames since it
    for s in range(0, total, block):
        e = min(total, s + block)
        out = np.zeros((e - s, width), dtype=np.float32)
        klass = np.full(e - s, UNKNOWN, dtype=np.uint8)
        m = 0
        while m < e - s:
            if piece is None or (piece if isinstance(piece, int) else piece.shape[0]) == 0:
                piece, played = next(pieces, (e - s - m, False))
                continue
            take = min(e - s - m, piece if isinstance(piece, int) else piece.shape[0])
            if isinstance(piece, int):
                piece -= take
            else:
                out[m:m + take] = piece[:take]
                klass[m:m + take] = CLASS_PLAYED if played else UNKNOWN
                piece = piece[take:]
            m += take
        for i in np.flatnonzero((starts < e) & (ends > s)).tolist():
            a, b, reason = timeline.silences[i]
            klass[max(a, s) - s:min(b, e) - s] = reason
        silent = np.concatenate(([False], klass != CLASS_PLAYED, [False]))
        edges = np.flatnonzero(np.diff(silent.astype(np.int8)))
        for a, b in zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True):
            before, start = (last, run) if a == 0 else (out[a - 1], 0)
            out[a:b] = fade_from(before, b - a, timeline.fade, start)
        played_at = np.flatnonzero(klass == CLASS_PLAYED)
        if played_at.size:
            last, run = out[played_at[-1]].copy(), e - s - 1 - int(played_at[-1])
        else:
            run += e - s
        yield out, klass


def rebuild_live(samples: np.ndarray, n_ticks: int, up: int, down: int, timeline: AudioTimeline) -> tuple[np.ndarray, np.ndarray]:
    """The whole stream of :func:`rebuild_blocks` from the tick samples ``samples`` (frames, channels), as one array of
    frames (float32) and one of classes (tests and short streams)."""
    samples = samples.reshape(samples.shape[0], samples.shape[-1] if samples.ndim > 1 else 1)
    blocks = list(rebuild_blocks([samples[:frames_before(n_ticks, up, down)]], n_ticks, up, down, timeline, samples.shape[1]))
    if not blocks:
        return np.zeros((0, samples.shape[1]), dtype=np.float32), np.zeros(0, dtype=np.uint8)
    return np.concatenate([o for o, _ in blocks]), np.concatenate([k for _, k in blocks])


@dataclass
class AudioCheck:
    """Outcome of :func:`check_audio`: one line per class of frames, and how many frames differ unexplained."""

    lines: list[str]
    unexplained: int


class AudioChecker:
    """:func:`check_audio` fed block by block: :meth:`feed` the live frames and the rebuilt ones (:func:`rebuild_blocks`)
    at the same positions, in order, then :meth:`finish` with both streams' lengths; the report is the one the whole
    arrays give, in memory of a block."""

    def __init__(self, timeline: AudioTimeline, name: str, rate: float):
        self.timeline, self.name, self.rate = timeline, name, rate
        self.compared = 0
        self.same = dict.fromkeys((CLASS_PLAYED, *REASONS), 0)
        self.bad = dict.fromkeys((CLASS_PLAYED, *REASONS), 0)
        self.first: dict[int, tuple[int, list[float], list[float]]] = {}
        """Per class, the first differing frame: (index, live values, replay values)."""

    def feed(self, live: np.ndarray, rebuilt: np.ndarray, klass: np.ndarray) -> None:
        """Compare the next frames (as many of each as the shorter gives; none once the live WAV has ended)."""
        live = live.reshape(live.shape[0], -1) if live.ndim < 2 else live
        n = min(live.shape[0], rebuilt.shape[0])
        same = (live[:n] == rebuilt[:n]).all(axis=1)
        k = klass[:n]
        for reason in self.same:
            mask = k == reason
            self.same[reason] += int((mask & same).sum())
            bad = mask & ~same
            if bad.any():
                self.bad[reason] += int(bad.sum())
                if reason not in self.first:
                    i = int(np.flatnonzero(bad)[0])
                    self.first[reason] = (self.compared + i, live[i].tolist(), rebuilt[i].tolist())
        self.compared += n

    def finish(self, n_live: int, n_rebuilt: int) -> AudioCheck:
        """The report, ``n_live`` frames in the live WAV and ``n_rebuilt`` in the rebuilt stream."""
        timeline, name = self.timeline, self.name
        lines = [f"audio: {self.compared} frames compared with {name} ({n_live} in it, {n_rebuilt} in the replay)"]
        unexplained = 0
        lines.append(f"{self.same[CLASS_PLAYED]} frames: the ticks' samples, equal to {name} sample for sample"
                     + (f" ({len(timeline.resyncs)} resync(s) at tick(s) {_first(t for t, _ in timeline.resyncs)})" if timeline.resyncs else ""))
        for reason, text in REASONS.items():
            if self.same[reason]:
                lines.append(f"{self.same[reason]} frames: safe silence, equal: {text}")
        for reason in (CLASS_PLAYED, *REASONS):
            if self.bad[reason]:
                i, live_i, replay_i = self.first[reason]
                what = "the ticks' samples" if reason == CLASS_PLAYED else REASONS[reason]
                unexplained += self.bad[reason]
                lines.append(f"{self.bad[reason]} frames DIFFER ({what}), first at frame {i} ({i / self.rate:.4f} s): live {live_i}, "
                             f"replay {replay_i}: was the session run with another graph, parameters, --seed or map?")
        extra = n_live - n_rebuilt
        if extra > 0 and timeline.total is None:
            lines.append(f"{extra} frames after frame {n_rebuilt}: the session log ends before them (the session did not end "
                         "cleanly), not checked")
        elif extra:
            unexplained += abs(extra)
            lines.append(f"{abs(extra)} frames DIFFER in length: {name} has {n_live}, the session log says "
                         f"{n_rebuilt} were handed to the sound card: is {name} this session's --record-audio?")
        return AudioCheck(lines, unexplained)


def check_audio(live: np.ndarray, rebuilt: np.ndarray, klass: np.ndarray, timeline: AudioTimeline, name: str,
                rate: float) -> AudioCheck:
    """Compare the live ``--record-audio`` WAV (``name``) with the rebuilt stream (:func:`rebuild_live`), frame by frame,
    whole arrays (:class:`AudioChecker` does it block by block)."""
    checker = AudioChecker(timeline, name, rate)
    checker.feed(live, rebuilt, klass)
    return checker.finish(live.shape[0], rebuilt.shape[0])


def _first(items: Iterable[int], n: int = 6) -> str:
    items = list(items)
    return ", ".join(str(i) for i in items[:n]) + (", ..." if len(items) > n else "")
