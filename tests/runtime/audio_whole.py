"""The rebuild and check of a session's audio as they were before they streamed: whole arrays in memory.

Kept verbatim (flowtex.runtime.audio_check before block-by-block processing) as the oracle of
tests/runtime/test_audio_stream.py: the streamed rebuild and check must give these frames, classes and lines.
"""

from __future__ import annotations

import numpy as np

from flowtex.dsp.audio_interp import frames_before
from flowtex.runtime.audio_check import REASONS, UNKNOWN, AudioCheck, _first, fade_from
from flowtex.runtime.audio_ring import CLASS_PLAYED
from flowtex.runtime.audio_timeline import AudioTimeline


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
