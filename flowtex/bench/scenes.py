"""Scenes as ``flowtex bench`` inputs: the planner's decisions become knobs.

``flowtex bench SCENE.yaml`` plans the scene for every configuration, so the
planner can be swept like any node parameter:

* ``plan=planned,all``: the planner's graph against every component each
  surface has a model for (all thresholds 0, no forced drops) — the cost the
  planner saves and the error it buys;
* ``plan.COMPONENT=auto,keep,drop`` (COMPONENT: texture, friction, taps,
  pattern, stiffness): force one component on or off for every surface that has it;
  ``auto`` leaves it to the planner.

Node knobs (``NODE.PARAM``, ``NODE.every``) then apply to the planned graph
(node names as ``flowtex scene plan`` writes them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import FlowtexError

PLAN_KNOB = "plan"
PLAN_MODES = ("planned", "all")
COMPONENT_MODES = ("auto", "keep", "drop")
COMPONENTS = ("texture", "friction", "taps", "pattern", "stiffness")
GIVEN_COMPONENTS = ("pattern", "stiffness")
"""Kept whenever the scene gives them, unless dropped (no salience threshold)."""
THRESHOLD_COMPONENTS = ("texture", "friction", "taps")


def is_plan_knob(key: str) -> bool:
    """True for ``plan`` and ``plan.COMPONENT`` knob names."""
    return key == PLAN_KNOB or key.startswith(PLAN_KNOB + ".")


def check_plan_knob(key: str, values: list[Any]) -> None:
    """Raise a one-line error for an unknown plan knob or value."""
    if key == PLAN_KNOB:
        allowed: tuple[str, ...] = PLAN_MODES
    else:
        component = key.split(".", 1)[1]
        if component not in COMPONENTS:
            raise FlowtexError(f"--knob {key}: no component {component!r}; use plan.{{{','.join(COMPONENTS)}}}=auto,keep,drop")
        allowed = COMPONENT_MODES
    bad = [v for v in values if v not in allowed]
    if bad:
        raise FlowtexError(f"--knob {key}: unknown value {bad[0]!r}; use {','.join(allowed)}")


def is_scene_file(path: str | Path) -> bool:
    """True if ``path`` is a scene file (a YAML mapping with ``surfaces``) rather than a graph."""
    from ..yamlsource import load_yaml, read_source

    try:
        doc = load_yaml(read_source(Path(path), "graph or scene file"), str(path))
    except FlowtexError:
        return False  # the graph loader reports the problem with its own message
    return isinstance(doc, dict) and "surfaces" in doc and "nodes" not in doc


def apply_plan_settings(scene: Any, settings: dict[str, str]) -> None:
    """Change ``scene`` (a flowtex.scene.file.Scene) in place as the plan knobs ask."""
    if settings.get(PLAN_KNOB, "planned") == "all":
        scene.thresholds = {**scene.thresholds, **{c: 0.0 for c in THRESHOLD_COMPONENTS}}
        for spec in scene.surfaces.values():
            spec.drop = ()
    for key, mode in settings.items():
        if key == PLAN_KNOB or mode == "auto":
            continue
        component = key.split(".", 1)[1]
        for spec in scene.surfaces.values():
            spec.keep = tuple(c for c in spec.keep if c != component)
            spec.drop = tuple(c for c in spec.drop if c != component)
            if component in GIVEN_COMPONENTS:
                if mode == "drop":
                    spec.drop += (component,)
                continue  # kept whenever given, unless dropped
            if mode == "drop":
                spec.drop += (component,)
        if component in THRESHOLD_COMPONENTS and mode == "keep":
            scene.thresholds = {**scene.thresholds, component: 0.0}  # every surface that has the component passes


def write_planned_graph(scene_path: str | Path, settings: dict[str, str], out_path: Path,
                        plugins: tuple[str | Path, ...] = ()) -> Path:
    """Plan ``scene_path`` with the plan knob ``settings`` applied and write the graph (absolute file paths) to ``out_path``."""
    from ..registry import load_registry
    from ..scene.build import write_text_atomic
    from ..scene.file import load_scene
    from ..scene.graphgen import graph_yaml, scene_graph
    from ..scene.plan import PATTERN_NODE, plan_scene

    scene = load_scene(scene_path)
    apply_plan_settings(scene, settings)
    registry = load_registry(plugins)
    plan = plan_scene(scene, frozenset(registry.names()))
    write_text_atomic(out_path, graph_yaml(scene_graph(scene, plan, None, registry.get(PATTERN_NODE))))
    return out_path
