"""Exit code 2 (docs/cli.md): a bug in flowtex itself is one 'internal error' line, or the traceback with FLOWTEX_DEBUG=1."""

from __future__ import annotations

import pytest

from flowtex.cli import graph as graph_cli
from flowtex.cli.main import EXIT_INTERNAL_ERROR, main


def _broken(args) -> int:
    raise ZeroDivisionError("a flowtex bug")


def test_a_bug_is_one_internal_error_line_and_exit_2(monkeypatch, capsys) -> None:
    monkeypatch.setattr(graph_cli, "cmd_nodes", _broken)
    monkeypatch.delenv("FLOWTEX_DEBUG", raising=False)
    assert main(["nodes"]) == EXIT_INTERNAL_ERROR == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["flowtex: internal error: ZeroDivisionError: a flowtex bug (set FLOWTEX_DEBUG=1 for a traceback; please report it)"]


def test_flowtex_debug_shows_the_traceback(monkeypatch) -> None:
    monkeypatch.setattr(graph_cli, "cmd_nodes", _broken)
    monkeypatch.setenv("FLOWTEX_DEBUG", "1")
    with pytest.raises(ZeroDivisionError, match="a flowtex bug"):
        main(["nodes"])
