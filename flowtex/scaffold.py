"""``flowtex plugin new NAME -o DIR``: an installable plugin package for one node type, with its tests.

What is written (``NAME`` is the node type, e.g. ``smooth_gain``; the Python
package is ``flowtex_NAME``)::

    DIR/pyproject.toml                 entry point flowtex.nodes -> flowtex_NAME.node
    DIR/README.md
    DIR/flowtex_NAME/__init__.py
    DIR/flowtex_NAME/node.py           the node, to the documented API, with a stateful kernel
    DIR/tests/test_NAME.py             golden test on a recording the test generates, reference, chunked runs
    DIR/tests/golden/NAME.npz          the golden outputs, made now by running the test's own graph

The example kernel is a gain followed by a one-pole low-pass (per channel,
state in ``s``): small, stateful, and with a closed-form reference
(``scipy.signal.lfilter``) that its test checks against.
"""

from __future__ import annotations

import keyword
import re
import tempfile
from pathlib import Path
from string import Template

from .errors import FlowtexError

NAME_RE = re.compile(r"^[a-z][a-z0-9_]{0,49}$")

PYPROJECT = '''\
[build-system]
requires = ["setuptools>=64"]
build-backend = "setuptools.build_meta"

[project]
name = "flowtex-$dist"
version = "0.1.0"
description = "flowtex node type '$name'"
requires-python = ">=3.10"
dependencies = ["flowtex", "numpy", "numba", "scipy"]

[project.optional-dependencies]
test = ["pytest"]

# flowtex finds the node types of every installed package through this group.
[project.entry-points."flowtex.nodes"]
$name = "$package.node"

[tool.setuptools.packages.find]
include = ["$package*"]

[tool.pytest.ini_options]
testpaths = ["tests"]
'''

README = '''\
# flowtex-$dist: the `$name` node type

A flowtex plugin package (made by `flowtex plugin new $name`).

    pip install -e .          # the node appears in `flowtex nodes $name`
    pytest                    # golden test, reference test, chunked == one pass
    flowtex plugin check $package/node.py

`$package/node.py` holds the node: declared parameters and ports, `build()`
(sizes the state), and the numba kernel. Its example is a gain followed by a
one-pole low-pass; replace the maths, keep the shape (docs/plugins.md in
flowtex describes the contract). After a change of behaviour, review and
rewrite the golden file with `pytest --update-golden`.
'''

NODE = '''\
"""The '$name' node type: gain, then a one-pole low-pass per channel (replace with your own maths)."""

from __future__ import annotations

import math

from numba import njit

from flowtex.node_api import Field, Layout, Memory, Node, Param, Port

MEMORY = Memory(params=Layout("float", [Field("k", 1, "gain"), Field("a", 1, "smoothing factor of the low-pass")]),
                state=Layout("float", [Field("y", "w", "last output of each channel")], sizes=("w",)))
"""The node's parameters p and state s, declared once: build() packs them, the kernel indexes them by these names."""
P_K = MEMORY.params.const("k")
P_A = MEMORY.params.const("a")
S_Y = MEMORY.state.const("y")


@njit(cache=True)
def ${name}_kernel(p, s, si, x, y):
    """y[t] = y[t-1] + a * (k * x[t] - y[t-1]) per channel (layout: MEMORY)."""
    k = p[P_K]
    a = p[P_A]
    for t in range(x.shape[0]):
        for c in range(x.shape[1]):
            s[S_Y + c] = s[S_Y + c] + a * (k * x[t, c] - s[S_Y + c])
            y[t, c] = s[S_Y + c]


class $cls(Node):
    """Gain, then a one-pole low-pass smoother (per component)."""

    type_name = "$name"
    params = {
        "k": Param("float", default=1.0, doc="gain applied before smoothing", min=-1e6, max=1e6),
        "cutoff_hz": Param("float", default=10.0, doc="-3 dB frequency of the smoother", unit="Hz",
                           min=0.0, min_exclusive=True, max=1e6),
    }
    inputs = {"x": Port(None, "*", "signal (any shape)")}
    outputs = {"y": Port("=x", "=x", "smoothed, scaled signal")}
    kernel = ${name}_kernel
    memory = MEMORY

    def build(self, inputs, outputs):
        a = 1.0 - math.exp(-2.0 * math.pi * self.p["cutoff_hz"] / self.context.node_rate)
        return self.pack_state({"w": inputs["x"].width}, params={"k": self.p["k"], "a": a})
'''

TEST = '''\
"""Tests of the '$name' node: golden outputs, an independent reference, and chunked runs equal to one pass."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

import flowtex

GOLDEN = Path(__file__).parent / "golden" / "$name.npz"
RATE = 1000.0
GRAPH = """\\
flowtex: 1
name: $name-test
rate: 1000
inputs: {x: {unit: N}}
nodes:
  n: {type: $name, params: {k: 2.0, cutoff_hz: 25.0}}
edges: [x -> n.x]
outputs: {y: n.y}
"""


def write_inputs(folder: Path) -> tuple[Path, Path]:
    """The test graph and a small recording (a seeded noisy step, 1 s at 1 kHz) in ``folder``."""
    rng = np.random.default_rng(7)
    x = np.where(np.arange(1000) >= 200, 1.0, 0.0) + 0.1 * rng.standard_normal(1000)
    graph, recording = folder / "graph.yaml", folder / "recording.npz"
    graph.write_text(GRAPH)
    np.savez(recording, x=x, rate=RATE)
    return graph, recording


def test_golden(golden, tmp_path):
    graph, recording = write_inputs(tmp_path)
    golden.check(graph, recording, GOLDEN)


def test_matches_a_one_pole_reference(tmp_path):
    graph, recording = write_inputs(tmp_path)
    x = np.load(recording)["x"]
    y = flowtex.load_graph(graph).run({"x": x})["y"]
    a = 1.0 - math.exp(-2.0 * math.pi * 25.0 / RATE)
    reference = lfilter([2.0 * a], [1.0, -(1.0 - a)], x)  # the same recursion, written by scipy
    np.testing.assert_allclose(y, reference, rtol=1e-12, atol=1e-12)  # float64 rounding of two summation orders


def test_chunked_runs_equal_one_pass(tmp_path):
    graph, recording = write_inputs(tmp_path)
    x = np.load(recording)["x"]
    g = flowtex.load_graph(graph)
    whole = g.run({"x": x})["y"].copy()
    g.reset()
    parts = [g.process({"x": x[a:b]})["y"].copy() for a, b in ((0, 1), (1, 333), (333, 1000))]
    np.testing.assert_array_equal(np.concatenate(parts), whole)
'''


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_") if part) or "Node"


def check_name(name: str) -> None:
    """Refuse a node type name that cannot be a Python identifier and package name, or that a built-in node type has."""
    from .registry import BUILTIN_TYPES

    if not NAME_RE.match(name) or keyword.iskeyword(name):
        raise FlowtexError(f"plugin new: {name!r} is not a node type name; use lowercase letters, digits and '_', starting with "
                           "a letter, at most 50 characters (e.g. smooth_gain)")
    if name in BUILTIN_TYPES:  # else the package's own test, run to write its golden file, names a temporary folder
        raise FlowtexError(f"plugin new: {name!r} is a built-in node type (flowtex nodes {name}); choose another name, "
                           f"e.g. my_{name}")


def scaffold_files(name: str) -> dict[str, str]:
    """Relative path -> text of every file of the package for node type ``name``."""
    check_name(name)
    values = {"name": name, "package": f"flowtex_{name}", "dist": name.replace("_", "-"), "cls": _camel(name)}
    package = values["package"]
    return {
        "pyproject.toml": Template(PYPROJECT).substitute(values),
        "README.md": Template(README).substitute(values),
        f"{package}/__init__.py": f'"""flowtex plugin package of the node type {name!r} (see node.py)."""\n',
        f"{package}/node.py": Template(NODE).substitute(values),
        f"tests/test_{name}.py": Template(TEST).substitute(values),
    }


def write_golden(folder: Path, name: str) -> Path:
    """Run the new test's own graph on its own recording (the node loaded from its file) and write the golden file."""
    import importlib.util

    from .testing import check_golden

    spec = importlib.util.spec_from_file_location(f"flowtex_scaffold_test_{name}", folder / "tests" / f"test_{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    golden = folder / "tests" / "golden" / f"{name}.npz"
    with tempfile.TemporaryDirectory(prefix="flowtex-plugin-new-") as tmp:
        graph, recording = module.write_inputs(Path(tmp))
        check_golden(graph, recording, golden, update=True, plugins=(folder / f"flowtex_{name}",))
    return golden


def new_plugin(name: str, out_dir: str | Path) -> list[Path]:
    """Write the package for node type ``name`` into ``out_dir`` (new or empty) and its golden file; returns the files."""
    files = scaffold_files(name)
    folder = Path(out_dir)
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise FlowtexError(f"-o {out_dir}: exists and is not an empty folder; plugin new writes a new package only")
    if not folder.parent.is_dir():
        raise FlowtexError(f"-o {out_dir}: folder {folder.parent} does not exist")
    # Built beside the target and renamed into place: a failure (or Ctrl-C) leaves no half-written package.
    with tempfile.TemporaryDirectory(prefix=f".{folder.name}.", dir=folder.parent) as tmp:
        staging = Path(tmp) / "package"
        for rel, text in files.items():
            path = staging / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        write_golden(staging, name)
        if folder.exists():
            folder.rmdir()
        staging.rename(folder)
    return sorted(p for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.parts)
