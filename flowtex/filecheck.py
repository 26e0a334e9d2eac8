"""What kind of flowtex file is this, and is it good? ``flowtex validate FILE`` for every kind, decided by content.

Kinds: graph, scene and device map (YAML; a map has ``flowtex_map:``, a scene ``surfaces:``, anything else is read as a
graph), texture model set (native JSON or HaTT XML), pattern file, tap library, friction and compliance estimates
(JSON, by their ``format`` key), DBC files, recordings (.npz/.csv/.h5) and CAN session logs (.blf/.log/.asc); the kind comes from the format registry
(:mod:`flowtex.io.formats`). Each is checked by the same reader the
verbs use, so a file that passes here loads there. Layer: beside flowtex.scene and flowtex.bench, below flowtex.cli.
Graphs are checked by flowtex.graph.compiled.check_graph (the command line adds its plugin report).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import DataError, FlowtexError
from .io.formats import (
    CAN_LOG,
    COMPLIANCE,
    DBC,
    DEVICE_MAP,
    FRICTION,
    GRAPH,
    JSON_FORMATS,
    MODEL_SET,
    PATTERN,
    RECORDING,
    SCENE,
    TAP_LIBRARY,
    file_kind,
)

if TYPE_CHECKING:
    from .io.canmap import CanMap
    from .node_decl import PortSpec

__all__ = ["CAN_LOG", "COMPLIANCE", "DBC", "DEVICE_MAP", "FRICTION", "GRAPH", "JSON_FORMATS", "MODEL_SET", "PATTERN", "RECORDING", "SCENE",
           "TAP_LIBRARY", "check_file", "check_map_for_graph", "file_kind"]
"""The kinds and :func:`file_kind` live in the one format registry, :mod:`flowtex.io.formats`."""


def check_file(path: str | Path, kind: str, dbc: str | Path | None = None, plugins: tuple[str | Path, ...] = (),
               auto_plugins: bool = True) -> str:
    """Check the file at ``path`` of ``kind`` (not a graph) with the reader the verbs use; returns ``PATH: ok (...)``.

    A device map is checked against ``dbc`` (required for it); a scene is planned (its model, tap, pattern and
    compliance files read) with the node types of ``plugins``.
    """
    path = Path(path)
    detail = _CHECKS[kind](path, dbc, plugins, auto_plugins)
    return f"{path}: ok ({kind}{', ' + detail if detail else ''})"


def _model_set(path: Path, *_: object) -> str:
    from .io.modelset import load_model_set

    ms = load_model_set(path)
    return f"{ms.num_models} models at {ms.sample_rate:g} Hz, orders {ms.ar_order}/{ms.ma_order}"


def _pattern(path: Path, *_: object) -> str:
    from .io.patternfile import read_pattern

    pat = read_pattern(path)
    return f"{len(pat.positions_mm)} features at {pat.sample_rate_hz:g} Hz"


def _taps(path: Path, *_: object) -> str:
    from .io.taplib import read_tap_library

    lib = read_tap_library(path)
    return f"{lib.speeds.size} taps at {lib.sample_rate_hz:g} Hz"


def _number(doc: dict, key: str, path: Path, low: float, high: float, optional: bool = False) -> float | None:
    value = doc.get(key)
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (math.isfinite(value) and low <= value <= high):
        raise DataError(f"{path}: key {key!r} must be a number from {low:g} to {high:g}, got {repr(value)[:40]}")
    return float(value)


def _friction(path: Path, *_: object) -> str:
    from .io.jsondoc import read_json_document
    from .schema.core import INVALID, Collector, check_keys, value_of
    from .schema.datafiles import FRICTION as DECLARED

    doc = read_json_document(path, FRICTION, "flowtex-friction", (1,))
    c = Collector(str(path))
    if check_keys(c, doc, DECLARED):
        mu = value_of(c, doc, DECLARED, "mu")
        value_of(c, doc, DECLARED, "mu_ci")
    c.raise_first_as_data_error()
    assert mu is not INVALID
    return f"mu {mu:.4g}"


def _compliance(path: Path, *_: object) -> str:
    from .io.jsondoc import read_json_document

    doc = read_json_document(path, COMPLIANCE, "flowtex-compliance", (1,))
    kc = _number(doc, "k_c", path, 0.0, 1.0, optional=True)
    if not isinstance(doc.get("valid"), bool):
        raise DataError(f"{path}: key 'valid' must be true or false")
    if doc["valid"] and kc is None:
        raise DataError(f"{path}: 'valid' is true but 'k_c' is missing")
    return f"k_c {kc:.4g}" if kc is not None and doc["valid"] else f"not valid: {str(doc.get('reason'))[:60]}"


def _dbc(path: Path, *_: object) -> str:
    from .io.dbc import load_dbc

    return f"{len(load_dbc(path).messages)} messages"


def _device_map(path: Path, dbc: str | Path | None, *_: object) -> str:
    if dbc is None:
        raise FlowtexError(f"{path}: a device map is checked against its device: give --dbc DEVICE.dbc")
    from .io.canmap import load_map
    from .io.dbc import load_dbc

    return _map_summary(load_map(path, load_dbc(dbc), dbc), dbc)


def _map_summary(m: CanMap, dbc: str | Path) -> str:
    from .io.mapsafety import moved_bounds

    moved = [text for b in m.outputs.values() if (text := moved_bounds(b)) is not None]
    onto = f"; moved onto the DBC's LSB grid: {'; '.join(moved)}" if moved else ""
    return f"{len(m.inputs)} inputs, {len(m.outputs)} outputs on {Path(dbc).name}{onto}"


def check_map_for_graph(path: str | Path, dbc: str | Path, inputs: Mapping[str, PortSpec],
                        outputs: Mapping[str, PortSpec]) -> tuple[str, list[str]]:
    """Check the device map at ``path`` against ``dbc`` and a graph's ports (name -> PortSpec) as ``flowtex live`` loads
    it (:func:`~flowtex.io.canmap.map_for_ports`: names, widths, units); returns ``PATH: ok (...)`` and the map's
    warning lines (:attr:`~flowtex.io.canmap.CanMap.warnings`)."""
    from .io.canmap import map_for_ports
    from .io.dbc import load_dbc

    m = map_for_ports(path, load_dbc(dbc), dbc, inputs, outputs)
    return f"{path}: ok ({DEVICE_MAP}, {_map_summary(m, dbc)})", m.warnings


def _scene(path: Path, _dbc: object, plugins: tuple[str | Path, ...], _auto_plugins: bool) -> str:
    from .registry import load_registry
    from .scene.file import load_scene
    from .scene.plan import plan_scene

    scene = load_scene(path)
    plan = plan_scene(scene, frozenset(load_registry(plugins).names()))
    kept = sum(d.keep for data in plan.values() for d in data.decisions.values())
    total = sum(len(data.decisions) for data in plan.values())
    return f"{len(plan)} surfaces, {kept} of {total} components kept"


def _recording(path: Path, *_: object) -> str:
    from .io.recordings import load_recording

    rec = load_recording(path)
    rate = f" at {rec.rate:g} Hz" if rec.rate is not None else " (no rate stated)"
    return f"{len(rec.arrays)} signals, {rec.samples} samples{rate}"


def _can_log(path: Path, *_: object) -> str:
    from .io.canlog import SessionFrames

    session = SessionFrames(path)  # streamed: a log of any length is checked in bounded memory
    received = sum(1 for m in session if m.is_rx)
    problem = session.completeness.problem if session.completeness is not None else None
    cut = f"; {problem}" if problem else ""
    return f"{session.number} frames, {received} received and {session.number - received} sent{cut}"


_CHECKS = {CAN_LOG: _can_log, MODEL_SET: _model_set, PATTERN: _pattern, TAP_LIBRARY: _taps, FRICTION: _friction, COMPLIANCE: _compliance,
           DBC: _dbc, DEVICE_MAP: _device_map, SCENE: _scene, RECORDING: _recording}
