"""One scaffold for the tests that write a plugin node and a graph using it (plugin declarations and mistakes, kernel
faults, non-finite outputs; hostile graph files use the graph alone): the source of a one-node plugin file, a graph
file's text chaining nodes from one scalar input ``x``, and a project folder holding them (as a user's project would:
``plugins/`` beside ``g.yaml``, a recording ``r.npz``).

The plugin files under ``tests/plugin_cases/`` stay whole files on purpose: they are the examples docs/plugins.md
shows, each mistake at a line a reader can find.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

SCALAR_IN = '{"x": Port((), "*")}'
"""The usual inputs of a plugin node: one scalar ``x`` of any unit."""
SCALAR_OUT = '{"y": Port((), "=x")}'
"""The usual outputs: one scalar ``y`` in ``x``'s unit."""


def plugin_source(type_name: str, kernel: str, body: str, *, doc: str, cls: str = "Plugged", params: str = "",
                  inputs: str = SCALAR_IN, outputs: str = SCALAR_OUT, build: str = "") -> str:
    """The text of a plugin file defining one node type: the ``@njit(cache=True)`` function ``kernel(p, s, si, x, y)``
    whose body is ``body`` (its lines as they would stand at the left margin), and the class
    ``cls`` with that ``type_name``, docstring ``doc``, ``params`` (a dict's source, none when empty), ``inputs``,
    ``outputs`` and, when ``build`` is given, ``build()`` returning that expression."""
    lines = ["import numpy as np", "from numba import njit", "", "from flowtex.node_api import Node, NodeState, Param, Port",
             "", "", "@njit(cache=True)", f"def {kernel}(p, s, si, x, y):"]
    lines += textwrap.indent(textwrap.dedent(body).strip("\n"), "    ").splitlines()
    lines += ["", "", f"class {cls}(Node):", f'    """{doc}"""', "", f'    type_name = "{type_name}"']
    if params:
        lines.append(f"    params = {params}")
    lines += [f"    inputs = {inputs}", f"    outputs = {outputs}", f"    kernel = {kernel}"]
    if build:
        lines += ["", "    def build(self, inputs, outputs):", f"        return {build}"]
    return "\n".join(lines) + "\n"


def chain_graph(*nodes: str, outputs: str = "", name: str = "t") -> str:
    """The text of a graph file at 1 kHz: the scalar input ``x`` through ``nodes`` in order (each ``"NAME: {type: ...}"``,
    a YAML mapping entry; each node's ``y`` feeds the next one's ``x``), the last node's ``y`` as output ``y``, and the
    further ``outputs`` (``"NAME: SOURCE, ..."``)."""
    names = [node.split(":", 1)[0].strip() for node in nodes]
    edges = [f"x -> {names[0]}.x"] + [f"{a}.y -> {b}.x" for a, b in zip(names[:-1], names[1:], strict=True)]
    listed = ", ".join([f"y: {names[-1]}.y", *filter(None, [outputs])])
    return "\n".join(["flowtex: 1", f"name: {name}", "rate: 1000", "inputs: {x: {}}", "nodes:", *(f"  {n}" for n in nodes),
                      f"edges: [{', '.join(edges)}]", f"outputs: {{{listed}}}"]) + "\n"


def plugin_project(folder: Path, plugins: dict[str, str], graph: str, x: np.ndarray | None = None) -> Path:
    """``folder`` (created if missing) holding ``plugins/NAME`` for each plugin file text, ``g.yaml`` holding ``graph``
    and, when ``x`` is given, the recording ``r.npz`` of the input ``x`` at 1 kHz; returns ``folder``."""
    (folder / "plugins").mkdir(parents=True, exist_ok=True)
    for file_name, text in plugins.items():
        (folder / "plugins" / file_name).write_text(text)
    (folder / "g.yaml").write_text(graph)
    if x is not None:
        np.savez(folder / "r.npz", x=x, rate=1000.0)
    return folder
