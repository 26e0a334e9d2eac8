"""An installed plugin package's compiled code is keyed by its package's sources (flowtex.plugincode): after an edit to
a helper that a kernel calls from another file of the package (an editable install, as `flowtex plugin new` sets up),
both tiers run the new code. numba keys a cached kernel by its own file only, so before this the kernel, its dispatch
wrapper and the fused module kept the old helper's machine code."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from test_plugin_cache_copies import HELPER, IMPORTS, NODE

from flowtex.graph.jit import kernel_fingerprint
from flowtex.plugincode import plugin_code_of

GRAPH = """
flowtex: 1
name: packaged
rate: 1000
inputs:
  x: {}
nodes:
  s: {type: package_scale}
edges:
  - x -> s.x
outputs:
  y: s.y
"""

CHILD = """
import json, sys
import numpy as np
from flowtex.graph.compiled import load_graph
print(json.dumps({tier: load_graph(sys.argv[1], tier=tier).run({"x": np.arange(4.0)})["y"].ravel().tolist()
                  for tier in ("dispatch", "fused")}))
"""
"""Runs the graph on both tiers in one process (the package found through its installed entry point)."""


def _install(site: Path, factor: float) -> None:
    """The package ``ftx_pkg_scale`` in ``site`` with an installed distribution's entry point, as pip would leave it."""
    pkg = site / "ftx_pkg_scale"
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "helpers.py").write_text("from numba import njit\n" + HELPER.replace("FACTOR", repr(factor)))
    (pkg / "nodes.py").write_text(IMPORTS + "from .helpers import factor\n" + NODE.replace("TYPE_NAME", "package_scale"))
    dist = site / "ftx_pkg_scale-0.1.dist-info"
    dist.mkdir(exist_ok=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: ftx-pkg-scale\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[flowtex.nodes]\npackage_scale = ftx_pkg_scale.nodes\n")


def _run(site: Path, graph: Path) -> dict[str, list[float]]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", CHILD, str(graph)], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_an_edited_helper_of_an_installed_package_gives_new_code_on_both_tiers(tmp_path):
    site, graph = tmp_path / "site", tmp_path / "g.yaml"
    graph.write_text(textwrap.dedent(GRAPH))
    _install(site, 2.0)
    assert _run(site, graph) == {"dispatch": [0.0, 2.0, 4.0, 6.0], "fused": [0.0, 2.0, 4.0, 6.0]}
    _install(site, 3.0)  # only the helper's file changes: the kernel's file and source are the same
    assert _run(site, graph) == {"dispatch": [0.0, 3.0, 6.0, 9.0], "fused": [0.0, 3.0, 6.0, 9.0]}


def test_other_numba_functions_keep_numbas_own_keys():
    """Only plugin folders' files and registered plugin packages are filed by flowtex: a flowtex kernel is keyed by
    flowtex's source tree, and any other numba function in the process (a library's) is left alone."""
    from flowtex.dsp.triangulation import clamp_query
    from flowtex.plugincode import register_plugin_package

    register_plugin_package("flowtex.nodes")  # an entry point into flowtex itself changes nothing
    assert plugin_code_of(clamp_query.py_func) is None
    assert kernel_fingerprint(clamp_query).startswith("flowtex.dsp.triangulation.clamp_query:")
    assert plugin_code_of(json.dumps) is None
