"""Installed entry points of group flowtex.nodes load lazily, as the built-in table does: listing the names imports
no plugin; a type's package is imported on its first use; a package that fails to import is named where it is used.

Two packages are installed for real (pip, editable, into a virtual environment made by the test, as
tests/test_plugin_new.py does): one made by ``flowtex plugin new``, one whose module raises when imported.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from flowtex.cli import main
from tests.test_plugin_new import STEP_TIMEOUT_S, _can_build_editable, _env

BROKEN_PYPROJECT = """[build-system]
requires = ["setuptools>=61"]
build-backend = "setuptools.build_meta"

[project]
name = "flowtex-broken-node"
version = "0.1"

[project.entry-points."flowtex.nodes"]
broken_node = "flowtex_broken_node.node"
"""

PROBE = """
import json, sys
from flowtex.errors import FlowtexError
from flowtex.registry import load_registry

def imported():
    return sorted(m for m in ("flowtex_lazy_gain.node", "flowtex_broken_node.node") if m in sys.modules)

reg = load_registry()
out = {"listed": [n for n in ("lazy_gain", "broken_node") if n in reg.names()], "after_listing": imported()}
out["class"] = reg.get("lazy_gain").__name__
out["after_use"] = imported()
errors = []
for _ in range(2):
    try:
        reg.types["broken_node"]
    except FlowtexError as exc:
        errors.append(str(exc))
out["errors"] = errors
print(json.dumps(out))
"""


@pytest.mark.skipif(not _can_build_editable(), reason="needs setuptools >= 70.1 or the 'wheel' package (test extra) "
                                                      "to build an editable install without network")
def test_installed_entry_points_load_on_first_use(tmp_path):
    assert main(["plugin", "new", "lazy_gain", "-o", str(tmp_path / "good")]) == 0
    broken = tmp_path / "broken"
    (broken / "flowtex_broken_node").mkdir(parents=True)
    (broken / "pyproject.toml").write_text(BROKEN_PYPROJECT)
    (broken / "flowtex_broken_node" / "__init__.py").write_text("")
    (broken / "flowtex_broken_node" / "node.py").write_text("raise RuntimeError('the lab forgot a file')\n")
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)], check=True,
                   timeout=STEP_TIMEOUT_S)  # this interpreter's pip installs into the venv that runs it
    python = str(venv / "bin" / "python")
    for pkg in (tmp_path / "good", broken):
        install = subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index",
                                  "-e", str(pkg)], capture_output=True, text=True, timeout=STEP_TIMEOUT_S, env=_env())
        assert install.returncode == 0, install.stderr[-2000:]
    probe = subprocess.run([python, "-c", PROBE], capture_output=True, text=True, timeout=STEP_TIMEOUT_S, env=_env(),
                           cwd=tmp_path)
    assert probe.returncode == 0, probe.stderr[-3000:]
    out = json.loads(probe.stdout.strip().splitlines()[-1])
    assert out["listed"] == ["lazy_gain", "broken_node"]
    assert out["after_listing"] == []                                  # names listed, nothing imported
    assert out["class"] and out["after_use"] == ["flowtex_lazy_gain.node"]  # only the package of the type used
    assert len(out["errors"]) == 2 and out["errors"][0] == out["errors"][1]  # the same error at every use
    assert "entry point 'broken_node' (flowtex_broken_node.node)" in out["errors"][0]
    assert "RuntimeError: the lab forgot a file" in out["errors"][0]
    nodes = subprocess.run([python, "-m", "flowtex", "nodes", "lazy_gain"], capture_output=True, text=True,
                           timeout=STEP_TIMEOUT_S, env=_env(), cwd=tmp_path)
    assert nodes.returncode == 0 and "from entry point flowtex_lazy_gain.node" in nodes.stdout, nodes.stderr
    listing = subprocess.run([python, "-m", "flowtex", "nodes"], capture_output=True, text=True, timeout=STEP_TIMEOUT_S,
                             env=_env(), cwd=tmp_path)
    assert listing.returncode == 1 and "entry point 'broken_node'" in listing.stderr  # a full listing imports every package
