"""Checks a live session makes before it starts: its output files (``--stats``, ``--record``).

A session's statistics and log are written after (or while) the loop runs, so a path that cannot be
written must be refused before the first tick, not found out at exit with the statistics lost.
:func:`preflight_live` applies the one output rule of :mod:`flowtex.io.atomic` (never an input of the
session; missing folders created, a folder that cannot be written refused) to both, and refuses one
file given for both.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..io.atomic import OutputError, check_output
from ..io.canlog import check_log_path


def session_inputs(graph: Any, dbc_path: str | Path, map_path: str | Path, simulate: Any = None) -> list[Path]:
    """The files a live session reads: the graph's YAML (when it has one), the DBC, the map and a ``--simulate`` recording."""
    spec_path = getattr(getattr(graph, "spec", None), "path", None)
    sim = simulate if isinstance(simulate, (str, Path)) else getattr(simulate, "path", None)
    return [Path(p) for p in (spec_path, dbc_path, map_path, sim) if p is not None]


def preflight_live(graph: Any, dbc_path: str | Path, map_path: str | Path, *, simulate: Any = None,
                   record: str | Path | None = None, stats_path: str | Path | None = None,
                   inputs: Sequence[str | Path] = ()) -> tuple[Path | None, Path | None]:
    """Check ``record`` and ``stats_path`` before the session; return them expanded (None stays None).

    ``inputs``: files the session was built from besides graph, DBC, map and recording (e.g. a scene file).

    Raises :class:`~flowtex.io.atomic.OutputError` (one line naming ``--record`` or ``--stats``) for an output that
    is an input of the session, a folder, in a folder that cannot be created or written, or the same file for both;
    :class:`~flowtex.errors.DataError` for a log name whose suffix python-can cannot write.
    """
    inputs = [*session_inputs(graph, dbc_path, map_path, simulate), *(Path(p) for p in inputs)]
    if record is not None:
        check_log_path(record, for_writing=False)  # the suffix; the folder is check_output's
    rec = check_output(record, inputs=inputs, option="--record")
    stats = check_output(stats_path, inputs=[*inputs, *([rec] if rec is not None else [])], option="--stats")
    if rec is not None and stats is not None and rec.resolve() == stats.resolve():
        raise OutputError(f"--stats {stats_path}: the same file as --record; give the statistics their own .json file")
    return rec, stats
