"""The ``audio`` section of a map file: graph outputs played through the sound card (docs/live.md, "Audio output").

::

    audio:
      device: null             # optional: PortAudio device name (substring) or index; absent = default output
      rate: 8000               # Hz, p/q times the graph's rate (p, q <= 1000: 8000, 44100, 48000 for a 1 kHz graph)
      block: 64                # frames per PortAudio callback
      channels:                # one entry per audio channel, in channel order
        - output: vibration    # a scalar graph output
          scale: 1.5           # graph units per full-scale sample (sample = value / scale)
          clip: 1.0            # graph units: a number C means [-C, C]; or [LOW, HIGH]

:func:`parse_audio` checks the section and appends ``(position, problem)`` pairs
to a list (the map loader turns them into ``map.yaml:LINE:COL`` lines).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..yamlsource import LocDict, LocList
from .dbc import suggest

AUDIO_KEYS = ("device", "rate", "block", "channels", "doc")
CHANNEL_KEYS = ("output", "scale", "clip", "doc")
MIN_RATE = 5000.0
"""Lowest audio rate accepted, Hz (the issue's and Culbertson 2012's floor)."""


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

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(scale, lo, hi) per channel as float64 arrays."""
        return (np.array([c.scale for c in self.channels]), np.array([c.lo for c in self.channels]),
                np.array([c.hi for c in self.channels]))


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


Add = Callable[[Any, str], None]


def parse_audio(raw: Any, pos: Any, add: Add, graph_outputs: dict[str, int] | None) -> AudioMap | None:
    """Check the ``audio`` mapping ``raw`` (at ``pos``); problems go to ``add(pos, text)``; None if any."""
    if not isinstance(raw, LocDict):
        add(pos, "'audio' must be a mapping with keys rate, block, channels (and optional device)")
        return None
    before = [0]

    def bad(p: Any, text: str) -> None:
        before[0] += 1
        add(p, text)

    for key in raw:
        if key not in AUDIO_KEYS:
            bad(raw.key_pos[key], f"audio: unknown key {key!r}{suggest(str(key), list(AUDIO_KEYS))}")
    rate = raw.get("rate")
    if not _number(rate) or rate < MIN_RATE:
        bad(raw.value_pos.get("rate", raw.pos), f"audio.rate must be a number of Hz >= {MIN_RATE:g} (e.g. 8000 or 48000), got {rate!r}")
    block = raw.get("block", 64)
    if isinstance(block, bool) or not isinstance(block, int) or not 1 <= block <= 65536:
        bad(raw.value_pos.get("block"), f"audio.block must be a whole number of frames per callback (e.g. 64), got {block!r}")
    device = raw.get("device")
    if device is not None and (isinstance(device, bool) or not isinstance(device, (str, int))):
        bad(raw.value_pos.get("device"), f"audio.device must be a device name or index (flowtex live --list-audio), got {device!r}")
    channels = _channels(raw, bad, graph_outputs)
    if before[0]:
        return None
    return AudioMap(rate=float(rate), block=int(block), channels=tuple(channels), device=device)


def _channels(raw: LocDict, bad: Add, graph_outputs: dict[str, int] | None) -> list[AudioChannel]:
    items = raw.get("channels")
    if not isinstance(items, LocList) or not items:
        bad(raw.value_pos.get("channels", raw.pos), "audio.channels must be a list of {output: NAME, scale: S, clip: C}, one per channel")
        return []
    out = []
    for i, entry in enumerate(items):
        pos = items.item_pos[i]
        if not isinstance(entry, LocDict):
            bad(pos, f"audio.channels[{i}]: expected a mapping with output, scale and clip")
            continue
        for key in entry:
            if key not in CHANNEL_KEYS:
                bad(entry.key_pos[key], f"audio.channels[{i}]: unknown key {key!r}{suggest(str(key), list(CHANNEL_KEYS))}")
        name = entry.get("output")
        if not isinstance(name, str):
            bad(entry.value_pos.get("output", pos), f"audio.channels[{i}]: 'output' must name a scalar graph output")
            continue
        if graph_outputs is not None:
            if name not in graph_outputs:
                bad(entry.value_pos["output"], f"audio.channels[{i}]: the graph has no output {name!r}{suggest(name, list(graph_outputs))}")
                continue
            if graph_outputs[name] != 1:
                bad(entry.value_pos["output"], f"audio.channels[{i}]: output {name!r} has {graph_outputs[name]} components; "
                                               "an audio channel plays one scalar output")
                continue
        scale = entry.get("scale", 1.0)
        if not _number(scale) or scale <= 0:
            bad(entry.value_pos.get("scale"), f"audio.channels[{i}]: scale must be a positive number of graph units per full-scale sample, "
                                              f"got {scale!r}")
            continue
        lo_hi = _clip(entry.get("clip"))
        if lo_hi is None:
            bad(entry.value_pos.get("clip", pos), f"audio.channels[{i}]: clip is required: a number C (clip to [-C, C]) or [LOW, HIGH] "
                                                  f"in graph units, got {entry.get('clip')!r}")
            continue
        lo, hi = lo_hi
        if max(abs(lo), abs(hi)) > scale * (1 + 1e-12):
            bad(entry.value_pos["clip"], f"audio.channels[{i}]: clip [{lo:g}, {hi:g}] exceeds full scale +-{scale:g} (scale); "
                                         f"raise scale to {max(abs(lo), abs(hi)):g} or narrow the clip")
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
    from ..errors import DataError, Diagnostic, GraphError, Location
    from ..yamlsource import load_yaml, read_source

    path = Path(path)
    data = load_yaml(read_source(path, "map file"), str(path))
    problems: list[Diagnostic] = []

    def add(pos: Any, text: str) -> None:
        problems.append(Diagnostic(Location(str(path), *(pos or (0, 0))), text))

    if not isinstance(data, LocDict) or "audio" not in data:
        raise DataError(f"{path}: the map has no 'audio' section (rate, block, channels); see docs/live.md, \"Audio output\"")
    amap = parse_audio(data["audio"], data.value_pos["audio"], add, graph_outputs)
    if problems or amap is None:
        raise GraphError(problems)
    return amap
