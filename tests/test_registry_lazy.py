"""The node-type table is lazy (issue 24 item 6): built-ins are named 'module:Class' and imported on first use."""

from __future__ import annotations

import importlib
import inspect
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import flowtex.nodes
from flowtex.node_api import Node
from flowtex.registry import BUILTIN_TYPES, load_registry

REPO = Path(__file__).resolve().parents[1]


def _node_modules_after(code: str) -> list[str]:
    """The flowtex.nodes.* modules imported by running ``code`` in a fresh interpreter from this source tree."""
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted(m for m in sys.modules if m.startswith('flowtex.nodes.'))))\n"
    done = subprocess.run([sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_table_names_every_node_type_the_package_defines() -> None:
    found = {}
    for info in pkgutil.iter_modules(flowtex.nodes.__path__):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"flowtex.nodes.{info.name}")
        for obj in vars(module).values():
            if inspect.isclass(obj) and issubclass(obj, Node) and obj.type_name and obj.__module__ == module.__name__:
                found[obj.type_name] = f"{module.__name__}:{obj.__name__}"
    assert found == BUILTIN_TYPES


def test_import_and_help_import_no_node_module() -> None:
    assert _node_modules_after("import flowtex") == []
    assert _node_modules_after("import flowtex.registry") == []
    assert _node_modules_after("from flowtex.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass") == []


def test_listing_names_imports_nothing_and_a_type_imports_its_module_only() -> None:
    code = ("from flowtex.registry import load_registry\nreg = load_registry()\nassert 'texture_lookup' in reg.names()\n"
            "assert reg.get('butterworth').type_name == 'butterworth'")
    assert _node_modules_after(code) == ["flowtex.nodes.filters"]


def test_a_lazy_entry_is_the_class_and_every_name_resolves() -> None:
    reg = load_registry()
    assert reg.get("no_such_type") is None and "no_such_type" not in reg.types
    for name in BUILTIN_TYPES:
        assert reg.types[name].type_name == name
    assert set(BUILTIN_TYPES) <= set(reg.names())
