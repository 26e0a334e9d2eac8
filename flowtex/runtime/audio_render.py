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

from ..dsp.audio_interp import Interpolator
from ..errors import FlowtexError
from ..io.audiomap import AudioMap

LEAD_MARGIN_S = 0.001
"""Slack between a tick's deadline and the callback that needs its samples (tick jitter allowed before an underrun), s."""


def samples_per_tick(amap: AudioMap, graph_rate: float, where: str = "map") -> int:
    """``audio.rate / graph rate`` as an integer; raises FlowtexError naming the fix otherwise."""
    up = amap.rate / float(graph_rate)
    if abs(up - round(up)) > 1e-9 * up or round(up) < 1:
        near = max(1, round(up)) * graph_rate
        raise FlowtexError(f"{where}: audio.rate {amap.rate:g} Hz is not a whole multiple of the graph's rate {graph_rate:g} Hz; "
                           f"use e.g. {near:g} Hz (the sound card must support it)")
    return int(round(up))


def lead_frames(amap: AudioMap, up: int) -> int:
    """Frames of silence before tick 0's first sample: one callback block, one tick and :data:`LEAD_MARGIN_S`."""
    return int(amap.block + up + math.ceil(LEAD_MARGIN_S * amap.rate))


def interpolator(amap: AudioMap, up: int) -> Interpolator:
    """A fresh interpolator for the map's channels."""
    scale, lo, hi = amap.arrays()
    return Interpolator(up, len(amap.channels), scale, lo, hi)


def render_outputs(outputs: Mapping[str, np.ndarray], amap: AudioMap, graph_rate: float, lead: int = 0) -> np.ndarray:
    """Audio samples (lead + n * up, channels) float32 for the graph outputs of ``n`` ticks (``lead`` zero frames first)."""
    up = samples_per_tick(amap, graph_rate)
    missing = [c.output for c in amap.channels if c.output not in outputs]
    if missing:
        raise FlowtexError(f"audio channels play output(s) {', '.join(missing)} that the graph does not produce")
    x = np.stack([np.asarray(outputs[c.output], dtype=np.float64).reshape(-1) for c in amap.channels], axis=1)
    out = np.zeros((lead + x.shape[0] * up, x.shape[1]), dtype=np.float32)
    interpolator(amap, up).render(np.ascontiguousarray(x), out[lead:])
    return out
