"""The ``audio`` section of a map file: graph outputs played through the sound card (docs/live.md, "Audio output").

::

    audio:
      device: null             # optional: PortAudio device name (substring) or index; absent = default output
      rate: 8000               # Hz, p/q times the graph's rate (p, q <= 1000: 8000, 44100, 48000 for a 1 kHz graph)
      block: 64                # frames per PortAudio callback
      margin_ms: 10            # optional: how far ahead of the sound card the ticks run (robustness vs latency)
      margin_max_ms: 15        # optional: how far a stall the margin did not absorb may raise it
      channels:                # one entry per audio channel, in channel order
        - output: vibration    # a scalar graph output
          scale: 1.5           # graph units per full-scale sample (sample = value / scale)
          clip: 1.0            # graph units: a number C means [-C, C]; or [LOW, HIGH]

:func:`parse_audio` checks the section against its declaration (:mod:`flowtex.schema.devmap`) and reports each
problem to the map loader's :class:`~flowtex.schema.core.Collector` as a ``map.yaml:LINE:COL`` line.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..schema.core import INVALID, Collector, check_unknown, is_number, value_of
from ..schema.devmap import AUDIO, CHANNEL, DEFAULT_AUDIO_MARGIN_MAX_MS, DEFAULT_AUDIO_MARGIN_MS, MAP
from ..schema.devmap import MIN_AUDIO_RATE as MIN_RATE
from ..yamlsource import LocDict, LocList
from .dbc import suggest

__all__ = ["MIN_RATE", "AudioChannel", "AudioMap", "default_audio_map", "load_audio_section", "parse_audio"]


@dataclass(frozen=True)
class AudioChannel:
    """One audio channel: a scalar graph output, its scale (graph units per full-scale sample) and clip (graph units)."""

    output: str
    scale: float
    lo: float
    hi: float


@dataclass(frozen=True)
class AudioMap:
    """A checked ``audio`` section."""

    rate: float
    block: int
    channels: tuple[AudioChannel, ...]
    device: str | int | None = None
    margin_ms: float = DEFAULT_AUDIO_MARGIN_MS
    """Time, ms, by which each tick's samples are ready before the sound card's callback can need them: a stall of
    the tick loop shorter than this is absorbed (the loop catches up), a longer one inserts silence (a resync).
    Sensor-to-DAC latency grows by the same amount."""
    margin_max_ms: float = DEFAULT_AUDIO_MARGIN_MAX_MS
    """Largest margin, ms (>= ``margin_ms``): a resync raises the margin by the frames the tick was late, up to this."""
    rate_at: str = ""
    """Where the map sets ``rate`` (``map.yaml:20:9``), for a device that cannot play it; empty for a default map."""

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(scale, lo, hi) per channel as float64 arrays."""
        return (np.array([c.scale for c in self.channels]), np.array([c.lo for c in self.channels]),
                np.array([c.hi for c in self.channels]))


_number = is_number


def parse_audio(raw: Any, pos: Any, c: Collector, graph_outputs: dict[str, int] | None) -> AudioMap | None:
    """Check the ``audio`` mapping ``raw`` (at ``pos``); problems go to ``c``; None if any."""
    if not isinstance(raw, LocDict):
        c.error(pos, MAP.keys["audio"].message)
        return None
    before = len(c)
    check_unknown(c, raw, AUDIO)
    rate = raw.get("rate")
    if "rate" not in raw:
        c.error(raw.pos, AUDIO.keys["rate"].message.format(got=None))
    else:
        rate = value_of(c, raw, AUDIO, "rate")
    block = value_of(c, raw, AUDIO, "block")
    margin = value_of(c, raw, AUDIO, "margin_ms")
    most = value_of(c, raw, AUDIO, "margin_max_ms")
    if "margin_max_ms" not in raw and margin is not INVALID:
        most = max(most, margin)
    elif most is not INVALID and margin is not INVALID and most < margin:
        c.error(raw.value_pos.get("margin_max_ms", raw.pos), f"audio.margin_max_ms ({most:g}) is below audio.margin_ms "
                f"({margin:g}): give margin_max_ms >= margin_ms (equal: the margin never grows)")
    device = value_of(c, raw, AUDIO, "device") if "device" in raw else None
    channels = _channels(raw, c, graph_outputs)
    if len(c) > before:
        return None
    return AudioMap(rate=float(rate), block=int(block), channels=tuple(channels), device=device, margin_ms=float(margin),
                    margin_max_ms=float(most), rate_at=str(c.loc(raw.value_pos["rate"])))


def _channels(raw: LocDict, c: Collector, graph_outputs: dict[str, int] | None) -> list[AudioChannel]:
    items = raw.get("channels")
    if not isinstance(items, LocList) or not items:
        c.error(raw.value_pos.get("channels", raw.pos), AUDIO.keys["channels"].message.format())
        return []
    out = []
    for i, entry in enumerate(items):
        pos = items.item_pos[i]
        if not isinstance(entry, LocDict):
            c.error(pos, f"audio.channels[{i}]: expected a mapping with output, scale and clip")
            continue
        check_unknown(c, entry, CHANNEL, i=i)
        name = entry.get("output")
        if not isinstance(name, str):
            c.error(entry.value_pos.get("output", pos), CHANNEL.keys["output"].message.format(i=i))
            continue
        if graph_outputs is not None:
            if name not in graph_outputs:
                c.error(entry.value_pos["output"], f"audio.channels[{i}]: the graph has no output {name!r}{suggest(name, list(graph_outputs))}")
                continue
            if graph_outputs[name] != 1:
                c.error(entry.value_pos["output"], f"audio.channels[{i}]: output {name!r} has {graph_outputs[name]} components; "
                                                   "an audio channel plays one scalar output")
                continue
        scale = value_of(c, entry, CHANNEL, "scale", i=i)
        if scale is INVALID:
            continue
        lo_hi = _clip(entry.get("clip"))
        if lo_hi is None:
            c.error(entry.value_pos.get("clip", pos), CHANNEL.keys["clip"].message.format(i=i, got=repr(entry.get("clip"))))
            continue
        lo, hi = lo_hi
        if max(abs(lo), abs(hi)) > scale * (1 + 1e-12):
            c.error(entry.value_pos["clip"], f"audio.channels[{i}]: clip [{lo:g}, {hi:g}] exceeds full scale +-{scale:g} (scale); "
                                             f"raise scale to {max(abs(lo), abs(hi)):g} or narrow the clip")
            continue
        if not lo <= 0.0 <= hi:
            c.error(entry.value_pos["clip"], f"audio.channels[{i}]: clip [{lo:g}, {hi:g}] does not contain 0, so an output of "
                                             f"0 (a tool at rest) would play as a constant {lo if lo > 0 else hi:g} (a DC offset "
                                             "the speaker or voice coil carries for as long as it rests): give a clip from LOW <= 0 "
                                             "to HIGH >= 0")
            continue
        out.append(AudioChannel(name, float(scale), lo, hi))
    return out


def _clip(v: Any) -> tuple[float, float] | None:
    if _number(v) and v > 0:
        return -float(v), float(v)
    if isinstance(v, list) and len(v) == 2 and all(_number(x) for x in v) and v[0] < v[1]:
        return float(v[0]), float(v[1])
    return None


def default_audio_map(graph_outputs: dict[str, int], rate: float, block: int = 64) -> AudioMap:
    """Every scalar graph output as one channel, scale 1, clip [-1, 1]: what ``flowtex run --output OUT.wav`` plays without ``--map``."""
    channels = tuple(AudioChannel(n, 1.0, -1.0, 1.0) for n, w in graph_outputs.items() if w == 1)
    return AudioMap(rate=float(rate), block=int(block), channels=channels)


def load_audio_section(path: str | Path, graph_outputs: dict[str, int]) -> AudioMap:
    """Only the ``audio`` section of the map file ``path`` (offline rendering needs no DBC); raises GraphError/DataError."""
    from ..errors import DataError
    from ..yamlsource import load_yaml, read_source

    path = Path(path)
    data = load_yaml(read_source(path, "map file"), str(path))
    c = Collector(str(path))
    if not isinstance(data, LocDict) or "audio" not in data:
        raise DataError(f"{path}: the map has no 'audio' section (rate, block, channels); see docs/live.md, \"Audio output\"")
    amap = parse_audio(data["audio"], data.value_pos["audio"], c, graph_outputs)
    c.raise_if_any()
    assert amap is not None
    return amap
