"""Write the planned scene as a normal flowtex graph (YAML) containing only the kept components.

Structure (as graphs/surface_render.yaml, one branch per surface):

* shared: ``speed`` (speed_estimator, HaTT's method) and ``contact``;
* per surface ``K`` and kept component: ``K_lookup`` -> ``K_synth`` (texture),
  ``K_pattern`` (pattern), ``K_friction`` (dahl_friction), ``K_taps`` (tap_player),
  ``K_spring`` (stiffness: a gain in N/mm on the clipped ``penetration`` input, mm);
* per signal (vibration, friction force, tap force) a chain of
  ``surface_switch`` nodes choosing surface ``index`` from the graph input
  named by ``select.input`` (default ``surface``); a surface without the
  component feeds a zero constant. All surfaces' nodes run every tick, so the
  chosen one's state is always current (no stale friction, no start-up burst);
* outputs ``force`` (sum), ``texture_force``, ``friction_force``, ``tap_force``,
  ``spring_force``, ``vibration`` and ``in_contact`` -- those whose component any surface keeps.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml

from ..dsp.contact import CONTACT_OFF_N, CONTACT_ON_N
from ..errors import FlowtexError
from .file import Scene
from .plan import PATTERN_NODE, SurfaceData

PATTERN_SOURCES = {"position": "position", "normal_force": "normal_force", "force": "normal_force", "normal": "normal",
                   "speed": "speed.speed", "velocity": "speed.velocity", "in_contact": "contact.in_contact"}
"""Graph signals a ``patterned_texture`` node's inputs are wired to, by input name."""


def _path(path: Path, base: Path | None) -> str:
    full = Path(os.path.abspath(path))
    if base is None:
        return str(full)
    return os.path.relpath(full, os.path.abspath(base))


class _Builder:
    def __init__(self) -> None:
        self.nodes: dict[str, dict[str, Any]] = {}
        self.edges: list[str] = []

    def node(self, name: str, type_: str, **params: Any) -> str:
        self.nodes[name] = {"type": type_, "params": params} if params else {"type": type_}
        return name

    def edge(self, src: str, dst: str) -> None:
        self.edges.append(f"{src} -> {dst}")

    def zero(self, name: str, value: list[float], unit: str) -> str:
        """Output of a shared zero constant (created once): what a surface without a component feeds its switch."""
        if name not in self.nodes:
            self.node(name, "constant", value=value, unit=unit)
        return f"{name}.y"

    def unit_normal(self) -> str:
        """Output of the shared ``unit_normal`` node (the ``normal`` input normalised; created once)."""
        if "unit_normal" not in self.nodes:
            self.node("unit_normal", "normalize")
            self.edge("normal", "unit_normal.x")
        return "unit_normal.y"

    def along_normal(self, name: str, scalar: str) -> str:
        """Output of a node ``name`` giving the force ``scalar`` (N) as a 3-vector along the unit normal."""
        self.node(name, "multiply")
        self.edge(self.unit_normal(), f"{name}.a")
        self.edge(scalar, f"{name}.b")
        return f"{name}.y"

    def select(self, signal: str, sources: list[str], index: str | None, fade: float) -> str:
        """Chain surface_switch nodes over ``sources`` (one per surface, file order); returns the chosen signal."""
        out = sources[0]
        for i, src in enumerate(sources[1:], start=1):
            name = self.node(f"{signal}_switch{i}", "surface_switch", b_index=i, fade=fade)
            self.edge(str(index), f"{name}.index")
            self.edge(out, f"{name}.a")
            self.edge(src, f"{name}.b")
            out = f"{name}.y"
        return out


def scene_graph(scene: Scene, plan: dict[str, SurfaceData], base: Path | None, pattern_cls: Any = None) -> dict[str, Any]:
    """The graph document (a dict ready for YAML). Paths are relative to ``base`` (None: absolute).

    ``pattern_cls`` is the registered ``patterned_texture`` node class, needed
    only when a pattern is kept (its ports say how to wire it).
    """
    keys = [scene.fixed] if scene.fixed else list(plan)
    index = scene.select_input if len(keys) > 1 else None
    b = _Builder()
    b.node("speed", "speed_estimator", method="hatt")
    b.node("contact", "contact", on_n=CONTACT_ON_N, off_n=CONTACT_OFF_N)
    b.edge("position", "speed.position")
    b.edge("normal", "speed.normal")
    b.edge("normal_force", "contact.normal_force")
    b.edge("position", "contact.position")
    b.edge("normal", "contact.normal")

    def kept(key: str, comp: str) -> bool:
        d = plan[key].decisions.get(comp)
        return bool(d and d.keep)

    outputs: dict[str, str] = {}
    forces: list[str] = []
    # --- texture (and pattern) vibration
    if any(kept(k, "texture") or kept(k, "pattern") for k in keys):
        sources = []
        for k in keys:
            parts = []
            if kept(k, "texture"):
                models = _path(plan[k].spec.models, base)
                b.node(f"{k}_lookup", "texture_lookup", models=models)
                b.node(f"{k}_synth", "arma_synth")
                b.edge("speed.speed", f"{k}_lookup.speed")
                b.edge("normal_force", f"{k}_lookup.force")
                for port in ("ar", "ma", "gain", "variance"):
                    b.edge(f"{k}_lookup.{port}", f"{k}_synth.{port}")
                parts.append(f"{k}_synth.y")
            if kept(k, "pattern"):
                parts.append(_pattern(b, k, plan[k].spec.pattern, pattern_cls))
            if len(parts) == 2:
                b.node(f"{k}_vibration", "add")
                b.edge(parts[0], f"{k}_vibration.a")
                b.edge(parts[1], f"{k}_vibration.b")
                parts = [f"{k}_vibration.y"]
            if not parts:
                parts = [b.zero("zero_vibration", [0.0], "m/s^2")]
            sources.append(parts[0])
        vib = b.select("vibration", sources, index, scene.fade_s)
        b.node("mute", "multiply")
        b.edge(vib, "mute.a")
        b.edge("contact.in_contact", "mute.b")
        b.node("direction", "normalize", min_norm=1.0e-6)
        b.node("unit_normal", "normalize")
        b.node("across", "cross")
        b.node("along", "multiply")
        b.node("texture", "gain", k=0.05, unit="N")
        for src, dst in (("speed.velocity", "direction.x"), ("normal", "unit_normal.x"), ("direction.y", "across.a"),
                         ("unit_normal.y", "across.b"), ("across.y", "along.a"), ("mute.y", "along.b"), ("along.y", "texture.x")):
            b.edge(src, dst)
        outputs["texture_force"] = "texture.y"
        outputs["vibration"] = "mute.y"
        forces.append("texture.y")
    # --- friction
    if any(kept(k, "friction") for k in keys):
        sources = []
        for k in keys:
            if kept(k, "friction"):
                b.node(f"{k}_friction", "dahl_friction", mu=float(plan[k].mu))
                b.edge("position", f"{k}_friction.position")
                b.edge("normal_force", f"{k}_friction.normal_force")
                b.edge("normal", f"{k}_friction.normal")
                sources.append(f"{k}_friction.force")
            else:
                sources.append(b.zero("zero_friction", [0.0, 0.0, 0.0], "N"))
        outputs["friction_force"] = b.select("friction", sources, index, scene.fade_s)
        forces.append(outputs["friction_force"])
    # --- taps
    if any(kept(k, "taps") for k in keys):
        sources = []
        for k in keys:
            if kept(k, "taps"):
                b.node(f"{k}_taps", "tap_player", library=_path(plan[k].spec.taps, base), mass=0.05)
                b.edge("contact.in_contact", f"{k}_taps.in_contact")
                b.edge("contact.incoming_speed", f"{k}_taps.incoming_speed")
                sources.append(f"{k}_taps.force")
            else:
                sources.append(b.zero("zero_tap", [0.0], "N"))
        tap = b.select("tap", sources, index, 0.0)  # a tap is a short transient: switch it on the tick
        outputs["tap_force"] = tap
        forces.append(b.along_normal("tap_vector", tap))
    # --- base surface: Hooke spring on the penetration depth, along the unit normal
    if any(kept(k, "stiffness") for k in keys):
        b.node("depth", "clip", low=0.0, high=1000.0)  # mm: not in contact (< 0) pushes nothing; NaN counts as 0
        b.edge("penetration", "depth.x")
        sources = []
        for k in keys:
            if kept(k, "stiffness"):
                b.node(f"{k}_spring", "gain", k=float(plan[k].stiffness), unit="N")  # N/mm x mm
                b.edge("depth.y", f"{k}_spring.x")
                sources.append(f"{k}_spring.y")
            else:
                sources.append(b.zero("zero_spring", [0.0], "N"))
        spring = b.select("spring", sources, index, scene.fade_s)
        outputs["spring_force"] = spring
        forces.append(b.along_normal("spring_vector", spring))
    if not forces:
        raise FlowtexError(f"{scene.path}: the plan keeps no component on any surface; nothing to render (force one with keep:)")
    total = forces[0]
    for i, f in enumerate(forces[1:], start=1):
        name = b.node(f"sum{i}", "add")
        b.edge(total, f"{name}.a")
        b.edge(f, f"{name}.b")
        total = f"{name}.y"
    outputs = {"force": total, **outputs, "in_contact": "contact.in_contact"}
    inputs: dict[str, Any] = {"position": {"shape": [3], "unit": "mm"}, "normal_force": {"unit": "N"}, "normal": {"shape": [3]}}
    if "depth" in b.nodes:
        inputs["penetration"] = {"unit": "mm"}
    if index is not None:
        inputs[index] = {}
    return {"flowtex": 1, "name": scene.name, "rate": scene.rate, "seed": 1,
            "description": f"planned by 'flowtex scene plan' from {scene.path.name}; surfaces: {', '.join(keys)}",
            "inputs": inputs, "nodes": b.nodes, "edges": b.edges, "outputs": outputs}


def _pattern(b: _Builder, key: str, pattern: Any, cls: Any) -> str:
    name = b.node(f"{key}_pattern", PATTERN_NODE, pattern=pattern)
    for port, spec in cls.inputs.items():
        src = PATTERN_SOURCES.get(port)
        if src is None:
            if not spec.optional:
                raise FlowtexError(f"cannot wire input {port!r} of {PATTERN_NODE}: the planner knows {', '.join(PATTERN_SOURCES)}")
            continue
        b.edge(src, f"{name}.{port}")
    return f"{name}.{'y' if 'y' in cls.outputs else next(iter(cls.outputs))}"


def graph_yaml(doc: dict[str, Any]) -> str:
    """YAML text of a graph document (keys in the order given)."""
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=150)
