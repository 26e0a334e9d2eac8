"""Fast start: ``flowtex --help`` and ``--version`` import no command module, no numba and no scipy; ``import flowtex``
works without ``fcntl`` (Windows) and imports no kernel. Checked through ``sys.modules`` of a fresh process, never
through timings (benchmarks/bench_startup.py measures those)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from flowtex.cli.main import COMMANDS, build_parser
from tests.conftest import REPO

HEAVY = ("numba", "scipy", "llvmlite", "flowtex.graph", "flowtex.nodes", "flowtex.dsp", "flowtex.io", "flowtex.runtime",
         "flowtex.fit", "flowtex.scene", "flowtex.compile")
"""Packages a bare start must not import."""

PROBE = """
import json, sys
{pre}
{action}
print(json.dumps(sorted(sys.modules)), file=sys.__stderr__)
"""


def modules_after(action: str, pre: str = "") -> list[str]:
    """Modules loaded in a fresh interpreter after ``action`` (stdout of the action is discarded)."""
    code = PROBE.format(pre=pre, action=action)
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stderr.strip().splitlines()[-1])


def heavy(modules: list[str]) -> list[str]:
    return [m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY)]


@pytest.mark.parametrize("flag", ["--help", "--version"])
def test_help_and_version_import_no_command_module_numba_or_scipy(flag):
    run = f"from flowtex.cli import main\ntry:\n    main([{flag!r}])\nexcept SystemExit:\n    pass"
    loaded = modules_after(run, pre="import io, contextlib\n_out = contextlib.redirect_stdout(io.StringIO()); _out.__enter__()")
    commands = sorted({module for module, _ in COMMANDS.values()})
    assert [m for m in loaded if m in commands] == []
    assert heavy(loaded) == []
    assert "flowtex.cli.main" in loaded  # the probe did run the CLI


def test_a_command_imports_only_its_own_module():
    run = "from flowtex.cli import main\ntry:\n    main(['resample', '--help'])\nexcept SystemExit:\n    pass"
    loaded = modules_after(run, pre="import io, contextlib\n_out = contextlib.redirect_stdout(io.StringIO()); _out.__enter__()")
    assert "flowtex.cli.resample" in loaded
    unrelated = ("flowtex.cli.fit", "flowtex.cli.live", "flowtex.cli.scene", "flowtex.cli.bench", "flowtex.cli.plot",
                 "flowtex.cli.compare", "flowtex.cli.models")  # (resample's module shares helpers of cli.run and cli.graph)
    assert [m for m in loaded if m in unrelated] == []


def test_import_flowtex_works_without_fcntl_and_loads_no_kernel():
    loaded = modules_after("import flowtex\nassert flowtex.__version__", pre="sys.modules['fcntl'] = None")
    assert heavy(loaded) == []


def test_kernel_cache_lock_works_without_fcntl(tmp_path):
    # the lock itself is chosen at the first lock: without fcntl (Windows) it is msvcrt's, absent here, so the error
    # names the missing module instead of failing at import
    code = ("import sys; sys.modules['fcntl'] = None\nfrom pathlib import Path\nfrom flowtex.graph.kcache import locked\n"
            f"try:\n    with locked(Path({str(tmp_path / 'x.lock')!r})):\n        pass\nexcept ImportError as e:\n"
            "    print('no lock module:', e.name)\nelse:\n    print('locked')")
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() in ("no lock module: msvcrt", "locked")


def test_summaries_are_the_parsers_help():
    # the lazy table lists each command with the summary its module registers: one text, checked here
    full = build_parser()
    sub = next(a for a in full._actions if a.__class__.__name__ == "_SubParsersAction")
    helps = {c.dest: c.help for c in sub._choices_actions}
    assert helps == {name: summary for name, (_, summary) in COMMANDS.items()}
    lazy = build_parser(None).format_help()
    assert lazy == full.format_help()
