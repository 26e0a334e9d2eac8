"""Old import paths for names that moved to another module: a lazy module ``__getattr__`` (PEP 562).

A module that gave up some names to a new module which imports it back (so a plain
re-export would be an import circle) keeps them importable with
``__getattr__ = moved_names(__name__, {name: new_module})``: the new module is imported by
name on first use, and the value is then stored in the old module so the lookup runs once.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from typing import Any


def moved_names(owner: str, homes: dict[str, str]) -> Callable[[str], Any]:
    """The ``__getattr__`` for module ``owner``: ``homes`` maps each moved name to the module that now defines it."""

    def __getattr__(name: str) -> Any:
        home = homes.get(name)
        if home is None:
            raise AttributeError(f"module {owner!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(home), name)
        setattr(sys.modules[owner], name, value)
        return value

    return __getattr__
