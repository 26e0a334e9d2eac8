"""Shared test helpers: write graph files into tmp_path."""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

os.environ.setdefault("FLOWTEX_BACKGROUND", "0")  # no background fused compiles (docs/engine.md) competing with the tests


@pytest.fixture
def write_graph(tmp_path):
    """Write YAML text (dedented) to tmp_path/NAME and return its path."""

    def _write(text: str, name: str = "g.yaml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text).lstrip("\n"))
        return path

    return _write
