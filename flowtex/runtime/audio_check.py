"""Prove what a live session played: its ``--record-audio`` against the replay of its ``--record`` log.

The replay WAV (``flowtex run GRAPH --input SESSION.blf ... --output REPLAY.wav``)
holds the live lead of silence, then every tick's samples back to back. Live
played tick ``k`` at ``lead + frames_before(k)`` (``k * up`` for a whole ratio) plus the silence of every resync before
it (``--stats``: ``audio.resyncs``, pairs of tick and inserted frames). Every
live frame that played a tick must equal the replay's; every other live frame
is safe silence: each run of differing frames is exactly the callback's fade from
the frame before it (``last * (1 - (f + 1) / fade)`` in float32, then zeros).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..dsp.audio_interp import frames_before


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
