"""No production file over ~400 lines without a stated reason (DESIGN.md: small modules with one job).

A module longer than :data:`LIMIT` lines either is split into modules with one job each, or says in its module
docstring why it stays whole, in a sentence starting with :data:`REASON` (one tightly coupled algorithm, say).
A file that is over the limit for now, with the reason, is listed in :data:`PENDING`; an entry that no longer
applies fails the test, so the list only shrinks.
"""

from __future__ import annotations

import ast

from tests.conftest import REPO

LIMIT = 420
"""Lines; "about 400", with 5% of slack so that one more import does not force a split."""

REASON = "Kept in one file:"
"""How a module docstring states why the module is longer than LIMIT."""

PENDING: dict[str, str] = {}
"""Path -> why it is over the limit without a reason in its docstring for now."""


def long_modules() -> dict[str, int]:
    """Path (relative to the repository) -> line count, for every flowtex module over LIMIT lines without REASON."""
    found = {}
    for path in sorted((REPO / "flowtex").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        n = len(text.splitlines())
        if n > LIMIT and REASON not in (ast.get_docstring(ast.parse(text)) or ""):
            found[path.relative_to(REPO).as_posix()] = n
    return found


def test_no_long_module_without_a_stated_reason():
    found = long_modules()
    unexplained = {path: n for path, n in found.items() if path not in PENDING}
    assert unexplained == {}, f"split these into modules with one job, or state '{REASON} ...' in the module docstring"
    stale = [path for path in PENDING if path not in found]
    assert stale == [], "these files are no longer over the limit (or now state a reason): remove them from PENDING"
