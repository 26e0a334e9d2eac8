"""The files a sweep's configurations read, and which knob names each: ``bench -o``/``--plot`` must not write over one.

A knob can name another model set, pattern file or plugin table in each configuration (``lookup.models=a.json,b.json``),
so the files the base graph reads are not all a sweep reads. Every configuration is checked (resolved, not compiled)
before anything runs; a scene file is planned once per distinct setting of the plan knobs.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .scenes import is_plan_knob, is_scene_file, write_planned_graph
from .sweep import resolve_config


def files_read_by_configs(graph_path: str | Path, configs: Iterable[dict[str, Any]],
                          plugins: tuple[str | Path, ...] = ()) -> dict[Path, tuple[str, Any] | None]:
    """Every file (resolved) a node of any configuration's graph reads (:func:`flowtex.graph.resolved.files_read`),
    mapped to the first setting of a configuration that names it (``("NODE.PARAM", value)``), or None when the graph
    itself does."""
    from ..graph.resolved import files_read

    found: dict[Path, tuple[str, Any] | None] = {}
    scene = is_scene_file(graph_path)
    with tempfile.TemporaryDirectory(prefix="flowtex-bench-") as tmp:
        planned: dict[tuple, Path] = {}
        for values in configs:
            plan = {k: v for k, v in values.items() if is_plan_knob(k)}
            graph_file = Path(graph_path)
            if scene:
                key = tuple(sorted(plan.items()))
                if key not in planned:
                    planned[key] = write_planned_graph(graph_path, plan, Path(tmp) / f"plan{len(planned)}.yaml", plugins)
                graph_file = planned[key]
            resolved = resolve_config(graph_file, {k: v for k, v in values.items() if k not in plan}, plugins)
            for path in sorted(files_read(resolved)):
                knob = _naming_knob(resolved, values, path)
                if found.get(path) is None:
                    found[path] = knob
    return found


def _naming_knob(resolved: Any, values: dict[str, Any], path: Path) -> tuple[str, Any] | None:
    """``("NODE.PARAM", value)`` of the setting in ``values`` whose path parameter is ``path`` in ``resolved``, or None."""
    for key, value in values.items():
        node, _, param = key.partition(".")
        rn = resolved.nodes.get(node)
        if rn is None or param not in rn.cls.params or rn.cls.params[param].kind != "path":
            continue
        given = rn.params.get(param)
        if isinstance(given, (str, Path)) and Path(given).resolve() == path:
            return key, value
    return None
