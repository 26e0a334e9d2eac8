"""Scene files: YAML text -> :class:`Scene`, every problem reported as ``path:line:col: message`` with a fix.

Uses the graph format's YAML loader (positions, duplicate keys, no tags) and
its :class:`~flowtex.graph.spec.Collector`. File paths inside a scene are
relative to the scene file's folder. The format is documented in docs/scenes.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import Diagnostic, GraphError, Location
from ..graph.spec import NAME_RE
from ..limits import excerpt
from ..node_api import suggest
from ..schema.core import INVALID, Collector, Record, check_keys, check_unknown, check_value, value_of
from ..schema.scene import COMPONENT_LIST, COMPONENTS, SCENE, SECTIONS, SURFACE, THRESHOLDS, nonneg
from ..yamlsource import LocDict, LocList, load_yaml, read_source

__all__ = ["COMPONENTS", "Scene", "SurfaceSpec", "load_scene", "parse_scene"]


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
    got = check_value(c, value, pos, nonneg(what, positive=positive))
    return None if got is INVALID else float(got)


def _range(c: Collector, value: Any, pos: Any, what: str, unit: str) -> tuple[float, float] | None:
    from ..schema.scene import TRAJECTORY

    if not (isinstance(value, LocList) and len(value) == 2):
        c.error(pos, TRAJECTORY.keys[what].message)
        return None
    lo = _number(c, value[0], value.item_pos[0], f"trajectory {what} low ({unit})")
    hi = _number(c, value[1], value.item_pos[1], f"trajectory {what} high ({unit})")
    if lo is None or hi is None:
        return None
    if hi < lo:
        c.error(pos, f"trajectory {what}: low {lo:g} exceeds high {hi:g}; write [low, high]")
        return None
    return lo, hi


def _mapping(c: Collector, data: LocDict, key: str) -> LocDict | None:
    raw = data.get(key)
    if raw is None:
        return None
    if not isinstance(raw, LocDict):
        c.error(data.value_pos.get(key), SCENE.keys[key].message)
        return None
    record: Record = SECTIONS[key][0]
    check_unknown(c, raw, record)  # required keys: reported by the section's reader
    return raw


def parse_scene(text: str, path: Path) -> Scene:
    """Check ``text`` (the contents of scene file ``path``) and return the :class:`Scene`."""
    c = Collector(str(path))
    base = path.parent
    data = load_yaml(text, str(path))
    if not isinstance(data, LocDict):
        message = "a scene file must be a mapping with keys flowtex, name, rate, surfaces, trajectory"
        raise GraphError([Diagnostic(Location(str(path), 1, 1), message)])
    check_keys(c, data, SCENE)
    value_of(c, data, SCENE, "flowtex")
    name = value_of(c, data, SCENE, "name") if "name" in data else path.stem
    rate = value_of(c, data, SCENE, "rate") if "rate" in data else 1000.0
    scene = Scene(path=path, name=path.stem if name is INVALID else name, rate=1000.0 if rate is INVALID else float(rate),
                  surfaces={}, description=str(data.get("description", "")))
    scene.surfaces = _surfaces(c, data, base)
    _trajectory(c, data, base, scene)
    th = _mapping(c, data, "thresholds")
    if th is not None:
        for k in th:
            if k in THRESHOLDS.keys:
                v = value_of(c, th, THRESHOLDS, k)
                if v is not INVALID:
                    scene.thresholds[k] = float(v)
    sel = _mapping(c, data, "select")
    if sel is not None:
        from ..schema.scene import SELECT

        if "input" in sel:
            if not isinstance(sel["input"], str) or not NAME_RE.match(sel["input"]):  # the name pattern, as editors check it
                c.error(sel.value_pos["input"], SELECT.keys["input"].message.format(got=excerpt(sel["input"])))
            else:
                scene.select_input = sel["input"]
        if "fade" in sel:
            v = value_of(c, sel, SELECT, "fade")
            scene.fade_s = scene.fade_s if v is INVALID else float(v)
        if "fixed" in sel:
            if sel["fixed"] not in scene.surfaces:
                c.error(sel.value_pos["fixed"], f"select.fixed: no surface {excerpt(sel['fixed'])}{suggest(str(sel['fixed']), list(scene.surfaces))}")
            else:
                scene.fixed = sel["fixed"]
    dev = _mapping(c, data, "device")
    if dev is not None:
        from ..schema.scene import DEVICE

        for k in DEVICE.keys:
            if k not in dev or not isinstance(dev[k], str):
                c.error(dev.value_pos.get(k, dev.pos), DEVICE.keys[k].message)
        scene.dbc = base / dev["dbc"] if isinstance(dev.get("dbc"), str) else None
        scene.map = base / dev["map"] if isinstance(dev.get("map"), str) else None
    c.raise_if_any()
    return scene


def _trajectory(c: Collector, data: LocDict, base: Path, scene: Scene) -> None:
    tr = _mapping(c, data, "trajectory")
    if tr is None:
        if "trajectory" in data and data["trajectory"] is None:
            c.error(data.value_pos["trajectory"], "trajectory is empty: give {speed: [lo, hi], force: [lo, hi]} or {recording: FILE}")
        return
    if "recording" in tr:
        if "speed" in tr or "force" in tr:
            c.error(tr.key_pos["recording"], "trajectory: give either recording or speed and force ranges, not both")
        elif value_of(c, tr, SECTIONS["trajectory"][0], "recording") is not INVALID:
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
        c.error(s.value_pos[key], COMPONENT_LIST.message.format(surface=surface, key=key))
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
        c.error(data.value_pos.get("surfaces"), SCENE.keys["surfaces"].message.format())
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
        check_unknown(c, s, SURFACE, surface=key)
        if not isinstance(s.get("models"), str):
            c.error(s.value_pos.get("models", pos), SURFACE.keys["models"].message.format(surface=key))
            continue
        spec = SurfaceSpec(key=key, models=base / s["models"], loc=c.loc(pos),
                           locs={k: c.loc(s.value_pos[k]) for k in s})
        for k in ("mu", "stiffness"):
            if k in s:
                got = value_of(c, s, SURFACE, k, surface=key)
                setattr(spec, k, None if got is INVALID else float(got))
        if "taps" in s and value_of(c, s, SURFACE, "taps", surface=key) is not INVALID:
            spec.taps = base / s["taps"]
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
    got = check_value(c, value, pos, SURFACE.keys["compliance"], surface=surface)
    if got is INVALID:
        return None
    return base / got if isinstance(got, str) else float(got)
