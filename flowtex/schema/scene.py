"""The scene file (docs/scenes.md), declared once: :mod:`flowtex.scene.file` checks with it, editors get its JSON Schema."""

from __future__ import annotations

from .core import Field, Record
from .graph import NAME_PATTERN, VERSION

COMPONENTS = ("texture", "friction", "taps", "pattern", "stiffness")
"""Components a surface may keep or drop; ``stiffness`` is the base-surface spring (``stiffness`` x ``compliance``)."""


def nonneg(what: str, unit: str = "", doc: str = "", positive: bool = False) -> Field:
    """A finite number >= 0 (> 0 when ``positive``), refused as '``what`` must be a non-negative number, got X'."""
    return Field("number", min=0.0, min_exclusive=positive, unit=unit, doc=doc,
                 message=f"{what} must be a {'positive' if positive else 'non-negative'} number, got {{got}}")


def _range(what: str, unit: str, example: str) -> Field:
    return Field("list", items=Field("number", min=0.0), length=(2, 2), unit=unit, doc=f"[low, high] {what} of the trajectory, {unit}.",
                 message=f"trajectory {what} must be [low, high] in {unit}, e.g. {what}: {example}")


COMPONENT_LIST = Field("any_of", of=(Field("choice", choices=COMPONENTS), Field("list", items=Field("choice", choices=COMPONENTS))),
                       doc="Components: " + ", ".join(COMPONENTS) + ".",
                       message="surface {surface!r}: {key} must be a list of components from " + ", ".join(COMPONENTS))

SURFACE = Record(
    keys={
        "models": Field("str", doc="Texture model set file (HaTT XML or flowtex JSON), relative to the scene file.",
                        message="surface {surface!r}: 'models' must name a texture model set file (HaTT XML or flowtex JSON)",
                        missing="surface {surface!r}: 'models' must name a texture model set file (HaTT XML or flowtex JSON)"),
        "mu": nonneg("surface {surface!r}: mu (kinetic friction coefficient)", doc="Kinetic friction coefficient (overrides the model set's)."),
        "taps": Field("str", doc="Tap library file (docs/tap-library.md).",
                      message="surface {surface!r}: 'taps' must name a tap library file (docs/tap-library.md)"),
        "pattern": Field("any", doc="Pattern of a patterned texture (docs/patterns.md)."),
        "compliance": Field("any_of", of=(Field("number", min=0.0, max=1.0), Field("str")),
                            doc="WHaT compliance k_c (0 soft .. 1 stiff), or the JSON file 'flowtex fit compliance' writes.",
                            message="surface {surface!r}: compliance must be k_c between 0 (soft) and 1 (stiff), or the JSON file "
                                    "'flowtex fit compliance' writes; got {got}"),
        "stiffness": nonneg("surface {surface!r}: stiffness (N/mm)", unit="N/mm", positive=True,
                            doc="Base-surface spring constant (scaled by k_c when compliance is given)."),
        "keep": COMPONENT_LIST,
        "drop": COMPONENT_LIST,
        "doc": Field("str", doc="Free text describing the surface."),
    },
    required=("models",),
    unknown="surface {surface!r}: unknown key {name!r}{hint}",
    doc="A surface: its texture model set and optional friction, taps, pattern and stiffness.",
)

TRAJECTORY = Record(
    keys={
        "speed": _range("speed", "mm/s", "[50, 250]"),
        "force": _range("force", "N", "[0.5, 2.5]"),
        "recording": Field("str", doc="A recording (.npz, .csv, .h5) whose speed and force drive the salience measure.",
                           message="trajectory.recording must name a recording file (.npz, .csv, .h5)"),
    },
    unknown="trajectory: unknown key {name!r}{hint}; allowed: {allowed}",
    doc="The force-speed trajectory the planner measures salience over: ranges, or a recording.",
)

THRESHOLDS = Record(
    keys={
        "texture": nonneg("thresholds.texture", unit="(m/s^2)^2", doc="Texture vibration power below which texture is dropped."),
        "friction": nonneg("thresholds.friction", doc="Kinetic friction coefficient below which friction is dropped."),
        "taps": nonneg("thresholds.taps", unit="Hz", doc="Tap spectral centroid below which taps are dropped."),
    },
    unknown="thresholds: unknown key {name!r}{hint}; allowed: {allowed}",
    doc="Per-component salience thresholds.",
)

SELECT = Record(
    keys={
        "input": Field("str", pattern=NAME_PATTERN, default="surface", doc="Graph input that selects the surface.",
                       message="select.input must be a graph input name (letters, digits, '_'), got {got}"),
        "fade": nonneg("select.fade (s)", unit="s", doc="Cross-fade time between surfaces."),
        "fixed": Field("str", doc="Render this surface alone."),
    },
    unknown="select: unknown key {name!r}{hint}; allowed: {allowed}",
    doc="How the rendered surface is chosen.",
)

DEVICE = Record(
    keys={
        "dbc": Field("str", doc="The device's DBC file.", message="device.dbc must name a file (device: {{dbc: device.dbc, map: map.yaml}})",
                     missing="device.dbc must name a file (device: {{dbc: device.dbc, map: map.yaml}})"),
        "map": Field("str", doc="The device map file.", message="device.map must name a file (device: {{dbc: device.dbc, map: map.yaml}})",
                     missing="device.map must name a file (device: {{dbc: device.dbc, map: map.yaml}})"),
    },
    required=("dbc", "map"),
    unknown="device: unknown key {name!r}{hint}; allowed: {allowed}",
    doc="The device the scene runs live on.",
)

SECTIONS = {"trajectory": (TRAJECTORY, "{speed: [50, 250], force: [0.5, 2.5]}"),
            "thresholds": (THRESHOLDS, "{texture: 1.0, friction: 0.5, taps: 60}"),
            "select": (SELECT, "{input: surface, fade: 0.01}"),
            "device": (DEVICE, "{dbc: device.dbc, map: map.yaml}")}
"""Top-level sections that are mappings: their record and the example their 'must be a mapping' message shows."""

SCENE = Record(
    keys={
        "flowtex": VERSION,
        "name": Field("str", length=(1, None), doc="Name of the scene (default: the file name).", message="name must be a non-empty string"),
        "rate": nonneg("rate (Hz)", unit="Hz", positive=True, doc="Base tick rate of the generated graph."),
        "surfaces": Field("map", names=NAME_PATTERN, values=Field("record", record=SURFACE), length=(1, None),
                          doc="Surfaces: name -> {models, mu, taps, ...}.",
                          message="surfaces must be a non-empty mapping of name: {{models: FILE, ...}}"),
        **{key: Field("record", record=rec, doc=rec.doc, message=f"{key} must be a mapping, e.g. {key}: {example}")
           for key, (rec, example) in SECTIONS.items()},
        "description": Field("any", doc="Free text describing the scene."),
    },
    required=("flowtex", "surfaces", "trajectory"),
    unknown="unknown top-level key {name!r}{hint}",
    missing="missing top-level key {name!r}",
    doc="A flowtex scene: surfaces to render, from which the planner builds a graph with only what matters.",
)
