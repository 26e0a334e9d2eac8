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
"""Run by the venv's interpreter: what listing the node types imports, what using one imports, a broken package's error."""

CLI = """
import contextlib, io, json
from flowtex.cli import main

runs = []
for args in (["nodes", "lazy_gain"], ["nodes"]):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(args)
    runs.append({"code": code, "stdout": out.getvalue(), "stderr": err.getvalue()})
print(json.dumps(runs))
"""
"""Run by the venv's interpreter: ``flowtex nodes lazy_gain`` and ``flowtex nodes`` (:func:`flowtex.cli.main`), one process
for both (the venv and its entry points are the point, not a process per command)."""


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
    install = subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index",
                              "-e", str(tmp_path / "good"), "-e", str(broken)], capture_output=True, text=True,
                             timeout=STEP_TIMEOUT_S, env=_env())  # one pip for both packages: its start-up once
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
    cli = subprocess.run([python, "-c", CLI], capture_output=True, text=True, timeout=STEP_TIMEOUT_S, env=_env(), cwd=tmp_path)
    assert cli.returncode == 0, cli.stderr[-3000:]
    nodes, listing = json.loads(cli.stdout.strip().splitlines()[-1])
    assert nodes["code"] == 0 and "from entry point flowtex_lazy_gain.node" in nodes["stdout"], nodes["stderr"]
    assert listing["code"] == 1 and "entry point 'broken_node'" in listing["stderr"]  # a full listing imports every package
