"""From graph outputs at the tick rate to audio samples, the same way live and offline (docs/live.md, "Audio output").

Each channel of the map's ``audio`` section plays one scalar graph output:
``up = audio rate / graph rate`` samples per tick from the band-limited
minimum-phase interpolator (:mod:`flowtex.dsp.audio_interp`), clipped and scaled.
Live, the first tick plays after :func:`lead_frames` frames of silence; the
replay of a session puts the same silence first, so its WAV lines up with the
live ``--record-audio`` sample for sample.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np

from .. import limits
from ..dsp.audio_interp import Interpolator, frames_before
from ..dsp.resample import rational_ratio
from ..errors import DataError, FlowtexError
from ..io.audiomap import AudioMap


def samples_per_tick(amap: AudioMap, graph_rate: float, where: str = "map") -> tuple[int, int]:
    """``audio.rate / graph rate`` as ``(up, down)`` in lowest terms (8000/1000: (8, 1); 44100/1000: (441, 10));
    raises FlowtexError naming the fix when there is no such ratio with both <= 1000, or it is below 1."""
    try:
        up, down = rational_ratio(float(graph_rate), amap.rate)
    except ValueError as exc:
        raise FlowtexError(f"{where}: audio.rate {amap.rate:g} Hz: {exc}") from None
    if up < down:
        raise FlowtexError(f"{where}: audio.rate {amap.rate:g} Hz is below the graph's rate {graph_rate:g} Hz")
    return up, down


def margin_frames(amap: AudioMap) -> int:
    """The map's ``margin_ms`` in frames (rounded up): how far ahead of the callback's position each tick's first
    frame lies at the tick's deadline."""
    return max(1, math.ceil(amap.margin_ms * amap.rate / 1000.0 - 1e-9))


def lead_frames(amap: AudioMap) -> int:
    """Frames of silence before tick 0's first sample: one callback block and the margin (:func:`margin_frames`)."""
    return int(amap.block + margin_frames(amap))


def interpolator(amap: AudioMap, ratio: tuple[int, int]) -> Interpolator:
    """A fresh interpolator for the map's channels."""
    scale, lo, hi = amap.arrays()
    return Interpolator(ratio[0], len(amap.channels), scale, lo, hi, down=ratio[1])


BLOCK_TICKS = 4096
"""Ticks rendered at once by :func:`render_blocks`: 4096 ticks at 48 kHz from 1 kHz are 196,608 frames (0.8 MB a
channel as float32), so a render of any length holds about that much audio."""


def _tick_values(outputs: Mapping[str, np.ndarray], amap: AudioMap) -> tuple[list[np.ndarray], int]:
    """The graph outputs the map's channels play (each flattened, as given) and their tick count; refuses a channel
    whose output the graph does not produce."""
    missing = [c.output for c in amap.channels if c.output not in outputs]
    if missing:
        raise FlowtexError(f"audio channels play output(s) {', '.join(missing)} that the graph does not produce")
    columns = [np.asarray(outputs[c.output]).reshape(-1) for c in amap.channels]
    return columns, len(columns[0])


def check_length(frames: int, amap: AudioMap, n: int, what: str) -> None:
    """Refuse an audio stream of more than :data:`~flowtex.limits.MAX_AUDIO_SECONDS` at the map's rate: a DataError
    starting with ``what`` (the file it is for). The stream is rendered block by block (memory does not grow with it);
    this bounds the time and disk a render takes."""
    most = limits.max_audio_frames(amap.rate)
    if frames > most:
        raise DataError(f"{what}: {n:,} ticks play as {frames:,} audio frames ({frames / amap.rate / 3600:,.1f} hours at "
                        f"{amap.rate:g} Hz), more than flowtex renders ({most:,} frames, "
                        f"{limits.MAX_AUDIO_SECONDS / 3600:g} hours: flowtex.limits.MAX_AUDIO_SECONDS); render fewer ticks")


def render_blocks(outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float, lead: int = 0,
                  what: str = "audio", ticks: int | None = None, free: bool = False) -> Iterator[np.ndarray]:
    """The audio samples of :func:`render_outputs`, as consecutive float32 blocks (frames, channels) of at most
    ``ticks`` (default :data:`BLOCK_TICKS`) ticks' frames (the ``lead`` zero frames first, in blocks of at most that many): the same samples bit for
    bit (the interpolator keeps its state from block to block), in memory of one block whatever the stream's length.
    ``free``: scale 1 and no clip (:func:`clip_shares`). Refused before the first block past
    :func:`check_length`."""
    ratio = samples_per_tick(amap, graph_rate)
    ticks = max(1, int(ticks if ticks is not None else BLOCK_TICKS))
    columns, n = _tick_values(outputs, amap)
    width = len(amap.channels)
    check_length(lead + frames_before(n, *ratio), amap, n, what)
    if free:
        interp = Interpolator(ratio[0], width, np.ones(width), np.full(width, -np.inf), np.full(width, np.inf), down=ratio[1])
    else:
        interp = interpolator(amap, ratio)
    step = ticks * interp.max_frames
    for a in range(0, lead, step):
        yield np.zeros((min(step, lead - a), width), dtype=np.float32)
    for a in range(0, n, ticks):
        b = min(n, a + ticks)
        x = np.empty((b - a, width))
        for q, column in enumerate(columns):
            x[:, q] = column[a:b]
        out = np.empty((interp.frames(b - a), width), dtype=np.float32)
        interp.render(x, out)
        yield out


def render_outputs(outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float, lead: int = 0,
                   what: str = "audio") -> np.ndarray:
    """Audio samples (lead + n * up, channels) float32 for the graph outputs of ``n`` ticks (``lead`` zero frames first),
    whole in memory (tests and short streams; a file is written block by block: :func:`write_render`)."""
    blocks = list(render_blocks(outputs, amap, graph_rate, lead, what))
    return np.concatenate(blocks) if blocks else np.zeros((0, len(amap.channels)), dtype=np.float32)


def write_render(path: str | Path, outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float,
                 lead: int = 0) -> int:
    """Write the samples of :func:`render_blocks` as a float32 WAV at ``path`` block by block
    (:class:`~flowtex.io.wav.WavWriter`: atomic, an older file kept on failure); returns the frames written."""
    from ..io.atomic import kept_on_success
    from ..io.wav import WavWriter

    blocks = render_blocks(outputs, amap, graph_rate, lead, what=str(path))
    first = next(blocks, None)  # refused (too long, a missing output) before any file is opened
    with kept_on_success(WavWriter(path, amap.rate, len(amap.channels))) as writer:
        for block in itertools.chain([first] if first is not None else [], blocks):
            writer.write(block)
    return writer.frames


CLIP_SLACK = 2e-3
"""A frame counts as clipped beyond its clip by this share of the clip's size: the interpolator's passband ripple
(<= 0.01 dB, 0.12 %) alone moves a signal that sits at its clip (a 0/1 contact state at clip 1) that far."""


def clip_shares(outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float) -> list[float]:
    """Per channel, the share of audio frames the clip changed: the same render with scale 1 and no clip, counted
    outside ``[lo, hi]`` (graph units) by more than :data:`CLIP_SLACK`. The played samples are clipped as they should
    be; this says how many were. Counted block by block (:func:`render_blocks`)."""
    width = len(amap.channels)
    _, lo, hi = amap.arrays()
    slack = CLIP_SLACK * np.maximum(np.abs(lo), np.abs(hi))
    outside = np.zeros(width, dtype=np.int64)
    frames = 0
    for out in render_blocks(outputs, amap, graph_rate, free=True):
        outside += ((out < lo - slack) | (out > hi + slack)).sum(axis=0)
        frames += out.shape[0]
    return [float(v) / frames for v in outside] if frames else [0.0] * width
