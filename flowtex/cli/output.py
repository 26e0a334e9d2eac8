"""What the command line prints: text from files (graph names, signal names, values) with control characters escaped,
so a hostile file cannot send escape codes to the terminal."""

from __future__ import annotations

import sys
from typing import TextIO

_KEEP = {"\n", "\t"}


def clean(text: str) -> str:
    """``text`` with every control character except newline and tab shown as an escape (``\\x1b``), never raw."""
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() or ch in _KEEP else ch.encode("unicode_escape").decode("ascii") for ch in text)


def say(text: str, stream: TextIO | None = None) -> None:
    """Print ``text`` (cleaned) to stdout, or to ``stream``."""
    print(clean(text), file=stream or sys.stdout)


def note(text: str) -> None:
    """Print ``text`` (cleaned) to stderr."""
    print(clean(text), file=sys.stderr)
