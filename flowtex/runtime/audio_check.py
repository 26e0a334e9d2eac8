"""Prove what a live session played: its ``--record-audio`` against the replay of its ``--record`` log.

With the session's audio timeline (:mod:`flowtex.runtime.audio_timeline`, in every log this
version records), :func:`rebuild_live` rebuilds the whole stream live handed to the sound card,
silence included, from the replay's tick samples; :func:`check_audio` compares it with the
live WAV, one line per class of frames (``flowtex run ... --expect-audio LIVE.wav``).
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

from collections.abc import Iterable, Sequence
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


def fade_from(last: np.ndarray, n: int, fade: int) -> np.ndarray:
    """The ``n`` frames of safe silence the callback plays after ``last`` (as float32 values, in float64)."""
    f = np.arange(1, n + 1, dtype=np.float64)
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


UNKNOWN = 255
"""Class of a rebuilt frame the timeline neither places a tick on nor marks as silence."""
REASONS = {CLASS_LEAD: "the lead before tick 0", CLASS_HELD: "ticks held by the input watchdog (a stale sensor)",
           CLASS_LATE: "ticks later than the margin (underruns)", CLASS_END: "the fade at the session's end",
           UNKNOWN: "frames the session log does not account for"}


def rebuild_live(samples: np.ndarray, n_ticks: int, up: int, down: int, timeline: AudioTimeline) -> tuple[np.ndarray, np.ndarray]:
    """The stream a live session handed to its sound card, from the replay's tick samples and the session's timeline.

    ``samples`` (frames, channels): the ``n_ticks`` ticks' samples back to back, no lead
    (:func:`~flowtex.runtime.audio_render.render_outputs`). Tick ``k`` goes to ``lead + frames_before(k)`` plus the
    silence of every resync up to it; every frame of a silence run, and every frame no tick reaches, plays the
    callback's fade from the sample before it (then zeros). Returns the frames (float32) and each frame's class
    (``CLASS_PLAYED``, a silence reason, or :data:`UNKNOWN`)."""
    samples = samples.reshape(samples.shape[0], samples.shape[-1] if samples.ndim > 1 else 1)
    shift = np.zeros(n_ticks + 1, dtype=np.int64)
    for k, gap in timeline.resyncs:
        shift[min(int(k), n_ticks):] += int(gap)
    n_frames = frames_before(n_ticks, up, down)
    j = np.arange(n_frames, dtype=np.int64)
    pos = timeline.lead + j + shift[j * down // up]
    ends = [int(pos[-1]) + 1 if n_frames else timeline.lead] + [b for _, b, _ in timeline.silences]
    total = timeline.total if timeline.total is not None else max(ends)
    keep = pos < total
    out = np.zeros((total, samples.shape[1]), dtype=np.float32)
    klass = np.full(total, UNKNOWN, dtype=np.uint8)
    out[pos[keep]] = samples[:n_frames][keep]
    klass[pos[keep]] = CLASS_PLAYED
    for a, b, reason in timeline.silences:
        klass[a:min(b, total)] = reason
    silent = np.concatenate(([False], klass != CLASS_PLAYED, [False]))
    edges = np.flatnonzero(np.diff(silent.astype(np.int8)))
    for a, b in zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True):
        before = out[a - 1] if a else np.zeros(out.shape[1], dtype=np.float32)
        out[a:b] = fade_from(before, b - a, timeline.fade)
    return out, klass


@dataclass
class AudioCheck:
    """Outcome of :func:`check_audio`: one line per class of frames, and how many frames differ unexplained."""

    lines: list[str]
    unexplained: int


def check_audio(live: np.ndarray, rebuilt: np.ndarray, klass: np.ndarray, timeline: AudioTimeline, name: str,
                rate: float) -> AudioCheck:
    """Compare the live ``--record-audio`` WAV (``name``) with the rebuilt stream (:func:`rebuild_live`), frame by frame."""
    live = live.reshape(live.shape[0], -1)
    n = min(live.shape[0], rebuilt.shape[0])
    same = (live[:n] == rebuilt[:n]).all(axis=1)
    k = klass[:n]
    lines = [f"audio: {n} frames compared with {name} ({live.shape[0]} in it, {rebuilt.shape[0]} in the replay)"]
    unexplained = 0
    played = k == CLASS_PLAYED
    lines.append(f"{int((same & played).sum())} frames: the ticks' samples, equal to {name} sample for sample"
                 + (f" ({len(timeline.resyncs)} resync(s) at tick(s) {_first(t for t, _ in timeline.resyncs)})" if timeline.resyncs else ""))
    for reason, text in REASONS.items():
        mask = (k == reason) & same
        if mask.any():
            lines.append(f"{int(mask.sum())} frames: safe silence, equal: {text}")
    for reason in (CLASS_PLAYED, *REASONS):
        bad = (k == reason) & ~same
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            what = "the ticks' samples" if reason == CLASS_PLAYED else REASONS[reason]
            unexplained += int(bad.sum())
            lines.append(f"{int(bad.sum())} frames DIFFER ({what}), first at frame {i} ({i / rate:.4f} s): live {live[i].tolist()}, "
                         f"replay {rebuilt[i].tolist()}: was the session run with another graph, parameters, --seed or map?")
    extra = live.shape[0] - rebuilt.shape[0]
    if extra > 0 and timeline.total is None:
        lines.append(f"{extra} frames after frame {rebuilt.shape[0]}: the session log ends before them (the session did not end "
                     "cleanly), not checked")
    elif extra:
        unexplained += abs(extra)
        lines.append(f"{abs(extra)} frames DIFFER in length: {name} has {live.shape[0]}, the session log says "
                     f"{rebuilt.shape[0]} were handed to the sound card: is {name} this session's --record-audio?")
    return AudioCheck(lines, unexplained)


def _first(items: Iterable[int], n: int = 6) -> str:
    items = list(items)
    return ", ".join(str(i) for i in items[:n]) + (", ..." if len(items) > n else "")
