"""The compile cache against damage (issue 27, section 4): numba's kernel cache files that are empty, truncated or have
flipped bytes are detected and rebuilt; a FLOWTEX_CACHE_DIR that cannot hold a cache is one line naming the variable.

The kernel here is a tiny ``@njit(cache=True)`` function in a module written to a temporary folder and imported under
a new name each time, so every import is a fresh dispatcher that loads the entry from disk, as a new process does.
"""

from __future__ import annotations

import importlib.util
import itertools
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtex.cache import SEAL_SUFFIX, cache_dir
from flowtex.errors import FlowtexError

REPO = Path(__file__).resolve().parents[1]
KERNEL = """
from numba import njit


@njit(cache=True)
def poly(x):
    return 3.0 * x * x - 2.0 * x + 0.5
"""
_count = itertools.count()


def _load(folder: Path):
    """A fresh import of the kernel module (new dispatcher, which reads numba's cache from disk)."""
    spec = importlib.util.spec_from_file_location(f"flowtex_cache_probe_{next(_count)}", folder / "probe.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.poly


def _entry(folder: Path) -> list[Path]:
    """The probe's numba files (index and data) in numba's cache folder for ``folder`` (``stats.cache_path``)."""
    where = Path(_load(folder).stats.cache_path)
    return sorted(p for p in where.glob("probe.poly-*") if p.suffix in (".nbi", ".nbc"))


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    folder = tmp_path_factory.mktemp("probe")
    (folder / "probe.py").write_text(KERNEL)
    assert _load(folder)(2.0) == 8.5  # compiled and saved
    assert _entry(folder) and all(Path(str(p) + SEAL_SUFFIX).exists() for p in _entry(folder))
    return folder


def _damage(path: Path, how: str, at: int, byte: int) -> None:
    data = bytearray(path.read_bytes())
    if how == "empty":
        data = bytearray()
    elif how == "truncate":
        data = data[: at % max(1, len(data))]
    else:
        data[at % len(data)] ^= byte or 1
    path.write_bytes(bytes(data))


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(which=st.sampled_from(["nbi", "nbc"]), how=st.sampled_from(["empty", "truncate", "flip"]),
       at=st.integers(0, 1 << 16), byte=st.integers(0, 255))
def test_a_damaged_kernel_cache_entry_is_rebuilt(probe, which, how, at, byte):
    """Whatever the damage, the next load gives the right result and leaves a sealed, loadable entry behind."""
    files = [p for p in _entry(probe) if p.suffix == f".{which}"]
    assert files
    _damage(files[0], how, at, byte)
    assert _load(probe)(2.0) == 8.5
    assert _load(probe)(-1.0) == 5.5
    entry = _entry(probe)
    assert entry and all(Path(str(p) + SEAL_SUFFIX).exists() for p in entry)


def test_an_unsealed_entry_is_not_trusted(probe):
    """A data file without its seal (written by a numba that flowtex did not guard, or a crash) is rebuilt."""
    for p in _entry(probe):
        Path(str(p) + SEAL_SUFFIX).unlink()
    assert _load(probe)(2.0) == 8.5
    assert all(Path(str(p) + SEAL_SUFFIX).exists() for p in _entry(probe))


@pytest.mark.parametrize("case", ["file", "below a file", "dangling link", "read-only"])
def test_a_cache_dir_that_cannot_hold_a_cache_is_one_line_naming_the_variable(tmp_path, monkeypatch, case):
    f = tmp_path / "f"
    f.write_text("x")
    target = {"file": f, "below a file": f / "sub", "dangling link": tmp_path / "link", "read-only": tmp_path / "ro"}[case]
    if case == "dangling link":
        os.symlink(tmp_path / "missing", target)
    if case == "read-only":
        if not os.path.exists("/sys/kernel"):
            pytest.skip("no /sys/kernel")
        target = Path("/sys/kernel/flowtex-cache") if os.geteuid() == 0 else target
        if os.geteuid() != 0:
            target.mkdir()
            target.chmod(0o500)
    monkeypatch.setenv("FLOWTEX_CACHE_DIR", str(target))
    with pytest.raises(FlowtexError) as e:
        cache_dir()
    msg = str(e.value)
    assert msg.startswith(f"FLOWTEX_CACHE_DIR={target}: ") and "\n" not in msg, msg
    expected = {"file": "is a file", "below a file": "cannot be created", "dangling link": "does not exist",
                "read-only": ("cannot be created", "is not writable")}[case]
    assert any(word in msg for word in ((expected,) if isinstance(expected, str) else expected)), msg


def test_the_command_line_says_it_in_one_line(tmp_path):
    (tmp_path / "f").write_text("x")
    (tmp_path / "g.yaml").write_text(textwrap.dedent("""\
        flowtex: 1
        name: g
        rate: 1000
        inputs: {x: {}}
        nodes: {k: {type: gain, params: {k: 2}}}
        edges: [x -> k.x]
        outputs: {y: k.y}
        """))
    env = {**os.environ, "FLOWTEX_CACHE_DIR": str(tmp_path / "f"), "PYTHONPATH": str(REPO)}
    p = subprocess.run([sys.executable, "-m", "flowtex", "graph", str(tmp_path / "g.yaml"), "--no-plugins"], capture_output=True,
                       text=True, env=env, timeout=600, cwd=tmp_path)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 1 and len(lines) == 1, p.stderr
    assert lines[0].startswith(f"FLOWTEX_CACHE_DIR={tmp_path / 'f'}: is a file"), p.stderr


def test_the_cache_writer_leaves_the_old_file_and_no_temporary_on_failure(tmp_path, monkeypatch):
    """flowtex.cache.write_cache_file, the one writer of seals, generated sources and filter designs: a rename that
    fails (a full disk, Ctrl-C) leaves the previous entry as it was and no temporary file beside it."""
    from flowtex.cache import write_cache_file

    entry = tmp_path / "entry.seal"
    write_cache_file(entry, b"old")

    def refuse(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", refuse)
    with pytest.raises(OSError):
        write_cache_file(entry, b"new")
    assert entry.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["entry.seal"]
