"""The graph file (docs/graph-format.md), declared once: :mod:`flowtex.graph.spec` checks with it, editors get its
JSON Schema. Node parameters are not declared here: they come from each node type's ``Param`` declarations
(:mod:`flowtex.schema.jsonschema` adds them per type)."""

from __future__ import annotations

from ..limits import MAX_EVERY, MAX_RATE_HZ
from .core import Field, Record

FORMAT_VERSION = 1
NAME_PATTERN = r"^[A-Za-z_][A-Za-z0-9_]*$"
EDGE_PATTERN = r"^\s*(?P<src>[^\s>-][^\s]*)\s*->\s*(?P<dst>[^\s]+)\s*$"

VERSION = Field("const", const=FORMAT_VERSION, doc="The format version; write 'flowtex: 1'.",
                missing="missing top-level key 'flowtex' (the format version; write 'flowtex: 1')",
                message="unsupported format version {got}; this flowtex reads version " + str(FORMAT_VERSION))
RATE = Field("number", unit="Hz", default=1000.0, min=0.0, min_exclusive=True, max=MAX_RATE_HZ,
             doc="Base tick rate of the graph.",
             message=f"rate must be a number of Hz in (0, {MAX_RATE_HZ:g}], got {{got}}")

INPUT = Record(
    keys={
        "shape": Field("any_of", doc="Shape of one tick's value: [] or absent for a scalar, [3] for a 3-vector.", default=[],
                       of=(Field("int", min=1), Field("list", items=Field("int", min=1))),
                       message="input {name!r}: shape must be a list of positive integers such as [3], or [] for a scalar"),
        "unit": Field("str", doc="Unit of the input ('-' or absent: dimensionless), e.g. mm, N, m/s^2.", default="",
                      message="input {name!r}: unit must be a string such as 'mm' or 'N'"),
        "doc": Field("str", doc="Free text describing the input."),
    },
    unknown="input {what!r}: unknown key {key}{hint}",
    doc="A graph input: its shape and unit.",
)

NODE = Record(
    keys={
        "type": Field("str", doc="Node type (flowtex nodes lists them).",
                      message="node {name!r}: missing 'type' (run 'flowtex nodes' to list node types)"),
        "params": Field("map", doc="Parameters of the node type (flowtex nodes TYPE lists them).",
                        message="node {name!r}: params must be a mapping of name: value"),
        "every": Field("int", default=1, min=1, max=MAX_EVERY, doc="Run the node every k ticks (zero-order hold between runs).",
                       message=f"node {{name!r}}: every must be a positive integer up to {MAX_EVERY:,} (run every k ticks), got {{got}}"),
        "doc": Field("str", doc="Free text describing the node."),
    },
    required=("type",),
    unknown="node {what!r}: unknown key {key}{hint}",
    missing="node {what!r}: missing 'type' (run 'flowtex nodes' to list node types)",
    doc="A node: its type, parameters and schedule.",
)

EDGE = Field("str", pattern=EDGE_PATTERN, doc='An edge "producer.port -> consumer.port" (a graph input by its bare name).',
             message='edge must be a string "producer.port -> consumer.port", got {got}')

GRAPH = Record(
    keys={
        "flowtex": VERSION,
        "name": Field("str", doc="Name of the graph (default: the file name).", message="name must be a string"),
        "rate": RATE,
        "seed": Field("int", default=0, min=0, doc="Default noise seed.", message="seed must be a non-negative integer, got {got}"),
        "description": Field("any", doc="Free text describing the graph."),
        "plugins": Field("list", items=Field("str", length=(1, None)),
                         doc="Folders of plugin node files, relative to the graph file.",
                         message="plugins must be a list of folders (relative to the graph file), got {got}"),
        "inputs": Field("map", names=NAME_PATTERN, values=Field("any_of", of=(Field("record", record=INPUT), Field("const", const=None))),
                        doc="Graph inputs: name -> {shape, unit}.", message="inputs must be a mapping of name: {{shape, unit}}"),
        "nodes": Field("map", names=NAME_PATTERN, values=Field("record", record=NODE),
                       doc="Nodes: name -> {type, params, every}.", message="nodes must be a mapping of name: {{type, params}}"),
        "edges": Field("list", items=EDGE, doc="Edges between ports.",
                       message='edges must be a list of "producer.port -> consumer.port" strings'),
        "outputs": Field("map", names=NAME_PATTERN, values=Field("str"), length=(1, None),
                         doc="Graph outputs: name -> node.port.", message="outputs must be a non-empty mapping of name: node.port"),
    },
    required=("flowtex", "rate", "nodes", "outputs"),
    unknown="unknown top-level key {key}{hint}",
    missing="missing top-level key {name!r}",
    doc="A flowtex graph: nodes joined by edges, run offline or live at one base rate.",
)
