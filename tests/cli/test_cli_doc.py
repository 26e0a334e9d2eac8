"""docs/cli.md names every verb and every flag the parser accepts (one page for the whole vocabulary)."""

from __future__ import annotations

import argparse
import re

from flowtex.cli import build_parser
from tests.conftest import REPO


def _flags(parser: argparse.ArgumentParser, prefix: str, found: dict[str, set[str]]) -> None:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                _flags(sub, f"{prefix} {name}", found)
        elif action.option_strings and action.help != argparse.SUPPRESS and not isinstance(action, argparse._HelpAction):
            found.setdefault(prefix, set()).update(o for o in action.option_strings if o.startswith("--"))
    found.setdefault(prefix, set())


def test_every_verb_and_flag_is_on_the_cli_page():
    text = (REPO / "docs" / "cli.md").read_text(encoding="utf-8")
    found: dict[str, set[str]] = {}
    _flags(build_parser(), "flowtex", found)
    verbs = [v.split(" ", 1)[1] for v in found if " " in v]
    assert len(verbs) >= 17
    missing_verbs = [v for v in verbs if f"{v.split()[-1]} " not in text]
    missing_flags = sorted({f for flags in found.values() for f in flags if not re.search(re.escape(f) + r"(?![\w-])", text)})
    assert missing_verbs == [] and missing_flags == []
