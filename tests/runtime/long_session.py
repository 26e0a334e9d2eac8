"""A consistent live session log of any length, written in seconds: the ticks of a short simulated session, repeated.

The graph is stateless (two gains) and only the ticks that received one frame of each sensor are repeated, so each
repeated tick's actuator block is what live would send for its received frames, wherever it is placed: the long log
replays with every tick equal, as a real session of that length would. Used by tests/runtime/test_replay_stream.py
and benchmarks/bench_replay.py, with :func:`~tests.memory.peak_bytes`.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import can
import numpy as np
from test_live import DBC, MAP

from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import SessionWriter, read_session
from flowtex.runtime.live import LiveConfig, run_live
from tests.cli.gain_graph import MAP_GRAPH
from tests.memory import peak_bytes  # noqa: F401  (the replay tests and benchmark take it from here)

AUDIO = "audio:\n  rate: 8000\n  block: 64\n  channels:\n    - {output: vibration, scale: 1.0, clip: 1.0}\n"
"""An audio section for the session's map (:meth:`LongSession.audio_map`)."""
FRAMES_PER_TICK = 4
"""Two sensor frames received and two actuator frames sent a tick."""


class LongSession:
    """The graph, map and repeated ticks of one short simulated session in ``folder`` (``g.yaml``, ``m.yaml``)."""

    def __init__(self, folder: Path, ticks: int = 200):
        self.folder, self.dbc = folder, DBC
        self.graph, self.map = folder / "g.yaml", folder / "m.yaml"
        self.graph.write_text(MAP_GRAPH)
        self.map.write_text(textwrap.dedent(MAP))
        t = np.arange(ticks + 100) / 1000.0
        pos = np.stack([100 * np.sin(2 * np.pi * t), 50 * np.cos(6 * np.pi * t), 10 + 0 * t], axis=1)
        np.savez(folder / "rec.npz", position=pos, normal_force=3 + np.sin(10 * np.pi * t), rate=np.float64(1000))
        r = run_live(load_graph(self.graph), LiveConfig(DBC, self.map, simulate=folder / "rec.npz", max_ticks=ticks,
                                                        record=folder / "short.blf", status=None, seed=3))
        assert r.error is None and r.ticks == ticks
        blocks: list[tuple[list[can.Message], list[can.Message]]] = []
        rx: list[can.Message] = []
        for m in read_session(folder / "short.blf"):
            if m.is_rx:
                rx.append(m)
            elif not blocks or len(blocks[-1][1]) == 2:
                blocks.append((rx, [m]))
                rx = []
            else:
                blocks[-1][1].append(m)
        self.exit_block = blocks.pop()[1]
        self.ticks = [b for b in blocks if sorted(m.arbitration_id for m in b[0]) == [0x100, 0x101]]
        assert len(self.ticks) > ticks // 2  # the simulated device sends both sensors nearly every tick

    def audio_map(self) -> Path:
        """``ma.yaml``: the session's map with an audio section (8 kHz, 64-frame blocks, the vibration played)."""
        path = self.folder / "ma.yaml"
        path.write_text(self.map.read_text() + AUDIO)
        return path

    def write(self, path: Path, ticks: int) -> Path:
        """A log of ``ticks`` ticks and the exit block at ``path`` (.blf, .log or .asc)."""
        w = SessionWriter(path)
        for j in range(ticks):
            rx, block = self.ticks[j % len(self.ticks)]
            for m in rx:
                w.write(m, True)
            for m in block:
                w.write(m, False)
        for m in self.exit_block:
            w.write(m, False)
        w.close()
        return path

