"""``flowtex watch``: rerun a graph over a recording whenever the graph, its model files or its plugins change.

The loop polls modification times (and sizes) of every file the last run
depended on -- the graph file, the files its ``path`` parameters name (model
sets, tap libraries, ...), the plugin files loaded for it, and the recording --
every ``interval`` seconds. On a change it rebuilds and reruns in this process:

* the graph is built at the ``auto`` tier by default: a structure whose fused
  code is cached runs fused; a new structure runs on the dispatch tier at once
  while the fused code compiles in a background process at nice 19
  (:mod:`flowtex.compile.service`), so the next run finds it without the
  foreground ever waiting for a compile;
* edited plugin files are imported afresh (:func:`flowtex.registry.forget_plugin_code`);
* a run that fails (a typo mid-edit) prints its error and the loop keeps watching.

Each run reports one line per output (RMS, peak, non-finite count, and the
previous run's RMS) and the files that changed since the last run.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import FlowtexError
from ..graph.resolved import files_read
from ..io.atomic import check_not_input

Signature = dict[Path, tuple[int, int] | None]


@dataclass
class WatchResult:
    """What one run gave: per output (RMS, peak, non-finite count), or the error."""

    stats: dict[str, tuple[float, float, int]] = field(default_factory=dict)
    error: str = ""
    units: dict[str, str] = field(default_factory=dict)
    """Each output's unit (the graph's declaration; '' when dimensionless), shown with its name."""


def output_stats(values: np.ndarray) -> tuple[float, float, int]:
    """RMS and peak |value| over the finite values (all components), and the number of non-finite values."""
    flat = np.asarray(values, dtype=np.float64).ravel()
    finite = flat[np.isfinite(flat)]
    rms = float(np.sqrt(np.mean(finite * finite))) if finite.size else float("nan")
    peak = float(np.max(np.abs(finite))) if finite.size else float("nan")
    return rms, peak, int(flat.size - finite.size)


def stat_lines(result: WatchResult, previous: WatchResult | None) -> list[str]:
    """``  y [N]: RMS 0.5 (was 0.25), peak 1, non-finite 0`` per output (values in the output's unit)."""
    lines = []
    for name, (rms, peak, bad) in result.stats.items():
        was = ""
        if previous is not None and name in previous.stats:
            was = f" (was {previous.stats[name][0]:.6g})"
        elif previous is not None and previous.stats:
            was = " (new output)"
        unit = result.units.get(name, "")
        shown = f"{name} [{unit}]" if unit else name
        lines.append(f"  {shown}: RMS {rms:.6g}{was}, peak {peak:.6g}, non-finite {bad}")
    return lines


def file_signature(paths: set[Path]) -> Signature:
    """(mtime in ns, size) of each file, None for a missing one."""
    out: Signature = {}
    for path in paths:
        try:
            st = path.stat()
            out[path] = (st.st_mtime_ns, st.st_size)
        except OSError:
            out[path] = None
    return out


def dependencies(graph: Any) -> set[Path]:
    """Files a built graph depends on: path parameters of its nodes (the graph file and plugins are added by the caller)."""
    return files_read(graph.resolved)


@dataclass
class Watcher:
    """One watch session; :meth:`run_once` builds and runs, :meth:`loop` polls and reruns."""

    graph_path: Path
    input_path: Path
    output_path: Path | None
    emit: Callable[[str], None]
    overrides: Mapping[str, Any] = field(default_factory=dict)
    plugins: tuple[str | Path, ...] = ()
    auto_plugins: bool = True
    tier: str = "auto"
    plot: Callable[[dict[str, np.ndarray], Any, int], None] | None = None
    """Called after each good run with (outputs, graph, run number), e.g. to refresh a PNG (``watch --plot``)."""
    plot_path: Path | None = None
    """The file ``plot`` writes (``watch --plot``): refused, as the output is, when the graph reads it."""
    watched: set[Path] = field(default_factory=set)
    plugin_files: list[Path] = field(default_factory=list)
    last: WatchResult | None = None
    """The last good run's result (the report compares each run's RMS with it)."""
    latest: WatchResult | None = None
    """The latest run's result, failed or not (``watch --max-runs`` exits 1 when it failed)."""
    runs: int = 0

    def run_once(self, changed: list[Path]) -> WatchResult:
        """Build and run the graph; report; remember which files to watch (the ones this run read)."""
        from ..graph.compiled import graph_registry, load_graph
        from ..registry import forget_plugin_code
        from .offline import run_recording

        self.runs += 1
        what = "start" if not changed else "changed: " + ", ".join(_shown(p) for p in changed)
        started = time.perf_counter()
        watched = {self.graph_path.resolve(), self.input_path.resolve()}
        result = WatchResult()
        try:
            if any(p.suffix == ".py" for p in changed):
                forget_plugin_code()
            graph = load_graph(self.graph_path, dict(self.overrides), self.plugins, auto_plugins=self.auto_plugins, tier=self.tier)
            read = dependencies(graph)
            watched |= read
            for option, written in (("-o", self.output_path), ("--plot", self.plot_path)):  # each run: an edit may name it
                check_not_input(written, read, option, what="a file the graph reads")
            plugin_files = list(graph_registry(self.graph_path, self.plugins, self.auto_plugins).plugin_files)
            watched |= {Path(p).resolve() for p in plugin_files}
            if plugin_files != self.plugin_files:
                self.plugin_files = plugin_files
                self.emit(f"loaded plugin code: {', '.join(map(str, plugin_files)) or 'none'}")
            outputs = run_recording(graph, self.input_path, self.output_path, progress=False)
            result.stats = {name: output_stats(values) for name, values in outputs.items()}
            result.units = {name: spec.unit for name, spec in graph.outputs.items()}
            tier = graph.tier
            if self.plot is not None:
                self.plot(outputs, graph, self.runs)
        except FlowtexError as exc:
            result.error = str(exc)
            tier = "-"
            watched |= self.watched  # keep watching what the last good run read (e.g. a plugin being fixed)
        elapsed = time.perf_counter() - started
        self.watched = watched
        if result.error:
            self.emit(f"run {self.runs} ({what}): failed after {elapsed:.2f} s")
            for line in result.error.splitlines():
                self.emit(f"  {line}")
        else:
            target = f" -> {self.output_path}" if self.output_path else ""
            self.emit(f"run {self.runs} ({what}): {elapsed:.2f} s on the {tier} tier{target}")
            for line in stat_lines(result, self.last if self.last and not self.last.error else None):
                self.emit(line)
            self.last = result
        self.latest = result
        return result

    def loop(self, interval: float, max_runs: int | None = None) -> int:
        """Run, then poll every ``interval`` s and rerun on a change, until ``max_runs`` runs (or Ctrl-C); returns runs.

        Signatures are taken *before* each run, so an edit saved while a run is going on triggers the next one.
        """
        signature = file_signature(self._paths())
        self.run_once([])
        signature = {**file_signature(self._paths()), **signature}  # files the run revealed, as they are now
        while max_runs is None or self.runs < max_runs:
            time.sleep(interval)
            now = file_signature(set(signature))
            changed = sorted(p for p in signature if signature[p] != now[p])
            if changed:
                signature = now
                self.run_once(changed)
                signature = {**file_signature(self._paths()), **signature}
        return self.runs

    def _paths(self) -> set[Path]:
        return self.watched or {self.graph_path.resolve(), self.input_path.resolve()}


def _shown(path: Path) -> str:
    from ..nodecheck import shown_path

    return shown_path(path)
