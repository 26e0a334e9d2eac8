"""A plugin folder's compiled code is filed by its sources, not its path (flowtex.plugincode.plugin_code_id): a copy of the
folder elsewhere (another checkout, a folder moved, or staged and renamed) loads the kernels, the dispatch wrapper
and the fused module the first copy compiled; an edit anywhere in the folder, even in a helper the kernel calls and
not in the kernel, gives new machine code; two copies loaded in one process each run as their own module; and a
kernel's exception raised by code another copy compiled still names its node and file."""

from __future__ import annotations

import os
import shutil
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from numba.core import event

from flowtex import cache
from flowtex.cache import shares_compiled_code
from flowtex.graph.compiled import load_graph
from flowtex.graph.faults import KernelError
from flowtex.registry import forget_plugin_code
from tests.plugin_files import plugin_project

IMPORTS = """
import numpy as np
from numba import njit
from flowtex.node_api import Node, NodeState, Port
"""

HELPER = """
@njit(cache=True)
def factor():
    return FACTOR
"""
"""The helper the kernel calls (FACTOR: its literal); tests/test_plugin_package_code.py puts it in a file of its own."""

NODE = """
@njit(cache=True)
def scaled_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        for c in range(x.shape[1]):
            if x[t, c] > 99.5:
                raise ValueError("x too large")
            y[t, c] = factor() * x[t, c]

class Scaled(Node):
    type_name = "TYPE_NAME"
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "x times the helper's factor")}
    kernel = scaled_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.zeros(0))
"""

PLUGIN = IMPORTS + HELPER + NODE.replace("TYPE_NAME", "copied_scale")

GRAPH = """
flowtex: 1
name: copied
rate: 1000
plugins: [plugins]
inputs:
  x: {}
nodes:
  s: {type: copied_scale}
edges:
  - x -> s.x
outputs:
  y: s.y
"""


class _Compiles(event.Listener):
    """Names of the functions numba compiles (not loads from its cache) while registered."""

    def __init__(self) -> None:
        self.names: list[str] = []

    def on_start(self, ev: event.Event) -> None:
        func = getattr((ev.data or {}).get("dispatcher"), "py_func", None)
        self.names.append(getattr(func, "__qualname__", "?"))

    def on_end(self, ev: event.Event) -> None:
        pass


def _project(root: Path, factor: float = 2.0) -> Path:
    """A graph and its plugin folder under ``root``. The tests use the same factor (the same sources) where they can:
    what one compiles, the next loads, wherever its folder lies."""
    return plugin_project(root, {"copied_scale.py": textwrap.dedent(PLUGIN).replace("FACTOR", repr(factor))}, textwrap.dedent(GRAPH))


def _run(project: Path, tier: str) -> tuple[np.ndarray, list[str]]:
    """The graph's output on both tiers' inputs, and what numba compiled for it (nothing loaded earlier is kept)."""
    forget_plugin_code()
    listener = _Compiles()
    with event.install_listener("numba:compile", listener):
        y = load_graph(project / "g.yaml", tier=tier).run({"x": np.arange(4.0)})["y"].copy()
    return y, listener.names


@pytest.fixture(autouse=True)
def _forget_plugins():
    yield
    forget_plugin_code()


@pytest.mark.parametrize("tier", ["dispatch", "fused"])
def test_a_copied_plugin_folder_loads_what_the_first_compiled(tmp_path, tier):
    first = _project(tmp_path / "first")
    y, _ = _run(first, tier)
    np.testing.assert_array_equal(y, 2.0 * np.arange(4.0))
    copy = tmp_path / "elsewhere" / "copy"
    shutil.copytree(first, copy)
    shutil.rmtree(first)  # moved, not only copied: nothing can come from the first folder's files
    y, compiled = _run(copy, tier)
    np.testing.assert_array_equal(y, 2.0 * np.arange(4.0))
    assert compiled == [], compiled


@pytest.mark.parametrize("tier", ["dispatch", "fused"])
def test_an_edited_helper_gives_new_code_on_both_tiers(tmp_path, tier):
    project = _project(tmp_path, 2.0)
    y, _ = _run(project, tier)
    np.testing.assert_array_equal(y, 2.0 * np.arange(4.0))
    plugin = project / "plugins" / "copied_scale.py"
    plugin.write_text(plugin.read_text().replace("return 2.0", "return 3.0"))  # the helper, not the kernel, changes
    y, _ = _run(project, tier)  # (whether it compiles depends on what earlier runs left in the cache)
    np.testing.assert_array_equal(y, 3.0 * np.arange(4.0))


def test_two_copies_in_one_process_are_two_modules(tmp_path):
    a, b = _project(tmp_path / "a"), _project(tmp_path / "b")
    forget_plugin_code()
    ga, gb = load_graph(a / "g.yaml", tier="dispatch"), load_graph(b / "g.yaml", tier="dispatch")
    files = {Path(g.resolved.nodes["s"].cls.kernel.py_func.__code__.co_filename).resolve() for g in (ga, gb)}
    assert files == {(a / "plugins" / "copied_scale.py").resolve(), (b / "plugins" / "copied_scale.py").resolve()}
    for g in (ga, gb):
        np.testing.assert_array_equal(g.run({"x": np.arange(4.0)})["y"], 2.0 * np.arange(4.0))


def test_an_exception_from_code_a_deleted_copy_compiled_names_the_node_and_this_file(tmp_path):
    first = _project(tmp_path / "first")
    _run(first, "fused")  # compiles the fused module, whose raise locations name the first copy's file
    copy = tmp_path / "copy"
    shutil.copytree(first, copy)
    shutil.rmtree(first)
    forget_plugin_code()
    graph = load_graph(copy / "g.yaml", tier="fused")
    with pytest.raises(KernelError) as caught:
        graph.run({"x": np.array([1.0, 100.0])})
    message = str(caught.value)
    assert "node 's' (copied_scale)" in message and "x too large" in message, message
    assert message.startswith(str(copy / "plugins" / "copied_scale.py") + ":"), message


def test_compiled_code_is_shared_with_the_same_file_in_another_copy_of_flowtex():
    from flowtex.nodes.arith import _gain

    here = Path(_gain.py_func.__code__.co_filename)
    assert shares_compiled_code(here, _gain.py_func)
    assert shares_compiled_code(Path("/another/checkout/flowtex/nodes") / here.name, _gain.py_func)
    assert not shares_compiled_code(Path("/another/checkout/flowtex/dsp") / here.name, _gain.py_func)
    assert not shares_compiled_code(Path("/another/checkout/notflowtex/nodes") / here.name, _gain.py_func)


def test_plugin_code_left_unwritten_for_a_month_is_pruned(tmp_path, monkeypatch):
    current = tmp_path / "numba" / "fingerprint"
    old, recent, touched = (current / "plugins" / name for name in ("old", "recent", "touched"))
    month_ago = time.time() - cache.PLUGIN_KEEP_S - 3600
    for folder in (old, recent, touched):
        folder.mkdir(parents=True)
        (folder / "k.nbi").write_bytes(b"x")
        if folder is not recent:
            os.utime(folder / "k.nbi", (month_ago, month_ago))
            os.utime(folder, (month_ago, month_ago))
    (touched / "k.2.nbc").write_bytes(b"y")  # a new entry this month: the folder is in use
    monkeypatch.setattr(cache, "_CONFIGURED", [current])
    cache.prune_numba_cache()
    assert not old.exists() and recent.exists() and touched.exists()
