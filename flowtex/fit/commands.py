"""``flowtex fit KIND ...``: one subcommand per kind of model, each registered by its own module."""

from __future__ import annotations

import importlib
from typing import Any

FIT_COMMAND_MODULES: tuple[str, ...] = (
    "flowtex.fit.pattern",
    "flowtex.fit.compliance",
    "flowtex.fit.texture_cli",
    "flowtex.fit.friction",
    "flowtex.fit.taps",
)
"""Modules that add a ``flowtex fit`` kind: each has ``register_fit(fit_subparsers)``."""


def register(subparsers: Any) -> None:
    """Add ``flowtex fit`` with every kind listed in :data:`FIT_COMMAND_MODULES`."""
    p = subparsers.add_parser("fit", help="fit models (texture, friction, taps, pattern, compliance) to recordings",
                              description="Turn recordings into models that flowtex's nodes render.")
    kinds = p.add_subparsers(dest="fit_kind", required=True, metavar="KIND")
    for module_name in FIT_COMMAND_MODULES:
        importlib.import_module(module_name).register_fit(kinds)
    importlib.import_module("flowtex.fit.compare_cli").register(subparsers)   # flowtex compare: judges what fit made
