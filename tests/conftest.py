"""Shared test helpers: write graph files into tmp_path."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

os.environ.setdefault("FLOWTEX_BACKGROUND", "0")  # no background fused compiles (docs/engine.md) competing with the tests
# The suite runs on the dispatch tier: a structure costs no numba compile once its node types are cached, and both tiers
# give bit-identical outputs (tests/test_engine_tiers.py). The files below keep the fused tier: tier equivalence and goldens.
_SUITE_TIER_MARK = "PYTEST_FLOWTEX_SUITE_TIER"
"""Set beside FLOWTEX_COMPILE when this conftest chose the tier: pytest-xdist's workers inherit the controller's
environment, so in a worker FLOWTEX_COMPILE is already set and only this mark says the suite (not the caller) set it."""
if "FLOWTEX_COMPILE" not in os.environ:
    os.environ["FLOWTEX_COMPILE"] = "dispatch"
    os.environ[_SUITE_TIER_MARK] = "1"
SUITE_SETS_TIER = os.environ.get(_SUITE_TIER_MARK) == "1"

FUSED_TIER_FILES = frozenset({
    # tier equivalence and goldens
    "test_engine_tiers.py", "test_examples.py", "test_texture_examples.py", "test_golden_portability.py",
    # live sessions built through the Python API: live always runs the fused tick (flowtex live forces it), and only the
    # fused tier carries an exception raised inside a kernel out to the runtime (the dispatch tier's wrappers are C
    # callbacks): test_live.py's "exception inside the graph" session fails on the dispatch tier
    "test_live.py", "test_livesafe_dbc.py", "test_livesafe_guard.py", "test_livesafe_replay.py",
    "test_livesafe_session.py", "test_replay.py", "test_fused.py", "test_scene_live.py",
})
"""Test files that run on the fused tier (what library callers get by default), whatever the suite's default."""


def pytest_configure(config: pytest.Config) -> None:
    if os.environ.get("PYTEST_FLOWTEX_PROFILE"):  # where the suite's time goes (tests/suite_profile.py, docs/testing.md)
        from suite_profile import register

        register(config)


@pytest.fixture(autouse=True)
def _compile_tier(request, monkeypatch):
    """The fused tier for the files of :data:`FUSED_TIER_FILES`; the suite's default (dispatch) elsewhere.

    A tier set in the environment before the run (``FLOWTEX_COMPILE=fused pytest``) applies to every file."""
    if SUITE_SETS_TIER and request.path.name in FUSED_TIER_FILES:
        monkeypatch.setenv("FLOWTEX_COMPILE", "fused")


@pytest.fixture
def write_graph(tmp_path):
    """Write YAML text (dedented) to tmp_path/NAME and return its path."""

    def _write(text: str, name: str = "g.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text).lstrip("\n"))
        return path

    return _write


HATT_ENV = "FLOWTEX_HATT_DIR"
"""Folder holding HaTT's published ``Models_*.xml`` files (research licence: never committed)."""


def hatt_xml_files() -> list[Path]:
    """HaTT's published model sets, from ``$FLOWTEX_HATT_DIR``; empty when the variable is unset or the folder holds none."""
    folder = os.environ.get(HATT_ENV)
    if not folder or not Path(folder).is_dir():
        return []
    return sorted(Path(folder).glob("Models_*.xml"))


@pytest.fixture(scope="session")
def hatt_files() -> list[Path]:
    """The HaTT XML model sets; skips the test when they are not on this machine (set FLOWTEX_HATT_DIR)."""
    files = hatt_xml_files()
    if not files:
        pytest.skip(f"HaTT's published model sets are not here (set {HATT_ENV} to the folder holding Models_*.xml)")
    return files
