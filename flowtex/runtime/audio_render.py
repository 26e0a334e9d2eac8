"""From graph outputs at the tick rate to audio samples, the same way live and offline (docs/live.md, "Audio output").

Each channel of the map's ``audio`` section plays one scalar graph output:
``up = audio rate / graph rate`` samples per tick from the band-limited
minimum-phase interpolator (:mod:`flowtex.dsp.audio_interp`), clipped and scaled.
Live, the first tick plays after :func:`lead_frames` frames of silence; the
replay of a session puts the same silence first, so its WAV lines up with the
live ``--record-audio`` sample for sample.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

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


def render_outputs(outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float, lead: int = 0,
                   what: str = "audio") -> np.ndarray:
    """Audio samples (lead + n * up, channels) float32 for the graph outputs of ``n`` ticks (``lead`` zero frames first).
    A stream of more values than a recording may hold (:data:`~flowtex.limits.MAX_RECORDING_VALUES`) is refused before
    it is allocated: a DataError starting with ``what`` (the file it is for)."""
    ratio = samples_per_tick(amap, graph_rate)
    missing = [c.output for c in amap.channels if c.output not in outputs]
    if missing:
        raise FlowtexError(f"audio channels play output(s) {', '.join(missing)} that the graph does not produce")
    n = len(outputs[amap.channels[0].output])
    frames = lead + frames_before(n, *ratio)
    values = frames * len(amap.channels)
    if values > limits.MAX_RECORDING_VALUES:
        raise DataError(f"{what}: {n:,} ticks play as {frames:,} audio frames x {len(amap.channels)} channel(s), {values:,} "
                        f"values, more than a recording may hold ({limits.MAX_RECORDING_VALUES:,}: "
                        "flowtex.limits.MAX_RECORDING_VALUES); render fewer ticks or at a lower audio rate")
    x = np.stack([np.asarray(outputs[c.output], dtype=np.float64).reshape(-1) for c in amap.channels], axis=1)
    out = np.zeros((frames, x.shape[1]), dtype=np.float32)
    interpolator(amap, ratio).render(np.ascontiguousarray(x), out[lead:])
    return out


CLIP_SLACK = 2e-3
"""A frame counts as clipped beyond its clip by this share of the clip's size: the interpolator's passband ripple
(<= 0.01 dB, 0.12 %) alone moves a signal that sits at its clip (a 0/1 contact state at clip 1) that far."""


def clip_shares(outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float) -> list[float]:
    """Per channel, the share of audio frames the clip changed: the same render with scale 1 and no clip, counted
    outside ``[lo, hi]`` (graph units) by more than :data:`CLIP_SLACK`. The played samples are clipped as they should
    be; this says how many were."""
    ratio = samples_per_tick(amap, graph_rate)
    x = np.stack([np.asarray(outputs[c.output], dtype=np.float64).reshape(-1) for c in amap.channels], axis=1)
    out = np.zeros((frames_before(x.shape[0], *ratio), x.shape[1]), dtype=np.float32)
    width = len(amap.channels)
    free = Interpolator(ratio[0], width, np.ones(width), np.full(width, -np.inf), np.full(width, np.inf), down=ratio[1])
    free.render(np.ascontiguousarray(x), out)
    _, lo, hi = amap.arrays()
    slack = CLIP_SLACK * np.maximum(np.abs(lo), np.abs(hi))
    outside = (out < lo - slack) | (out > hi + slack)
    return [float(v) for v in outside.mean(axis=0)] if out.shape[0] else [0.0] * width
