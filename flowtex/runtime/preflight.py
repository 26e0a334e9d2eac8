"""Checks a live session makes before it starts: its output files (``--stats``, ``--record``, ``--record-audio``).

A session's statistics and logs are written after (or while) the loop runs, so a path that cannot be
written must be refused before the first tick, not found out at exit with the statistics lost.
:func:`preflight_live` applies the one output rule of :mod:`flowtex.io.atomic` (never an input of the
session; missing folders created, a folder that cannot be written refused) to each, and refuses one
file given for two of them. The option values themselves are checked when the
:class:`~flowtex.runtime.liveconfig.LiveConfig` is made.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

from ..graph.program import TickProgram
from ..io.atomic import OutputError, check_output
from ..io.canlog import check_log_path
from .liveconfig import LiveConfig


def session_inputs(graph: TickProgram, dbc_path: str | Path, map_path: str | Path, simulate: Any = None) -> list[Path]:
    """The files a live session reads: the graph's YAML (when it has one), the DBC, the map and a ``--simulate`` recording."""
    spec_path = graph.spec.path
    sim = simulate if isinstance(simulate, (str, Path)) else getattr(simulate, "path", None)
    return [Path(p) for p in (spec_path, dbc_path, map_path, sim) if p is not None]


class SessionOutputs(NamedTuple):
    """A session's output paths, expanded (None: not asked for)."""

    record: Path | None
    stats: Path | None
    record_audio: Path | None


def preflight_live(graph: TickProgram, config: LiveConfig) -> SessionOutputs:
    """Check ``config.record``, ``config.stats_path`` and ``config.record_audio`` before the session; return them expanded.

    ``config.inputs``: files the session was built from besides graph, DBC, map and recording (e.g. a scene file).

    Raises :class:`~flowtex.io.atomic.OutputError` (one line naming ``--record``, ``--stats`` or ``--record-audio``) for
    an output that is an input of the session, a folder, in a folder that cannot be created or written, or the same file
    as another output; :class:`~flowtex.errors.DataError` for a log name whose suffix python-can cannot write.
    """
    inputs = [*session_inputs(graph, config.dbc_path, config.map_path, config.simulate), *(Path(p) for p in config.inputs)]
    record, stats_path = config.record, config.stats_path
    if record is not None:
        check_log_path(record, for_writing=False)  # the suffix; the folder is check_output's
    rec = check_output(record, inputs=inputs, option="--record")
    stats = check_output(stats_path, inputs=[*inputs, *([rec] if rec is not None else [])], option="--stats")
    if rec is not None and stats is not None and rec.resolve() == stats.resolve():
        raise OutputError(f"--stats {stats_path}: the same file as --record; give the statistics their own .json file")
    audio = check_output(config.record_audio, inputs=[*inputs, *(p for p in (rec, stats) if p is not None)],
                         option="--record-audio", suffixes=(".wav",))
    return SessionOutputs(rec, stats, audio)
