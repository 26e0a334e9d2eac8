"""``flowtex plugin check``: each common plugin mistake named at its file and line (issue 25; out-of-bounds writes: 27 §5).

tests/plugin_cases/mistakes.py holds one node type per mistake: a kernel that allocates, one that keeps
its state in a local variable, one that writes only column 0 of a 3-vector, one that writes far outside
its state array (which, unchecked, corrupts memory: the check runs it bounds-checked in a child process).
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from flowtex.cli import main

CASES = Path(__file__).parent / "plugin_cases"
REPO = Path(__file__).resolve().parents[1]


def _line(path: Path, needle: str) -> int:
    return next(k for k, line in enumerate(path.read_text().splitlines(), start=1) if needle in line)


def _check(capsys, target: str) -> tuple[int, list[str], str]:
    code = main(["plugin", "check", target])
    out = capsys.readouterr()
    return code, out.out.strip().splitlines(), out.err.strip()


def check_copy(case: Path, folder: Path, name: str) -> tuple[int, list[str], str, Path]:
    """``plugin check NAME`` run in ``folder`` on a copy of ``case`` named ``name`` (messages then say ``NAME:LINE``):
    exit code, stdout lines, stderr, the copy's path."""
    shutil.copy(case, folder / name)
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = main(["plugin", "check", name])
    finally:
        os.chdir(cwd)
    return code, out.getvalue().strip().splitlines(), err.getvalue().strip(), folder / name


@pytest.fixture(scope="module")
def mistakes_report(tmp_path_factory):
    """One run of plugin check over the mistakes file (it compiles four kernels twice: once plain, once bounds-checked)."""
    return check_copy(CASES / "mistakes.py", tmp_path_factory.mktemp("pc"), "mistakes.py")


def test_every_mistake_is_one_line_at_its_file_and_line(mistakes_report):
    code, lines, err, path = mistakes_report
    assert code == 1
    assert err == "mistakes.py: 4 problem(s) in node type(s) alloc_pc, forget_pc, col0_pc, oob_pc"
    at = {name: f"mistakes.py:{_line(path, f'def {name}_kernel')}: node '{name}_pc': "
          for name in ("alloc", "forget", "col0", "oob")}
    problems = [line for line in lines if ": note: " not in line]
    assert len(problems) == 4
    assert problems[0].startswith(at["alloc"] + "kernel alloc_kernel allocates memory on every call (numba generated NRT_")
    assert problems[1].startswith(at["forget"] + "output 'y': chunked (blocks of 1, 7, 64, 1, 200, 13, ...) and one-pass runs "
                                  "differ from tick 1")  # the first block boundary
    assert problems[2].startswith(at["col0"] + "output 'y': element(s) [1, 2] of 3 per tick never written")
    assert problems[3].startswith(at["oob"] + "kernel reads or writes outside its arrays")


def test_parameters_without_bounds_are_notes(mistakes_report):
    _, lines, _, path = mistakes_report
    notes = [line for line in lines if ": note: " in line]
    params_line = _line(path, 'params = {"k"')
    assert notes == [f"mistakes.py:{params_line}: node 'alloc_pc': note: parameter 'k' has no min or max; "
                     "any such value reaches the kernel (declare bounds, e.g. Param('float', min=0.0, max=1.0))"]


def test_a_clean_plugin_passes_with_notes_only(capsys):
    code, lines, err = _check(capsys, str(REPO / "plugins" / "soft_clip.py"))
    assert code == 0 and err.endswith("ok (node type(s) soft_clip; 1 note(s))")
    assert len(lines) == 1 and "note: parameter 'limit' has no max" in lines[0]


def test_an_installed_node_type_is_checked_by_name(capsys):
    code, lines, err = _check(capsys, "butterworth")
    assert code == 0 and "ok (node type(s) butterworth" in err
    code, _, err = _check(capsys, "buterworth")
    assert code == 1 and "(did you mean 'butterworth'?)" in err


def test_declaration_mistakes_are_reported_by_plugin_check(tmp_path, capsys):
    text = textwrap.dedent('''\
        from numba import njit

        from flowtex.node_api import Node, Port


        @njit(cache=True)
        def k(p, s, si, x, y):
            pass


        class Bad(Node):
            """bad port"""

            type_name = "badport_pc"
            inputs = {"x": Port((), "*")}
            outputs = {"y": Port("=nope", "=x")}
            kernel = k
        ''')
    (tmp_path / "badport.py").write_text(text)
    code, lines, _ = _check(capsys, str(tmp_path / "badport.py"))
    assert code == 1
    assert lines == [f"{tmp_path / 'badport.py'}:16: node 'badport_pc': output 'y': shape '=nope' names no input; inputs are: x"]


def test_allocation_is_found_in_a_cached_kernel_too(mistakes_report, monkeypatch):
    # numba shows no LLVM IR for code loaded from its disk cache: a second allocation check of the mistakes file (its
    # kernels cached by the fixture's check) must still see the allocation. Only the allocation step's child runs, for
    # the one type asserted on (the message it becomes is the fixture tests'): the runtime child and the other kernels'
    # compiles would cost CPU this assertion does not look at.
    from flowtex import plugincheck

    monkeypatch.chdir(mistakes_report[3].parent)
    alloc = plugincheck.node_types("mistakes.py")["alloc_pc"]
    kept = plugincheck.allocation_key(alloc)
    assert kept is not None and kept.is_file()  # the fixture's check kept what it found ...
    kept.unlink()  # ... forgotten here, so the child compiles the (cached) kernel afresh
    found, failed = plugincheck.allocations("mistakes.py", [alloc])["alloc_pc"]
    assert failed is None and found and all(call.startswith("NRT_") for call in found), found
    assert plugincheck._kept_allocations(kept) == found


def test_a_kept_allocation_check_is_used_for_the_same_code_only(mistakes_report, tmp_path, monkeypatch):
    """The allocation step compiles every kernel afresh in a child (about 2 s a plugin file). What it found is kept,
    keyed as the compiled code is: checking the same code again starts no child, a copy of the plugin folder loaded
    elsewhere (a fresh process, as a user's next ``plugin check``) finds the same record, and any edit to the folder
    (here a helper file added) has a record of its own. A damaged record counts as none."""
    from flowtex import plugincheck

    started = []
    children = plugincheck._children
    monkeypatch.setattr(plugincheck, "_children", lambda target, classes, mode, env: started.append(mode) or
                        children(target, classes, mode, env))
    monkeypatch.chdir(mistakes_report[3].parent)
    alloc = plugincheck.node_types("mistakes.py")["alloc_pc"]
    assert plugincheck.allocations("mistakes.py", [alloc])["alloc_pc"][0] and started == []  # the fixture's record
    kept = plugincheck.allocation_key(alloc)
    for name, extra in (("copy", False), ("edited", True)):
        (tmp_path / name).mkdir()
        shutil.copy(CASES / "mistakes.py", tmp_path / name / "mistakes.py")
        if extra:
            (tmp_path / name / "helper.py").write_text("SCALE = 2.0\n")
    probe = ("import sys; from flowtex import plugincheck\n"
             "for folder in sys.argv[1:]:\n"
             "    print(plugincheck.allocation_key(plugincheck.node_types(folder + '/mistakes.py')['alloc_pc']))\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}  # this checkout's flowtex
    out = subprocess.run([sys.executable, "-c", probe, str(tmp_path / "copy"), str(tmp_path / "edited")],
                         capture_output=True, text=True, check=True, env=env).stdout.split()
    assert out[0] == str(kept) and out[1] != str(kept)
    good = kept.read_bytes()
    # nested past Python's recursion limit, json.loads raises RecursionError, which is not a ValueError
    for damaged in (b"", b'{"allocations": [1]}', b"\xff\xfe", b"[]", b"[" * 100_000):
        kept.write_bytes(damaged)
        assert plugincheck._kept_allocations(kept) is None
    kept.write_bytes(good)


KILLS = """\
import os
import signal

import numpy as np
from numba import njit

from flowtex.node_api import Node, NodeState, Param, Port


@njit(cache=True)
def div0_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = p[0] / 0.0 * x[t, 0]


class Before(Node):
    \"\"\"divides by zero\"\"\"
    type_name = "before_pc"
    params = {"k": Param("float", default=1.0, min=0.0, max=2.0)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = div0_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["k"]]))


class Kills(Before):
    \"\"\"ends the process that builds it\"\"\"
    type_name = "kills_pc"

    def build(self, inputs, outputs):
        os.kill(os.getpid(), signal.SIGKILL)  # build() runs in the runtime check's child process only


class After(Before):
    \"\"\"divides by zero, defined after the type that kills the process\"\"\"
    type_name = "after_pc"
"""


def test_a_type_that_kills_the_checking_process_is_named_and_the_next_type_is_still_checked(tmp_path, capsys):
    # the runtime checks of every type of a file run in one child process: when one type ends that process, the report
    # names that type, the type checked before it keeps its result, and the type after it is checked in a new process
    (tmp_path / "kills.py").write_text(KILLS)
    code, lines, err = _check(capsys, str(tmp_path / "kills.py"))
    assert code == 1 and err.endswith("3 problem(s) in node type(s) before_pc, kills_pc, after_pc"), err
    by_type = {name: [line for line in lines if f"node '{name}_pc'" in line] for name in ("before", "kills", "after")}
    assert len(by_type["kills"]) == 1 and "running the kernel crashed the checking process (signal SIGKILL)" in by_type["kills"][0]
    for name in ("before", "after"):
        assert len(by_type[name]) == 1 and "kernel raised ZeroDivisionError" in by_type[name][0], lines


def test_the_bounds_checked_child_compiles_into_its_own_tree_of_this_source_tree(tmp_path, monkeypatch):
    """Bounds-checked code has its own cache tree (numba's keys do not tell it from normal code), one folder per flowtex
    source tree as the normal cache has; older trees' folders are pruned, and a caller's NUMBA_CACHE_DIR (which would
    turn flowtex's filing by contents off) is not passed on."""
    from flowtex import plugincheck
    from flowtex.cache import KEEP_OLD

    monkeypatch.setenv("FLOWTEX_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "callers"))
    older = [tmp_path / "boundscheck" / f"tree{k}" for k in range(KEEP_OLD + 2)]
    for k, folder in enumerate(older):
        folder.mkdir(parents=True)
        os.utime(folder, (1e9 + k, 1e9 + k))  # long unused, oldest first
    seen = {}
    monkeypatch.setattr(plugincheck, "_children", lambda target, classes, mode, env: seen.update(env) or {})
    plugincheck.runtime_problems("any.py", [])
    env = plugincheck.child_env(seen)
    assert env["NUMBA_BOUNDSCHECK"] == "1" and "NUMBA_CACHE_DIR" not in env
    assert [f.exists() for f in older] == [False, False] + [True] * KEEP_OLD  # the newest few kept


CHECK_ONE = """
import sys
from flowtex import kernelprobe
from flowtex.plugincheck import node_types
assert kernelprobe.main(["runtime", sys.argv[1], sys.argv[2]]) == 0
kernel = node_types(sys.argv[1])[sys.argv[2]].get_kernel()
print(sum(kernel.stats.cache_hits.values()), sum(kernel.stats.cache_misses.values()))
"""
"""The runtime checks' child (``python -m flowtex.kernelprobe runtime FILE TYPE``), then its kernel's numba cache hits and
misses."""


def test_a_copied_plugin_folder_is_checked_bounds_checked_without_compiling(tmp_path, monkeypatch):
    """The bounds-checked cache files a plugin's kernels by its folder's code id, as the normal cache does, so a copy of
    the folder elsewhere (here: moved, with new file times) is checked by a child that loads what the first compiled;
    its entries are sealed (a damaged one is rebuilt, flowtex.cache.guard_numba_cache) and stay out of the normal tree."""
    from flowtex import plugincheck
    from flowtex.cache import source_fingerprint
    from flowtex.plugincode import plugin_code_id

    monkeypatch.setenv("FLOWTEX_CACHE_DIR", str(tmp_path / "cache"))  # empty: the first check compiles
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "callers"))
    first = tmp_path / "first"
    first.mkdir()
    shutil.copy(REPO / "plugins" / "soft_clip.py", first)
    classes = list(plugincheck.node_types(str(first / "soft_clip.py")).values())
    assert plugincheck.runtime_problems(str(first / "soft_clip.py"), classes) == {"soft_clip": []}
    entry = tmp_path / "cache" / "boundscheck" / source_fingerprint() / "plugins" / plugin_code_id(first / "soft_clip.py")
    assert sorted(f.suffix for f in entry.iterdir()) == [".nbc", ".nbi", ".sha256", ".sha256"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cache", "first"]  # nothing in the caller's NUMBA_CACHE_DIR
    assert [p.name for p in (tmp_path / "cache").iterdir()] == ["boundscheck"]  # nor in the normal tree
    copy = tmp_path / "elsewhere" / "copy"
    shutil.copytree(first, copy)
    shutil.rmtree(first)
    os.utime(copy / "soft_clip.py", (1.0e9, 1.0e9))
    done = subprocess.run([sys.executable, "-c", CHECK_ONE, "soft_clip.py", "soft_clip"], cwd=copy, capture_output=True,
                          env=plugincheck.child_env(plugincheck.RUNTIME_ENV), text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    *items, counts = done.stdout.strip().splitlines()
    assert items == ['{"start": "soft_clip"}', '{"done": "soft_clip"}']  # checked, no problem
    assert counts == "1 0"  # one cache hit, no compile
