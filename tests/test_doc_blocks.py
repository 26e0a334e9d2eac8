"""Every ```python block in README.md and docs/*.md runs as written, so the documentation cannot rot.

Each block runs on its own in a fresh folder holding a copy of the repository's ``graphs/`` and ``plugins/`` (the
files the blocks name), as a script, so a block that writes a file writes it there. A block is skipped only when
the line before its fence says so:

* ``<!-- doc-test: fragment (why) -->``: a piece of a larger program (a test for the reader's own suite);
* ``<!-- doc-test: hatt (why) -->``: it reads HaTT's published model sets as ``models/``; runs when
  ``FLOWTEX_HATT_DIR`` names their folder (research licence: never committed), skipped otherwise.

Every dotted name the prose quotes (```flowtex.fit.resample.resample_model_set```) names a module or an attribute
that exists, so a renamed or moved function is caught where the documentation still sends readers.
"""

from __future__ import annotations

import importlib
import re
import runpy
import shutil
from pathlib import Path

import pytest

from tests.conftest import hatt_xml_files

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
FENCE = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
MARK = re.compile(r"<!-- doc-test: (fragment|hatt) \(.+\) -->\s*$")


def doc_blocks() -> list[tuple[str, str, str | None]]:
    """(``file:line`` of the fence, source, marker or None) for every ```python block of the documentation."""
    blocks = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for match in FENCE.finditer(text):
            before = text[: match.start()].rstrip("\n").rsplit("\n", 1)[-1]
            mark = MARK.match(before)
            line = text.count("\n", 0, match.start()) + 1
            blocks.append((f"{doc.relative_to(REPO)}:{line}", match.group(1), mark.group(1) if mark else None))
    return blocks


BLOCKS = doc_blocks()


def test_the_documentation_has_python_blocks_and_every_marker_is_known():
    assert len(BLOCKS) >= 10
    for doc in DOCS:
        for line in doc.read_text(encoding="utf-8").splitlines():
            if "doc-test:" in line:
                assert MARK.match(line), f"{doc.name}: {line!r} is not '<!-- doc-test: fragment|hatt (why) -->'"


@pytest.mark.parametrize(("where", "source", "mark"), BLOCKS, ids=[b[0] for b in BLOCKS])
def test_doc_block_runs_as_written(where, source, mark, tmp_path, monkeypatch):
    if mark == "fragment":
        pytest.skip(f"{where}: marked as a fragment")
    for folder in ("graphs", "plugins"):
        shutil.copytree(REPO / folder, tmp_path / folder)
    if mark == "hatt":
        files = hatt_xml_files()
        if not files:
            pytest.skip(f"{where}: needs HaTT's model sets (set FLOWTEX_HATT_DIR)")
        (tmp_path / "models").symlink_to(files[0].parent, target_is_directory=True)
    script = tmp_path / "block.py"
    script.write_text(source, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    runpy.run_path(str(script), run_name="__doc_block__")


DOTTED = re.compile(r"`(flowtex(?:\.[A-Za-z_][A-Za-z0-9_]*)+)")


def _resolves(name: str) -> bool:
    """True if ``name`` is an importable module, or an attribute (chain) of the longest importable module prefix."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_every_dotted_flowtex_name_in_the_documentation_exists():
    names = {(m.group(1), doc.name) for doc in DOCS for m in DOTTED.finditer(doc.read_text(encoding="utf-8"))}
    assert len(names) > 50
    assert [(doc, name) for name, doc in sorted(names) if not _resolves(name)] == []
