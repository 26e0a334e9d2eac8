"""Scene files: YAML text -> :class:`Scene`, every problem reported as ``path:line:col: message`` with a fix.

Uses the graph format's YAML loader (positions, duplicate keys, no tags) and
its :class:`~flowtex.graph.spec.Collector`. File paths inside a scene are
relative to the scene file's folder. The format is documented in docs/scenes.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import Diagnostic, GraphError, Location
from ..graph.spec import FORMAT_VERSION, NAME_RE, Collector
from ..limits import excerpt
from ..node_api import suggest
from ..yamlsource import LocDict, LocList, load_yaml, read_source

TOP_KEYS = ("flowtex", "name", "rate", "surfaces", "trajectory", "select", "device", "thresholds", "description")
SURFACE_KEYS = ("models", "mu", "taps", "pattern", "compliance", "stiffness", "keep", "drop", "doc")
COMPONENTS = ("texture", "friction", "taps", "pattern", "stiffness")
"""Components a surface may keep or drop; ``stiffness`` is the base-surface spring (``stiffness`` x ``compliance``)."""
THRESHOLD_KEYS = ("texture", "friction", "taps")
TRAJECTORY_KEYS = ("speed", "force", "recording")
SELECT_KEYS = ("input", "fade", "fixed")
DEVICE_KEYS = ("dbc", "map")


@dataclass
class SurfaceSpec:
    """One surface of a scene (paths resolved against the scene file's folder)."""

    key: str
    models: Path
    loc: Location
    mu: float | None = None
    taps: Path | None = None
    pattern: Any = None
    compliance: float | Path | None = None
    """WHaT compliance k_c (0 soft .. 1 stiff), or the flowtex-compliance JSON file holding it (docs/compliance.md)."""
    stiffness: float | None = None
    """Base-surface spring constant, N/mm (scaled by k_c when ``compliance`` is given)."""
    keep: tuple[str, ...] = ()
    drop: tuple[str, ...] = ()
    locs: dict[str, Location] = field(default_factory=dict)
    """Location of each key of the surface's mapping (for errors raised while planning)."""


@dataclass
class Scene:
    """A parsed scene file (docs/scenes.md)."""

    path: Path
    name: str
    rate: float
    surfaces: dict[str, SurfaceSpec]
    speed_range: tuple[float, float] | None = None
    """mm/s; None when the trajectory is a recording (see ``recording``)."""
    force_range: tuple[float, float] | None = None
    """N; None when the trajectory is a recording."""
    recording: Path | None = None
    thresholds: dict[str, float] = field(default_factory=dict)
    """Per-component threshold overrides (units: texture (m/s^2)^2, friction mu, taps Hz)."""
    select_input: str = "surface"
    fade_s: float = 0.01
    fixed: str | None = None
    """Surface key rendered alone (``select: {fixed: KEY}``), else None."""
    dbc: Path | None = None
    map: Path | None = None
    description: str = ""


def load_scene(path: str | Path) -> Scene:
    """Read and check a scene file. Raises :class:`GraphError` listing every problem."""
    path = Path(path)
    return parse_scene(read_source(path, "scene file"), path)


def _number(c: Collector, value: Any, pos: Any, what: str, positive: bool = False) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0 or (positive and value == 0):
        c.error(pos, f"{what} must be a {'positive' if positive else 'non-negative'} number, got {excerpt(value)}")
        return None
    return float(value)


def _range(c: Collector, value: Any, pos: Any, what: str, unit: str) -> tuple[float, float] | None:
    if not (isinstance(value, LocList) and len(value) == 2):
        c.error(pos, f"trajectory {what} must be [low, high] in {unit}, e.g. {what}: [50, 250]" if what == "speed"
                else f"trajectory {what} must be [low, high] in {unit}, e.g. {what}: [0.5, 2.5]")
        return None
    lo = _number(c, value[0], value.item_pos[0], f"trajectory {what} low ({unit})")
    hi = _number(c, value[1], value.item_pos[1], f"trajectory {what} high ({unit})")
    if lo is None or hi is None:
        return None
    if hi < lo:
        c.error(pos, f"trajectory {what}: low {lo:g} exceeds high {hi:g}; write [low, high]")
        return None
    return lo, hi


def _mapping(c: Collector, data: LocDict, key: str, allowed: tuple[str, ...], example: str) -> LocDict | None:
    raw = data.get(key)
    if raw is None:
        return None
    if not isinstance(raw, LocDict):
        c.error(data.value_pos.get(key), f"{key} must be a mapping, e.g. {key}: {example}")
        return None
    for k in raw:
        if k not in allowed:
            c.error(raw.key_pos[k], f"{key}: unknown key {k!r}{suggest(str(k), allowed)}; allowed: {', '.join(allowed)}")
    return raw


def parse_scene(text: str, path: Path) -> Scene:
    """Check ``text`` (the contents of scene file ``path``) and return the :class:`Scene`."""
    c = Collector(str(path))
    base = path.parent
    data = load_yaml(text, str(path))
    if not isinstance(data, LocDict):
        message = "a scene file must be a mapping with keys flowtex, name, rate, surfaces, trajectory"
        raise GraphError([Diagnostic(Location(str(path), 1, 1), message)])
    for key in data:
        if key not in TOP_KEYS:
            c.error(data.key_pos[key], f"unknown top-level key {key!r}{suggest(str(key), TOP_KEYS)}")
    for key in ("flowtex", "surfaces", "trajectory"):
        if key not in data:
            c.error(data.pos, f"missing top-level key {key!r}" + (" (the format version; write 'flowtex: 1')" if key == "flowtex" else ""))
    if "flowtex" in data and data["flowtex"] != FORMAT_VERSION:
        c.error(data.value_pos["flowtex"], f"unsupported format version {excerpt(data['flowtex'])}; this flowtex reads version {FORMAT_VERSION}")
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name:
        c.error(data.value_pos.get("name"), "name must be a non-empty string")
        name = path.stem
    rate = _number(c, data.get("rate", 1000.0), data.value_pos.get("rate"), "rate (Hz)", positive=True) or 1000.0
    scene = Scene(path=path, name=name, rate=rate, surfaces={}, description=str(data.get("description", "")))
    scene.surfaces = _surfaces(c, data, base)
    _trajectory(c, data, base, scene)
    th = _mapping(c, data, "thresholds", THRESHOLD_KEYS, "{texture: 1.0, friction: 0.5, taps: 60}")
    if th is not None:
        for k in th:
            if k in THRESHOLD_KEYS:
                v = _number(c, th[k], th.value_pos[k], f"thresholds.{k}")
                if v is not None:
                    scene.thresholds[k] = v
    sel = _mapping(c, data, "select", SELECT_KEYS, "{input: surface, fade: 0.01}")
    if sel is not None:
        if "input" in sel:
            if not isinstance(sel["input"], str) or not NAME_RE.match(sel["input"]):
                c.error(sel.value_pos["input"], f"select.input must be a graph input name (letters, digits, '_'), got {excerpt(sel['input'])}")
            else:
                scene.select_input = sel["input"]
        if "fade" in sel:
            v = _number(c, sel["fade"], sel.value_pos["fade"], "select.fade (s)")
            scene.fade_s = scene.fade_s if v is None else v
        if "fixed" in sel:
            if sel["fixed"] not in scene.surfaces:
                c.error(sel.value_pos["fixed"], f"select.fixed: no surface {excerpt(sel['fixed'])}{suggest(str(sel['fixed']), list(scene.surfaces))}")
            else:
                scene.fixed = sel["fixed"]
    dev = _mapping(c, data, "device", DEVICE_KEYS, "{dbc: device.dbc, map: map.yaml}")
    if dev is not None:
        for k in DEVICE_KEYS:
            if k not in dev or not isinstance(dev[k], str):
                c.error(dev.value_pos.get(k, dev.pos), f"device.{k} must name a file (device: {{dbc: device.dbc, map: map.yaml}})")
        scene.dbc = base / dev["dbc"] if isinstance(dev.get("dbc"), str) else None
        scene.map = base / dev["map"] if isinstance(dev.get("map"), str) else None
    if c.diagnostics:
        raise GraphError(c.diagnostics)
    return scene


def _trajectory(c: Collector, data: LocDict, base: Path, scene: Scene) -> None:
    tr = _mapping(c, data, "trajectory", TRAJECTORY_KEYS, "{speed: [50, 250], force: [0.5, 2.5]}")
    if tr is None:
        if "trajectory" in data and data["trajectory"] is None:
            c.error(data.value_pos["trajectory"], "trajectory is empty: give {speed: [lo, hi], force: [lo, hi]} or {recording: FILE}")
        return
    if "recording" in tr:
        if "speed" in tr or "force" in tr:
            c.error(tr.key_pos["recording"], "trajectory: give either recording or speed and force ranges, not both")
        elif not isinstance(tr["recording"], str):
            c.error(tr.value_pos["recording"], "trajectory.recording must name a recording file (.npz, .csv, .h5)")
        else:
            scene.recording = base / tr["recording"]
        return
    for k in ("speed", "force"):
        if k not in tr:
            c.error(tr.pos, f"trajectory: missing {k} range [low, high]" + (" in mm/s" if k == "speed" else " in N"))
    if "speed" in tr:
        scene.speed_range = _range(c, tr["speed"], tr.value_pos["speed"], "speed", "mm/s")
    if "force" in tr:
        scene.force_range = _range(c, tr["force"], tr.value_pos["force"], "force", "N")


def _components(c: Collector, s: LocDict, key: str, surface: str) -> tuple[str, ...]:
    raw = s.get(key)
    if raw is None:
        return ()
    items = [raw] if isinstance(raw, str) else raw
    if not isinstance(items, list):
        c.error(s.value_pos[key], f"surface {surface!r}: {key} must be a list of components from {', '.join(COMPONENTS)}")
        return ()
    out = []
    for i, item in enumerate(items):
        pos = items.item_pos[i] if isinstance(items, LocList) else s.value_pos[key]
        if item not in COMPONENTS:
            c.error(pos, f"surface {surface!r}: unknown component {excerpt(item)} in {key}{suggest(str(item), COMPONENTS)}; "
                         f"components: {', '.join(COMPONENTS)}")
        else:
            out.append(item)
    return tuple(out)


def _surfaces(c: Collector, data: LocDict, base: Path) -> dict[str, SurfaceSpec]:
    raw = data.get("surfaces")
    if raw is None:
        return {}
    if not isinstance(raw, LocDict) or not raw:
        c.error(data.value_pos.get("surfaces"), "surfaces must be a non-empty mapping of name: {models: FILE, ...}")
        return {}
    out: dict[str, SurfaceSpec] = {}
    for key, s in raw.items():
        pos = raw.key_pos[key]
        if not isinstance(key, str) or not NAME_RE.match(key):
            c.error(pos, f"surface name {key!r} is not valid: use letters, digits and '_', not starting with a digit (it names graph nodes)")
            continue
        if not isinstance(s, LocDict):
            c.error(raw.value_pos[key], f"surface {key!r}: expected a mapping with at least 'models' (a HaTT XML or native model set)")
            continue
        for k in s:
            if k not in SURFACE_KEYS:
                c.error(s.key_pos[k], f"surface {key!r}: unknown key {k!r}{suggest(str(k), SURFACE_KEYS)}")
        if not isinstance(s.get("models"), str):
            c.error(s.value_pos.get("models", pos), f"surface {key!r}: 'models' must name a texture model set file (HaTT XML or flowtex JSON)")
            continue
        spec = SurfaceSpec(key=key, models=base / s["models"], loc=c.loc(pos),
                           locs={k: c.loc(s.value_pos[k]) for k in s})
        if "mu" in s:
            spec.mu = _number(c, s["mu"], s.value_pos["mu"], f"surface {key!r}: mu (kinetic friction coefficient)")
        if "taps" in s:
            if not isinstance(s["taps"], str):
                c.error(s.value_pos["taps"], f"surface {key!r}: 'taps' must name a tap library file (docs/tap-library.md)")
            else:
                spec.taps = base / s["taps"]
        if "stiffness" in s:
            spec.stiffness = _number(c, s["stiffness"], s.value_pos["stiffness"], f"surface {key!r}: stiffness (N/mm)", positive=True)
        spec.pattern = s.get("pattern")
        if "compliance" in s:
            spec.compliance = _compliance(c, s["compliance"], s.value_pos["compliance"], key, base)
        spec.keep = _components(c, s, "keep", key)
        spec.drop = _components(c, s, "drop", key)
        both = set(spec.keep) & set(spec.drop)
        if both:
            c.error(s.key_pos["drop"], f"surface {key!r}: {', '.join(sorted(both))} is both kept and dropped; remove it from one list")
        out[key] = spec
    return out


def _compliance(c: Collector, value: Any, pos: Any, surface: str, base: Path) -> float | Path | None:
    """``compliance:`` is k_c (a number in [0, 1]) or the JSON file 'flowtex fit compliance' wrote."""
    if isinstance(value, str):
        return base / value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not 0.0 <= value <= 1.0:
        c.error(pos, f"surface {surface!r}: compliance must be k_c between 0 (soft) and 1 (stiff), or the JSON file "
                     f"'flowtex fit compliance' writes; got {excerpt(value)}")
        return None
    return float(value)
