"""Which components each surface of a scene needs: salience figure, threshold, keep or drop, and why.

Thresholds and their sources (Culbertson & Kuchenbecker, Culbertson & Kuchenbecker 2017, sec. 5-6;
; docs/scenes.md):

* texture: mean vibration power over the trajectory's 9 x 9 speed/force grid,
  kept at >= 1 (m/s^2)^2. Removing texture made no significant difference for
  Cork, Silk 1, Tarp and Whiteboard (HaTT powers 0.25-0.44 for Whiteboard and
  Silk 1) and hurt for MDF (1.19) and every rougher surface.
* friction: kinetic friction coefficient mu_k, kept at >= 0.5. The five
  surfaces rated *better* without rendered friction have mu_k <= 0.41
  (Whiteboard 0.17, MDF 0.19, ABS 0.21, Silk 1 0.28, Tarp 0.41); the only
  surface that needed it is EPDM Foam (1.39).
* taps: mean tap spectral centroid at 50-100 mm/s, kept at >= 60 Hz. Carpet 3
  (47.8 Hz, the lowest of the 15) was the only surface felt too hard with
  taps; surfaces that needed taps (ABS, Brick 1, MDF, Paper Plate 2,
  Whiteboard) are hard ones.
* pattern: no study measured it; a pattern given in the scene is kept (unless
  dropped) when the ``patterned_texture`` node type is available.
* stiffness: the base surface, a Hooke spring on the penetration depth
  (Culbertson & Kuchenbecker 2017 sec. 3.2 rendered every surface so, at
  0.25 N/mm). Kept whenever the scene gives ``stiffness`` (N/mm), scaled by the
  WHaT compliance k_c when ``compliance`` is given (docs/compliance.md:
  F = k_max k_c penetration); the figure is the rendered stiffness in N/mm.
  ``compliance`` without ``stiffness`` has nothing to scale: recorded as not
  kept, with that reason.
"""

from __future__ import annotations

import math
import shlex
from dataclasses import asdict, dataclass
from typing import Any

from ..errors import DataError, Diagnostic, FlowtexError, GraphError
from .file import Scene, SurfaceSpec

DEFAULT_THRESHOLDS = {"texture": 1.0, "friction": 0.5, "taps": 60.0}
"""Defaults: texture (m/s^2)^2, friction mu_k (dimensionless), taps Hz (sources in the module docstring)."""

UNITS = {"texture": "(m/s^2)^2", "friction": "", "taps": "Hz", "pattern": "", "stiffness": "N/mm"}
FIGURES = {"texture": "mean vibration power", "friction": "friction coefficient mu_k", "taps": "tap spectral centroid",
           "pattern": "pattern given", "stiffness": "base stiffness"}
PATTERN_NODE = "patterned_texture"


@dataclass
class Decision:
    """One surface component: keep it or not, the salience figure, the threshold, and why (the JSON record)."""

    keep: bool
    salience: float
    threshold: float
    reason: str


@dataclass
class SurfaceData:
    """What the planner loaded for one surface (reused by the graph writer)."""

    spec: SurfaceSpec
    mu: float | None
    decisions: dict[str, Decision]
    stiffness: float | None = None
    """Rendered base-surface stiffness, N/mm (``stiffness`` x k_c), or None."""


def _fail(spec: SurfaceSpec, key: str, message: str) -> FlowtexError:
    return GraphError([Diagnostic(spec.locs.get(key, spec.loc), message)])


def scene_ranges(scene: Scene) -> tuple[tuple[float, float], tuple[float, float]]:
    """Speed (mm/s) and force (N) ranges of the scene's trajectory (from the recording when it names one)."""
    if scene.recording is None:
        assert scene.speed_range is not None and scene.force_range is not None
        return scene.speed_range, scene.force_range
    from ..io.recordings import load_recording
    from .salience import trajectory_ranges

    rec = load_recording(scene.recording)
    missing = [k for k in ("position", "normal_force") if k not in rec.arrays]
    if missing:
        raise DataError(f"{scene.recording}: the trajectory recording lacks {', '.join(missing)} (needs position in mm and normal_force in N)")
    try:
        return trajectory_ranges(rec.arrays["position"], rec.arrays["normal_force"], rec.rate or scene.rate, rec.arrays.get("normal"))
    except ValueError as exc:
        raise DataError(f"{scene.recording}: {exc}") from None


def _decide(component: str, salience: float, threshold: float, spec: SurfaceSpec) -> Decision:
    above = salience >= threshold
    unit = f" {UNITS[component]}" if UNITS[component] else ""
    figure = f"{FIGURES[component]} {salience:.3g}{unit}"
    limit = f"threshold {threshold:g}{unit}"  # both in the figure's unit: a reader compares them as they stand
    if component in spec.keep:
        why = "" if above else f" ({figure} is below the {limit})"
        return Decision(True, salience, threshold, f"kept: forced by keep: in the scene{why}")
    if component in spec.drop:
        why = f" ({figure} is above the {limit})" if above else ""
        return Decision(False, salience, threshold, f"dropped: forced by drop: in the scene{why}")
    if above:
        return Decision(True, salience, threshold, f"kept: {figure} >= {limit}")
    return Decision(False, salience, threshold, f"dropped: {figure} < {limit}")


def _check_rate(spec: SurfaceSpec, field: str, key: str, file_rate: float, scene_rate: float) -> None:
    """Refuse, at the surface's line, a model set or tap library sampled at another rate than the scene runs at."""
    if abs(file_rate - scene_rate) > 1e-9 * scene_rate:
        path = getattr(spec, field)
        raise _fail(spec, field, f"surface {key!r}: {path} is sampled at {file_rate:g} Hz but the scene runs at {scene_rate:g} Hz; "
                                 f"run 'flowtex models resample {shlex.quote(str(path))} --rate {scene_rate:g} -o OUT.json' and name OUT.json here")


def plan_scene(scene: Scene, node_types: set[str] | frozenset[str] = frozenset()) -> dict[str, SurfaceData]:
    """Load every surface's models and decide each component; ``node_types`` are the registered node type names."""
    from ..io.modelset import load_model_set
    from ..io.taplib import read_tap_library
    from ..models.taps import spectral_centroid
    from .salience import mean_texture_power

    th = {**DEFAULT_THRESHOLDS, **scene.thresholds}
    speed_range, force_range = scene_ranges(scene)
    out: dict[str, SurfaceData] = {}
    for key, spec in scene.surfaces.items():
        try:
            ms = load_model_set(spec.models)
        except FlowtexError as exc:
            raise _fail(spec, "models", f"surface {key!r}: {exc}") from None
        _check_rate(spec, "models", key, ms.sample_rate, scene.rate)
        decisions: dict[str, Decision] = {}
        power = mean_texture_power(ms, speed_range, force_range)  # the set's own rule, as the planned graph's lookup
        decisions["texture"] = _decide("texture", power, th["texture"], spec)
        mu = spec.mu if spec.mu is not None else ms.mu
        if mu is not None and math.isfinite(mu) and mu >= 0:
            decisions["friction"] = _decide("friction", float(mu), th["friction"], spec)
        else:
            mu = None
            if "friction" in spec.keep:
                raise _fail(spec, "keep", f"surface {key!r}: keep: friction, but the model set has no friction coefficient; give mu")
        if spec.taps is not None:
            try:
                lib = read_tap_library(spec.taps)
            except FlowtexError as exc:
                raise _fail(spec, "taps", f"surface {key!r}: {exc}") from None
            _check_rate(spec, "taps", key, lib.sample_rate_hz, scene.rate)
            decisions["taps"] = _decide("taps", spectral_centroid(lib), th["taps"], spec)
        elif "taps" in spec.keep:
            raise _fail(spec, "keep", f"surface {key!r}: keep: taps, but the surface has no tap library; add taps: FILE")
        if spec.pattern is not None:
            if PATTERN_NODE not in node_types:
                if "pattern" in spec.keep:
                    raise _fail(spec, "pattern", f"surface {key!r}: keep: pattern, but this flowtex has no {PATTERN_NODE} node type")
                decisions["pattern"] = Decision(False, 1.0, 0.5, f"dropped: node type {PATTERN_NODE} is not available in this flowtex")
            elif "pattern" in spec.drop:
                decisions["pattern"] = Decision(False, 1.0, 0.5, "dropped: forced by drop: in the scene")
            else:
                decisions["pattern"] = Decision(True, 1.0, 0.5, "kept: the scene gives a pattern (no study measured its salience)")
        elif "pattern" in spec.keep:
            raise _fail(spec, "keep", f"surface {key!r}: keep: pattern, but the surface has no pattern")
        stiffness = _stiffness(spec, decisions)
        out[key] = SurfaceData(spec, mu, decisions, stiffness)
    return out


def _compliance_kc(spec: SurfaceSpec) -> tuple[float | None, str]:
    """k_c of the surface (None when the estimate is not valid) and where it comes from, for the reason."""
    from pathlib import Path

    if not isinstance(spec.compliance, Path):
        return spec.compliance, f"compliance k_c {spec.compliance:.3g}"
    from ..fit.compliance import FORMAT_NAME
    from ..io.jsondoc import read_json_document

    try:
        doc = read_json_document(spec.compliance, "compliance estimate", FORMAT_NAME, (1,))
    except FlowtexError as exc:
        raise _fail(spec, "compliance", f"surface {spec.key!r}: {exc}") from None
    kc = doc.get("k_c")
    if not doc.get("valid") or isinstance(kc, bool) or not isinstance(kc, (int, float)) or not 0.0 <= kc <= 1.0:
        return None, f"the compliance estimate in {spec.compliance.name} is not valid ({doc.get('reason', 'no reason given')})"
    return float(kc), f"compliance k_c {kc:.3g} from {spec.compliance.name}"


def _stiffness(spec: SurfaceSpec, decisions: dict[str, Decision]) -> float | None:
    """Decide the base-surface spring; returns the rendered stiffness (N/mm) when kept."""
    kc, source = (None, "") if spec.compliance is None else _compliance_kc(spec)
    if spec.stiffness is None:
        if "stiffness" in spec.keep:
            raise _fail(spec, "keep", f"surface {spec.key!r}: keep: stiffness, but the surface gives no stiffness; add stiffness: N/mm")
        if spec.compliance is not None:
            decisions["stiffness"] = Decision(False, 0.0, 0.0, f"not rendered: {source} scales a base stiffness, but the surface gives "
                                                               "no stiffness (N/mm); add stiffness: K_MAX")
        return None
    k = spec.stiffness
    why = "Hooke spring on the penetration input"
    if kc is not None:
        why = f"{spec.stiffness:.3g} N/mm x {source}; " + why
        k = spec.stiffness * kc
    elif spec.compliance is not None:
        why = f"{source}: stiffness {spec.stiffness:.3g} N/mm not scaled; " + why
    if k <= 0.0:
        decisions["stiffness"] = Decision(False, k, 0.0, f"dropped: base stiffness 0 N/mm ({why}) renders nothing")
        return None
    if "stiffness" in spec.drop:
        decisions["stiffness"] = Decision(False, k, 0.0, f"dropped: forced by drop: in the scene (base stiffness {k:.3g} N/mm)")
        return None
    decisions["stiffness"] = Decision(True, k, 0.0, f"kept: base stiffness {k:.3g} N/mm ({why}); no study measured its salience")
    return k


def plan_json(plan: dict[str, SurfaceData]) -> dict[str, dict[str, dict[str, Any]]]:
    """``{surface: {component: {"keep", "salience", "threshold", "reason"}}}`` (the ``--json`` document)."""
    return {key: {comp: asdict(d) for comp, d in data.decisions.items()} for key, data in plan.items()}


def silent_surfaces(plan: dict[str, SurfaceData]) -> list[str]:
    """One warning line per surface whose every component was dropped (it renders nothing), naming each reason."""
    lines = []
    for key, data in plan.items():
        if data.decisions and not any(d.keep for d in data.decisions.values()):
            why = "; ".join(f"{comp} {d.reason}" for comp, d in data.decisions.items())
            lines.append(f"surface {key!r} renders nothing: every component was dropped ({why}); lower its threshold in the "
                         "scene's thresholds:, or add keep: COMPONENT to the surface")
    return lines


def explain(plan: dict[str, SurfaceData]) -> str:
    """Human-readable table: one line per surface and component."""
    width = max([7] + [len(k) for k in plan])
    lines = [f"{'surface':<{width}}  {'component':<9} {'salience':>10} {'threshold':>10}  decision"]
    for key, data in plan.items():
        for comp, d in data.decisions.items():
            lines.append(f"{key:<{width}}  {comp:<9} {d.salience:>10.3g} {d.threshold:>10.3g}  {'KEEP' if d.keep else 'drop'}  {d.reason}")
    return "\n".join(lines)
